"""Start the local worker pool of ``proxops mc`` before the command line is even parsed.

The workers of a campaign cannot run before the pool's fork server has imported the worker modules
and built the scenario once (:mod:`proxops.exec.worker_warmup`): about 1.2 s of CPU for an srf
campaign (numba's import and kernel cache load are most of it), the critical path of the start.
:func:`proxops.exec.entry.main` calls :func:`prestart_from_argv` first thing, so the server starts
before this process imports the CLI (typer, click: 0.13-0.25 s, measured); ``mc`` then calls
:func:`prestart` again with its parsed options, which does nothing when the same pool exists.

The early read of the arguments is a best effort that never decides anything: anything it does not
recognise (an unknown option, a missing value, ``--help``, a bad number, ``--scheduler``) leaves
the start to ``mc``, which validates every option and reports bad input as usual. Imports nothing
heavy (the execution layer: multiprocessing, concurrent.futures).
"""

from __future__ import annotations

import json
import math
import os
from typing import Sequence

from proxops.exec.backends import MAX_WORKERS, START_METHOD, default_workers, prestart_pool
from proxops.scenarios.catalog import read_toml, resolve  # tomllib only
from proxops.scenarios.registry import SYSTEM_MODULES  # importlib only: no system is imported

ENV = "PROXOPS_WARM_SCENARIO"  # the scenario the fork server builds once (read by exec.worker_warmup)

# What every campaign worker imports (the system module comes with the first check)
WORKER_MODULES = ("proxops.analysis.campaign_worker", "proxops.analysis.runs", "proxops.scenarios.loader",
                  "proxops.systems.base")
WARMUP_MODULE = "proxops.exec.worker_warmup"  # imported last by the fork server: builds the scenario

_VALUE_OPTIONS = {"--runs": "runs", "-n": "runs", "--workers": "workers", "-w": "workers",
                  "--scheduler": "scheduler", "--seed": "seed", "--out": None, "--set": "set",
                  "--connect-timeout-s": "timeout"}
_FLAGS = {"--resume", "--series", "--no-series", "--report", "--no-report", "--progress", "--no-progress",
          "--json"}


def prestart(scenario: str, runs: int | None, workers: int | None, overrides: Sequence[str] = ()) -> None:
    """Start the local pool a campaign of ``scenario`` with these options uses (no effect when it
    exists or with fewer than 2 workers): its workers' start-up overlaps this process's work."""

    n_workers = workers if workers is not None else default_workers()
    if runs is not None:
        n_workers = min(n_workers, runs)
    modules = WORKER_MODULES + system_module(scenario)
    if START_METHOD != "forkserver":
        prestart_pool(n_workers, modules)
        return
    os.environ[ENV] = json.dumps({"scenario": scenario, "overrides": list(overrides)})
    try:  # the fork server also builds the scenario once, for every worker it forks
        prestart_pool(n_workers, modules + (WARMUP_MODULE,))
    finally:
        os.environ.pop(ENV, None)


# Monte Carlo of ``proxops reach mc`` (Iskender 2026 §9): los-tumble in its Monte Carlo configuration over
# the paper's axes (= analysis.reach.PAPER_OMEGAS_DEG_S, PAPER_A_MAX_MPS2; tests/test_reach_cli.py checks)
REACH_SCENARIO = "los-tumble"
REACH_OMEGAS_DEG_S = (1.0, 2.0, 3.0, 4.0, 5.0)
REACH_A_MAX_MPS2 = (0.20, 0.10, 0.05, 0.02)
REACH_MAX_GRID = 3000  # points per axis: the maps hold several float arrays of grid^2 per combination
REACH_MAX_IC_AXIS = 200  # ICs per axis of the Monte Carlo (n_x * n_y runs per combination)


def reach_overrides(duration_s: float) -> list[str]:
    """The ``--set`` overrides of one run of ``proxops reach mc`` of ``duration_s`` s."""
    return [f"sim.duration_s={float(duration_s)!r}", "mpc.config=monte-carlo", "mpc.constraint_mode=hard"]


def prestart_from_argv(argv: Sequence[str]) -> None:
    """:func:`prestart` for ``proxops [--debug] mc SCENARIO [options]``, ``proxops reach mc [options]`` or
    ``proxops cortex references [options]`` when ``argv`` (without the program name) reads unambiguously as that with valid numbers, no
    ``--scheduler`` (and for reach no ``--resume``); otherwise nothing."""
    argv = _without_global_options(list(argv))
    readers = {"mc": _read_mc_argv, "reach": _read_reach_mc_argv, "cortex": _read_cortex_references_argv}
    reader = readers.get(argv[0]) if argv else None
    parsed = reader(argv) if reader is not None else None
    if parsed is None:
        return
    try:
        prestart(*parsed)
    except Exception:  # noqa: BLE001 - the command's own call of prestart reports what went wrong
        return


_GLOBAL_FLAGS = {"--debug", "--verbose", "-v", "--quiet", "-q"}  # proxops.cli.main's options without a value


def _without_global_options(argv: list[str]) -> list[str]:
    while argv and argv[0] in _GLOBAL_FLAGS:
        argv = argv[1:]
    return argv


