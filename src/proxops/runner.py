"""Run a scenario end to end: load -> build -> simulate -> summarise -> save.

A system may run several closed loops for one scenario (e.g. with and without a
constraint); it then defines ``run(sc, seed, progress) -> (summary, {label: SimResult})``.
Otherwise the default is one ``simulate(system.build(sc))``.
"""

from __future__ import annotations

import json
import logging
import sys
import time
from pathlib import Path

from proxops.errors import input_error
from proxops.scenarios.loader import LoadedScenario, load_scenario
from proxops.analysis.runs import execute  # noqa: F401 (re-exported)
from proxops.sim.result import SimResult
from proxops.analysis.formatting import format_quantity
from proxops.plotting.systems import run_figures

log = logging.getLogger("proxops.runner")


def run_scenario(name_or_path, overrides=(), seed: int | None = None, out: Path | None = None,
                 figures: bool = True, progress: bool = False, oem: Path | None = None,
                 mat: Path | None = None) -> dict:
    """Load (a file or built-in name; or a :class:`LoadedScenario` as it is), run and (with ``out``)
    save one scenario; returns the summary dict. ``oem``/``mat``: also write CCSDS OEM / MATLAB
    files (:mod:`proxops.analysis.export`; summary key ``export``)."""
    loaded = name_or_path if isinstance(name_or_path, LoadedScenario) else load_scenario(name_or_path, list(overrides))
    if oem is not None or mat is not None:
        # optional outputs, imported when asked: analysis.export re-runs campaigns (pandas, pyarrow) and
        # propagates the truth (numba, scipy), which a plain run of a light system does not import
        from proxops.analysis import export
    if oem is not None:
        export.check_exportable(loaded.scenario)  # before the run, not after it
    log.debug("%s: %s scenario loaded from %s", loaded.scenario.name, loaded.scenario.system, loaded.source)
    start = time.perf_counter()
    summary, results = execute(loaded, seed=seed, progress=progress)
    log.info("%s: ran in %.1f s, status %s", loaded.scenario.name, time.perf_counter() - start, summary.get("status"))
    if out is not None:
        save_run(loaded, summary, results, Path(out), figures=figures)
        summary["out"] = str(out)
        log.info("%s: time series, summary%s written to %s", loaded.scenario.name, " and figures" if figures else "", out)
    if oem is not None or mat is not None:
        summary["export"] = export.export_run(loaded, summary, results, oem=oem, mat=mat)
    return summary


def save_run(loaded, summary: dict, results: dict[str, SimResult], out: Path, figures: bool = True) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    for label, result in results.items():
        result.save(out / label)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str))
    (out / "scenario.json").write_text(json.dumps(loaded.scenario.model_dump(mode="json", exclude_none=True), indent=2))
    paths: list[Path] = []
    if figures:
        paths = run_figures(loaded.scenario.system, loaded.system, loaded.scenario, results, out)
    return paths


DEMO_SCENARIOS = ("srf-vbar", "srf-rbar", "los-tumble", "cortex-nominal", "hybrid-capture", "underactuated-case1")  # one or more per system
# Seconds of each demo scenario on a fresh install (numba compiles its kernels; `make demo` from a fresh clone on
# 2 workers, 2026-11-28): only their order matters, the longest goes first (run_demo). With a warm cache the
# same order also balances the two workers (hybrid-capture 5.4 s, underactuated 2.7, srf-vbar 2.5, los 1.4,
# srf-rbar and cortex-nominal 0.8 s in one process).
DEMO_SECONDS = {"hybrid-capture": 78.0, "cortex-nominal": 68.0, "srf-vbar": 35.0, "los-tumble": 12.0,
                "underactuated-case1": 9.0, "srf-rbar": 2.0}


def run_demo(out: Path, workers: int | None = None) -> Path:
    """Run the demonstration scenarios, write each under ``out/<name>`` and a Markdown report (sections in
    :data:`DEMO_SCENARIOS` order). The scenarios run side by side on ``workers`` local processes (default:
    the usable CPUs, at most one per scenario; 1 = one after another in this process), the longest first
    (:data:`DEMO_SECONDS`), so the workers finish together (figures are most of a warm demo, compiling the
    kernels most of a first one)."""
    from proxops.exec.backends import MAX_WORKERS, default_workers, map_runs  # (not on `proxops run`'s path)

    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise input_error("--workers", workers, f"must be a whole number from 1 to {MAX_WORKERS} (1 = in this process)")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    n = len(DEMO_SCENARIOS)
    order = sorted(range(n), key=lambda k: -DEMO_SECONDS.get(DEMO_SCENARIOS[k], 0.0))
    workers = min(n, default_workers() if workers is None else workers)
    # one line per stage on stderr, also when it is a log file and not a terminal
    _stage(f"[demo] {n} scenarios on {workers} worker process{'es' if workers > 1 else ''} (the first run of each "
           "process loads, or on a fresh install compiles, the numba kernels)")

    def done(i: int, res: dict) -> None:  # i: the position in ``order``
        k = order[i]
        _stage(f"[demo {k + 1}/{n}] {DEMO_SCENARIOS[k]}: {res['status']} in {res['seconds']:.1f} s")

    results = map_runs(demo_scenario, [(DEMO_SCENARIOS[k], str(out)) for k in order], workers=workers, chunk_size=1,
                       on_result=done, finish_in_flight=False)  # a Ctrl-C stops the demo at once
    sections = dict(zip(order, results))
    lines = ["# proxops demo report", ""]
    for k in range(n):
        lines += sections[k]["lines"]
    report = out / "report.md"
    report.write_text("\n".join(lines))
    return report


def demo_scenario(item: tuple[str, str]) -> dict:
    """One scenario of :func:`run_demo` (``item``: its name and the demo folder), in a worker process: run,
    save under ``<folder>/<name>``; its outcome, seconds and report section."""
    name, folder = item
    out = Path(folder)
    start = time.perf_counter()
    loaded = load_scenario(name)
    summary, results = execute(loaded, progress=False)
    figs = save_run(loaded, summary, results, out / name)
    lines = [f"## {name}", "", loaded.scenario.description, ""] + summary_markdown(summary) + [""]
    lines += [f"![{p.stem}]({p.relative_to(out)})" for p in figs] + [""]
    return {"status": summary.get("status", "?"), "seconds": time.perf_counter() - start, "lines": lines}


def _stage(line: str) -> None:
    """One progress line on stderr, flushed at once (a log reader sees each stage as it ends)."""
    print(line, file=sys.stderr, flush=True)


def summary_markdown(summary: dict) -> list[str]:
    """``| metric | value |`` rows of a run summary, each value rounded to the resolution of its unit
    and shown with it (summary.json and --json keep full precision)."""
    lines = ["| metric | value |", "| --- | --- |"]
    for key, val in summary.items():
        if not isinstance(val, (dict, list)):
            lines.append(f"| {key} | {format_quantity(val, key)} |")
    return lines
