"""Campaign reports: statistics tables, the system's paper-layout table and figures of a
campaign folder (the report layer, above analysis and plotting)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from proxops.analysis.campaign import CampaignResult, _campaign_system, load_campaign, series_dir
from proxops.analysis.metric_order import ordered_metrics
from proxops.analysis.formatting import format_percent, format_quantity
from proxops.analysis.statistics import METRIC_PREFIX, format_table4, metric_statistics, navigation_table, wilson_interval
from proxops.errors import ProxopsInputError
from proxops.plotting.systems import mc_figures, mc_table_figures
from proxops.report.html import write_html
from proxops.sim.result import SimResult


def write_report(campaign, report_dir: str | Path | None = None, figures: bool = True, max_overlay: int = 100) -> dict:
    """Rebuild tables and figures of a campaign folder (or CampaignResult) under ``report_dir``
    (default ``<out>/report``): statistics.csv (Table 4 layout), summary.json, report.md and
    PNG figures. Returns ``{"summary": ..., "files": [...]}``."""
    result = campaign if isinstance(campaign, CampaignResult) else load_campaign(campaign)
    if result.out is None and report_dir is None:
        raise ProxopsInputError("report: this campaign has no folder; give report_dir")
    rdir = Path(report_dir) if report_dir is not None else result.out / "report"
    rdir.mkdir(parents=True, exist_ok=True)
    table, m = result.table, result.manifest
    summary = result.summary()
    files: list[Path] = []
    stats = result.statistics()
    stats.to_csv(rdir / "statistics.csv", index_label="metric")
    files.append(rdir / "statistics.csv")
    (rdir / "summary.json").write_text(json.dumps(summary, indent=2, default=str))
    files.append(rdir / "summary.json")
    counts = result.counts()
    lines = [
        f"# Monte Carlo campaign: {m.get('scenario')}",
        "",
        f"- scenario: {_source_label(m.get('source'))}, overrides: {m.get('overrides') or 'none'}",
        f"- content hash {m.get('scenario_hash')}, campaign seed {m.get('seed')}, "
        f"{counts['runs']} of {m.get('n_runs')} runs finished",
        f"- succeeded {counts['succeeded']}, failed {counts['failed']} (of which {counts['errors']} raised), "
        f"runs with constraint violations {counts['with_violations']} {counts['violations_by_constraint'] or ''}",
        "",
        "## Statistics over runs that did not raise (layout of Wijayatunga et al. Table 4)",
        "",
        "Metrics in reading order (Δv, terminal accuracy, safety, navigation, the system's own, timings);"
        " constants and bookkeeping are left out here and kept in statistics.csv.",
        "",
        format_table4(result.headline_statistics()) if len(stats) else "(no completed runs)",
        "",
    ]
    nav = navigation_table(table) if len(table) else ""
    if nav:
        lines += ["## Estimation error (navigation filter) beside the guidance statistics", "", nav, ""]
    if counts["succeeded"] and counts["succeeded"] < counts["runs"]:
        lines += ["## Statistics over successful runs", "", format_table4(result.statistics(subset="success")), ""]
    grid_cols = [c for axis in m.get("grid_axes", []) for c in axis if c in table]
    if grid_cols and len(table) and m.get("n_grid", 1) <= 20:  # one Table 4 block per grid point (e.g. error level)
        done = table[table["outcome"] != "error"]
        for gi, grp in done.groupby("grid_index", sort=True):
            point = grp.iloc[0]
            label = ", ".join(f"{c.removeprefix('disp.')} = {format_quantity(point[c], c, significant=True)}" for c in grid_cols)
            lines += [f"### Grid point {int(gi)}: {label}", "",
                      format_table4(metric_statistics(grp, metrics=ordered_metrics(table), subset="all")), ""]
    if grid_cols and len(table):
        by = table.groupby(grid_cols, sort=True)["success"].agg(["mean", "size"]).reset_index()
        by.to_csv(rdir / "grid_success.csv", index=False)
        files.append(rdir / "grid_success.csv")
        lines += ["## Success fraction per grid point", "",
                  "| " + " | ".join(c.removeprefix("disp.") for c in grid_cols) + " | runs | success |",
                  "|" + " --- |" * (len(grid_cols) + 2)]
        for _, r in by.head(200).iterrows():
            lines.append("| " + " | ".join(format_quantity(r[c], c, significant=True) for c in grid_cols)
                         + f" | {int(r['size'])} | {format_percent(r['mean'])} |")
        lines.append("")
    errs = table[table["outcome"] == "error"] if len(table) else table
    if len(errs):
        lines += ["## Runs that raised (first 10)", ""]
        lines += [f"- run {int(r.run_id)}: {r.error}" for r in errs.head(10).itertuples()]
        lines.append("")
    system_table = _system_campaign_table(m, table) if len(table) else ""
    if system_table:
        lines += ["## Results in the paper's layout", "", system_table, ""]
        (rdir / "paper_table.md").write_text(system_table + "\n")
        files.append(rdir / "paper_table.md")
    if figures and len(table):
        # matplotlib only when figures are drawn: a campaign's parent imports this module (mc --report)
        from proxops.plotting import campaign as cplot

        figs = [
            cplot.plot_dv_distribution(table, rdir / "dv_distribution.png"),
            cplot.plot_metric_histograms(table, rdir / "metrics.png", ordered_metrics(table, include_timing=False)),
            cplot.plot_outcome_map(table, m, rdir / "outcome_map.png"),
        ]
        if result.out is not None and (result.out / "series").is_dir():
            picked = []
            for r in table.head(max_overlay).itertuples():
                d = series_dir(result.out, int(r.run_id))
                if d.is_dir():
                    picked.append((SimResult.load(d), r.outcome))
            figs.append(cplot.plot_trajectory_overlay(picked, rdir / "trajectories.png", title=f"{m.get('scenario')}: "
                                                      f"{len(picked)} trajectories"))
            figs += _system_campaign_figures(m, [res for res, _ in picked], rdir)
        figs += _system_table_figures(m, table, rdir)
        figs = list(dict.fromkeys(f for f in figs if f is not None))  # table figures may redraw a series figure
        files += figs
        lines += ["## Figures", ""] + [f"![{f.stem}]({f.name})" for f in figs] + [""]
    (rdir / "report.md").write_text("\n".join(lines))
    files.append(rdir / "report.md")
    files.append(write_html(rdir / "report.html", f"Monte Carlo campaign: {m.get('scenario')}",
                            headline(result, summary), "\n".join(lines)))
    return {"summary": summary, "files": [str(f) for f in files], "report_dir": str(rdir)}


def headline(result: CampaignResult, summary: dict) -> list[tuple[str, str, str]]:
    """The numbers a reader looks for first, as ``(label, value, note)`` cards: the success rate
    with its 95 % Wilson interval, total Δv, safety, timings."""
    table, counts = result.table, result.counts()
    n, k = counts["runs"], counts["succeeded"]
    lo, hi = wilson_interval(k, n)
    cards = [("success rate", format_percent(k / n) if n else "no runs",
              f"{k} of {n} runs; 95 % interval [{format_percent(lo)}, {format_percent(hi)}] (Wilson)" if n else "")]
    done = table[table["outcome"] != "error"] if n else table
    dv = METRIC_PREFIX + "total_dv_mps"
    if n and dv in done and done[dv].notna().any():
        v = done[dv].astype(float)
        cards.append(("total Δv (median)", format_quantity(float(v.median()), "total_dv_mps"),
                      f"p95 {format_quantity(float(v.quantile(0.95)), 'total_dv_mps')}, "
                      f"max {format_quantity(float(v.max()), 'total_dv_mps')}"))
    by = ", ".join(f"{c} {v}" for c, v in counts["violations_by_constraint"].items() if v) or "none"
    cards.append(("runs with a constraint violation", f"{counts['with_violations']} of {n}", f"by constraint: {by}"))
    verdicts = [c for c in done.columns if c.startswith(METRIC_PREFIX) and "safe" in c
                and pd.api.types.is_bool_dtype(done[c])]
    for c in verdicts[:2]:
        cards.append((c[len(METRIC_PREFIX):].replace("_", " "), f"{int(done[c].sum())} of {int(done[c].notna().sum())}",
                      "runs with the verdict true"))
    wall = summary.get("wall_time_s")
    run_wall = METRIC_PREFIX + "wall_time_s"
    note = f"median run {format_quantity(float(done[run_wall].median()), 'wall_time_s')}" \
        if n and run_wall in done and done[run_wall].notna().any() else ""
    cards.append(("campaign wall time", format_quantity(float(wall), "wall_time_s") if wall is not None else "-", note))
    return cards


def _source_label(source) -> str:
    """A built-in's name, or the scenario file's name (not this machine's absolute path)."""
    if not source:
        return "unknown"
    path = Path(str(source))
    if "scenarios/builtin" in path.as_posix():
        return f"built-in `{path.stem}`"
    return f"`{path.name}`"


def _system_campaign_figures(manifest: dict, results: list, rdir: Path) -> list[Path]:
    """Figures the scenario's own system draws from saved series (:func:`proxops.plotting.systems.mc_figures`),
    e.g. the srf Monte Carlo overlays of Figs. 5/7/10 with the approach axis and keep-out zone."""
    if not results:
        return []
    loaded = _campaign_system(manifest)
    return mc_figures(loaded.scenario.system, loaded.system, loaded.scenario, results, rdir)


def _system_table_figures(manifest: dict, table: pd.DataFrame, rdir: Path) -> list[Path]:
    """Figures the scenario's own system draws from the campaign table alone
    (:func:`proxops.plotting.systems.mc_table_figures`, e.g. cortex Figs. 13-15 from per-run traces)."""
    loaded = _campaign_system(manifest)
    return mc_table_figures(loaded.scenario.system, loaded.system, loaded.scenario, table, rdir)


def _system_campaign_table(manifest: dict, table: pd.DataFrame) -> str:
    """A Markdown table the system builds from the campaign rows (``campaign_table`` hook),
    e.g. Table 3 of Iskender 2026 for the los-sweep grid; '' if none."""
    loaded = _campaign_system(manifest)
    return loaded.system.campaign_table(loaded.scenario, table)  # default (SystemBase): ""
