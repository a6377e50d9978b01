"""Which figures a system's runs get: found by convention, so systems never import plotting.

A module ``proxops.plotting.<system>`` may define

- ``run_figures(sc, results: dict[label, SimResult], out_dir) -> list[Path]`` (``proxops run --out``)
- ``mc_figures(sc, results: list[SimResult], out_dir) -> list[Path]`` (campaign reports, saved series)
- ``mc_table_figures(sc, table: DataFrame, out_dir) -> list[Path]`` (campaign reports from the table
  alone, drawn with or without saved series)

A system object may still carry ``figures`` / ``campaign_figures`` hooks (systems outside
proxops); they take precedence. Without either, a run gets :func:`plot_run`.
"""

from __future__ import annotations

import importlib
from pathlib import Path


def _module(system_name: str):
    try:
        return importlib.import_module(f"proxops.plotting.{system_name}")
    except ModuleNotFoundError as exc:
        if exc.name != f"proxops.plotting.{system_name}":
            raise
        return None


def _draw(system_name: str, system, hook: str, function: str, sc, results, out_dir) -> list[Path] | None:
    """The system's own hook if it has one, else ``proxops.plotting.<system>.<function>``, else None."""
    draw = getattr(system, hook, None)
    if draw is None:
        mod = _module(system_name)
        draw = getattr(mod, function, None) if mod is not None else None
    return None if draw is None else list(draw(sc, results, Path(out_dir)))


def run_figures(system_name: str, system, sc, results: dict, out_dir: Path) -> list[Path]:
    """Figures of one run (all its labelled results) under ``out_dir``."""
    paths = _draw(system_name, system, "figures", "run_figures", sc, results, out_dir)
    if paths is not None:
        return paths
    # matplotlib only when a figure is drawn: report.campaign imports this dispatcher at module level
    # and a campaign's parent process (which draws nothing without --report) must stay free of it
    from proxops.plotting.common import plot_run

    return [plot_run(next(iter(results.values())), Path(out_dir) / "trajectory.png", title=sc.name)]


def mc_figures(system_name: str, system, sc, results: list, out_dir: Path) -> list[Path]:
    """System-specific figures of a campaign from saved series ([] when the system has none)."""
    return _draw(system_name, system, "campaign_figures", "mc_figures", sc, results, out_dir) or []


def mc_table_figures(system_name: str, system, sc, table, out_dir: Path) -> list[Path]:
    """System-specific figures of a campaign from its table alone ([] when the system has none)."""
    return _draw(system_name, system, "campaign_table_figures", "mc_table_figures", sc, table, out_dir) or []
