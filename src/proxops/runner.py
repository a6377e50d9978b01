"""Run a scenario end to end: load -> build -> simulate -> summarise -> save.

A system may run several closed loops for one scenario (e.g. with and without a
constraint) by overriding ``run(sc, seed, progress) -> (summary, {label: SimResult})``; the
default (:class:`proxops.systems.base.SystemBase`) is one ``simulate(system.build(sc))``.
"""

from __future__ import annotations

import json
from pathlib import Path

from proxops.scenarios.loader import load_scenario
from proxops.sim.result import SimResult


def execute(loaded, seed: int | None = None, progress: bool = False) -> tuple[dict, dict[str, SimResult]]:
    """Run a loaded scenario; returns the summary and the results by label."""
    sc, system = loaded.scenario, loaded.system
    seed = sc.sim.seed if seed is None else seed
    extra, results = system.run(sc, seed=seed, progress=progress)
    main = next(iter(results.values()))
    summary = {"scenario": sc.name, "system": sc.system, **main.summary(), **extra}
    summary["seed"] = seed
    return summary, results


def check_scenario(loaded) -> None:
    """Every check a run makes before its first step: the schema (done when loading), the
    system's build (geometry, feasibility of the hop ladder, KOZ vs start...) and the
    dispersions table. Raises ProxopsInputError with one line; ``validate`` and ``mc`` call it."""
    from proxops.analysis.dispersions import parse_dispersions

    loaded.system.check(loaded.scenario)  # default: build; planners without a closed loop check without building
    parse_dispersions(loaded.scenario, loaded.scenario.dispersions)


def run_scenario(name_or_path: str, overrides=(), seed: int | None = None, out: Path | None = None,
                 figures: bool = True, progress: bool = False) -> dict:
    """Load, run and (with ``out``) save one scenario; returns the summary dict."""
    loaded = load_scenario(name_or_path, list(overrides))
    summary, results = execute(loaded, seed=seed, progress=progress)
    if out is not None:
        save_run(loaded, summary, results, Path(out), figures=figures)
        summary["out"] = str(out)
    return summary


def save_run(loaded, summary: dict, results: dict[str, SimResult], out: Path, figures: bool = True) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    for label, result in results.items():
        result.save(out / label)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str))
    paths: list[Path] = []
    if figures:
        drawn = loaded.system.figures(loaded.scenario, results, out)
        if drawn is not None:
            paths = list(drawn)
        else:
            from proxops.plotting.common import plot_run

            paths = [plot_run(next(iter(results.values())), out / "trajectory.png", title=loaded.scenario.name)]
    return paths


DEMO_SCENARIOS = ("srf-vbar", "srf-rbar", "los-tumble", "underactuated-case1")


def run_demo(out: Path) -> Path:
    """Run the demonstration scenarios, write each under ``out/<name>`` and a Markdown report."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    lines = ["# proxops demo report", ""]
    for name in DEMO_SCENARIOS:
        loaded = load_scenario(name)
        summary, results = execute(loaded, progress=True)
        figs = save_run(loaded, summary, results, out / name)
        lines += [f"## {name}", "", loaded.scenario.description, ""] + summary_markdown(summary)
        lines.append("")
        lines += [f"![{p.stem}]({p.relative_to(out)})" for p in figs]
        lines.append("")
    report = out / "report.md"
    report.write_text("\n".join(lines))
    return report


def summary_markdown(summary: dict) -> list[str]:
    """``| metric | value |`` rows of a run summary, each value rounded to the resolution of its unit
    and shown with it (summary.json and --json keep full precision)."""
    from proxops.analysis.formatting import format_quantity

    lines = ["| metric | value |", "| --- | --- |"]
    for key, val in summary.items():
        if not isinstance(val, (dict, list)):
            lines.append(f"| {key} | {format_quantity(val, key)} |")
    return lines
