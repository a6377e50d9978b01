"""One run of a Monte Carlo campaign, as a pool or Dask worker executes it.

Kept free of pandas and the campaign's storage and statistics (the parent's business): a spawned
worker unpickles :func:`campaign_run` from here, so its cold start imports only what a run needs
(scenarios, the system, the engine). :mod:`proxops.analysis.campaign` re-exports these names.
"""

from __future__ import annotations

import copy
import json
import math
import time
import traceback
from dataclasses import dataclass
from typing import Any

import importlib

import numpy as np

from proxops.analysis.runs import execute
from proxops.scenarios.dispersions import apply_values
from proxops.scenarios.loader import validate_scenario

METRIC_PREFIX = "metric."
DISP_PREFIX = "disp."


@dataclass(frozen=True)
class CampaignSpec:
    """What every worker needs to run any run of a campaign (sent once per worker)."""

    data: dict  # scenario TOML data after overrides, without [dispersions]
    system: str
    system_module: str
    source: str
    scenario_hash: str
    keep_series: bool = False


@dataclass(frozen=True)
class RunItem:
    run_id: int
    seed: int
    grid_index: int
    values: dict  # {dispersed key path: value}


_PREPARED: dict[str, tuple] = {}


def _prepared(spec: CampaignSpec):
    """(system, nominal validated scenario) of a spec, cached per process."""
    got = _PREPARED.get(spec.scenario_hash)
    if got is None:
        if spec.system_module:
            importlib.import_module(spec.system_module)
        loaded = validate_scenario(copy.deepcopy(spec.data), (), source=spec.source)
        got = (loaded.system, loaded.scenario)
        _PREPARED[spec.scenario_hash] = got
    return got


def check_nominal(spec: CampaignSpec, _item=None) -> None:
    """The system's check of the campaign's nominal scenario (default: its build) in this process,
    raising ProxopsInputError as :func:`proxops.scenarios.loader.check_scenario` does. Run by each pool
    worker before the campaign's runs, it is also the worker's warm-up: imports, numba kernels and
    the per-process caches of the build."""
    system, nominal = _prepared(spec)
    system.check(nominal)


def campaign_run(spec: CampaignSpec, item: RunItem):
    """Run one dispersed closed loop; returns ``(row, SimResult or None)``. Never raises:
    an exception becomes ``outcome = "error"`` with its message."""
    t0, cpu0 = time.perf_counter(), time.process_time()
    row: dict[str, Any] = {"run_id": int(item.run_id), "seed": int(item.seed), "grid_index": int(item.grid_index)}
    row.update({DISP_PREFIX + k: v for k, v in item.values.items()})
    series = None
    try:
        system, nominal = _prepared(spec)
        data = apply_values(copy.deepcopy(spec.data), item.values, nominal)
        loaded = validate_scenario(data, (), source=f"{spec.source} (run {item.run_id})")
        summary, results = execute(loaded, seed=item.seed)
        main = next(iter(results.values()))
        for name, value in (main.meta.get("max_violation") or {}).items():
            summary.setdefault("max_violation", {})[name] = float(value)
        ok = classify(system, loaded.scenario, summary)
        row.update(outcome="success" if ok else "failure", success=bool(ok), status=str(summary.get("status", "")),
                   error="")
        row.update(flatten_summary(summary))
        if spec.keep_series:
            series = main
    except Exception as exc:
        row.update(outcome="error", success=False, status="error", error=f"{type(exc).__name__}: {exc}",
                   error_traceback=traceback.format_exc(limit=20)[-4000:])
    row["run_wall_s"] = time.perf_counter() - t0
    row["run_cpu_s"] = time.process_time() - cpu0
    return row, series


def classify(system, sc, summary: dict) -> bool:
    """Success of one run: ``system.success(sc, summary)`` (default: SystemBase.success, the run
    did not end in a failed status)."""
    return bool(system.success(sc, summary))


_SKIP_SUMMARY = {"scenario", "system", "seed", "out", "status"}


def flatten_summary(summary: dict) -> dict:
    """Run summary -> ``{"metric.a.b": scalar}`` (lists as JSON text, None as NaN)."""
    out: dict[str, Any] = {}

    def walk(prefix: str, val) -> None:
        if isinstance(val, dict):
            for k, v in val.items():
                walk(f"{prefix}.{k}" if prefix else str(k), v)
        elif isinstance(val, (list, tuple, np.ndarray)):
            out[METRIC_PREFIX + prefix] = json.dumps(np.asarray(val).tolist() if isinstance(val, np.ndarray) else val,
                                                     default=str)
        elif val is None:
            out[METRIC_PREFIX + prefix] = math.nan
        elif isinstance(val, np.generic):
            out[METRIC_PREFIX + prefix] = val.item()
        elif isinstance(val, (bool, int, float, str)):
            out[METRIC_PREFIX + prefix] = val
        else:
            out[METRIC_PREFIX + prefix] = str(val)

    for key, val in summary.items():
        if key not in _SKIP_SUMMARY:
            walk(key, val)
    return out