def _read_reach_mc_argv(argv: list[str]):
    """(scenario, runs, workers, overrides) of ``reach mc [options]`` or None when in any doubt (its
    checks as ``proxops.cli_reach.mc`` makes them, so that an error is not preceded by a pool start)."""
    if argv[:2] != ["reach", "mc"]:
        return None
    values: dict = {"workers": None, "duration": 400.0, "n_x": 13, "n_y": 15, "omegas": [], "amaxs": []}
    ints = {"--workers": ("workers", 1, math.inf), "--n-x": ("n_x", 1, REACH_MAX_IC_AXIS),
            "--n-y": ("n_y", 1, REACH_MAX_IC_AXIS), "--grid": (None, 3, REACH_MAX_GRID)}
    floats = {"--duration-s": "duration", "--omega-deg-s": "omegas", "--omega-deg": "omegas",
              "--a-max-mps2": "amaxs", "--amax": "amaxs"}
    rest = argv[2:]
    k = 0
    while k < len(rest):
        name, eq, value = rest[k].partition("=")
        k += 1
        if name in ("--progress", "--no-progress", "--viability-check", "--json") and not eq:
            continue
        if name not in ints and name not in floats and name != "--out" or (eq and not name.startswith("--")):
            return None  # --help, --resume, --scheduler, a positional, a typo: reach mc decides
        if not eq:
            if k >= len(rest):
                return None
            value = rest[k]
            k += 1
        try:
            if name in ints:
                field, lo, hi = ints[name]
                number = int(value)
                if not lo <= number <= hi:
                    return None
                if field is not None:
                    values[field] = number
            elif name in floats:
                number = float(value)
                if not (math.isfinite(number) and number > 0):
                    return None
                field = floats[name]
                if isinstance(values[field], list):
                    values[field].append(number)
                else:
                    values[field] = number
        except ValueError:
            return None
    n_runs = (len(values["omegas"] or REACH_OMEGAS_DEG_S) * len(values["amaxs"] or REACH_A_MAX_MPS2)
              * values["n_x"] * values["n_y"])
    return REACH_SCENARIO, n_runs, values["workers"], reach_overrides(values["duration"])


CORTEX_REFERENCES_SCENARIO = "cortex-reference"  # = the default --scenario of `proxops cortex references`
CORTEX_REFERENCES_N = 100  # = its default --n
MAX_FIBONACCI_N = 1_000_000  # = proxops.systems.schema.cortex.MAX_FIBONACCI_N (that module imports pydantic)


def _read_cortex_references_argv(argv: list[str]):
    """(scenario, n, workers, overrides) of ``cortex references [options]`` (the arguments
    :func:`proxops.cli_cortex.references` starts the pool with) or None when in any doubt."""
    if argv[:2] != ["cortex", "references"]:
        return None
    values: dict = {"--n": CORTEX_REFERENCES_N, "--workers": None, "--scenario": CORTEX_REFERENCES_SCENARIO, "--set": []}
    rest = argv[2:]
    k = 0
    while k < len(rest):
        name, eq, value = rest[k].partition("=")
        k += 1
        if name in ("--resume", "--figures", "--no-figures", "--json") and not eq:
            continue
        if name not in values and name != "--out":
            return None  # --help, a positional, a typo: the command decides
        if not eq:
            if k >= len(rest):
                return None
            value = rest[k]
            k += 1
        if name in ("--n", "--workers"):
            try:
                number = int(value)
            except ValueError:
                return None
            if not 1 <= number <= (MAX_WORKERS if name == "--workers" else MAX_FIBONACCI_N):
                return None
            values[name] = number
        elif name == "--set":
            values["--set"].append(value)
        elif name == "--scenario":
            values["--scenario"] = value
    return values["--scenario"], values["--n"], values["--workers"], values["--set"]


def _read_mc_argv(argv: list[str]):
    """(scenario, runs, workers, overrides) or None when in any doubt."""
    argv = _without_global_options(argv)
    if not argv or argv[0] != "mc":
        return None
    values: dict = {"runs": None, "workers": None, "set": []}
    positional: list[str] = []
    rest = argv[1:]
    k = 0
    while k < len(rest):
        token = rest[k]
        k += 1
        if token == "--":
            positional.extend(rest[k:])
            break
        if not token.startswith("-") or token == "-":
            positional.append(token)
            continue
        name, eq, value = token.partition("=")
        if name in _FLAGS and not eq:
            continue
        if name not in _VALUE_OPTIONS or (eq and not name.startswith("--")):
            return None  # --help, a typo, an option added later, -n=5: mc decides
        if not eq:
            if k >= len(rest):
                return None
            value = rest[k]
            k += 1
        field = _VALUE_OPTIONS[name]
        if field == "scheduler":
            return None
        if field == "set":
            values["set"].append(value)
        elif field == "seed":  # checked like mc does, so that its error is not preceded by a pool start
            try:
                if not 0 <= int(value) < 2**63:
                    return None
            except ValueError:
                return None
        elif field == "timeout":
            try:
                if not 0 < float(value) < math.inf:
                    return None
            except ValueError:
                return None
        elif field is not None:
            try:
                number = int(value)
            except ValueError:
                return None
            if number < 1:
                return None
            values[field] = number
    if len(positional) != 1:
        return None
    return positional[0], values["runs"], values["workers"], values["set"]


def system_module(scenario: str) -> tuple[str, ...]:
    """The module of the scenario's system (for the workers to import up front), read from its TOML
    without validating it (the campaign does that); () when it cannot be told (the run imports it).
    Reads it with :mod:`proxops.scenarios.catalog`, not the loader: that imports pydantic (~0.5 s),
    and this runs before the pool starts, whose start it would delay."""
    try:
        module = SYSTEM_MODULES.get(read_toml(resolve(scenario)).get("system"))
        return (module,) if module else ()
    except Exception:  # noqa: BLE001 - a bad scenario is reported by the campaign's own check
        return ()
