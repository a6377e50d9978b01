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


def run_demo(out: Path) -> Path:
    """Run the demonstration scenarios, write each under ``out/<name>`` and a Markdown report."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    lines = ["# proxops demo report", ""]
    for k, name in enumerate(DEMO_SCENARIOS, start=1):
        # one line per stage on stderr, also when it is a log file and not a terminal
        first = " (includes the one-time compilation of the numba kernels)" if k == 1 else ""
        _stage(f"[demo {k}/{len(DEMO_SCENARIOS)}] {name}: running{first}")
        start = time.perf_counter()
        loaded = load_scenario(name)
        summary, results = execute(loaded, progress=True)
        figs = save_run(loaded, summary, results, out / name)
        _stage(f"[demo {k}/{len(DEMO_SCENARIOS)}] {name}: {summary.get('status', '?')} in {time.perf_counter() - start:.1f} s")
        lines += [f"## {name}", "", loaded.scenario.description, ""] + summary_markdown(summary)
        lines.append("")
        lines += [f"![{p.stem}]({p.relative_to(out)})" for p in figs]
        lines.append("")
    report = out / "report.md"
    report.write_text("\n".join(lines))
    return report


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
