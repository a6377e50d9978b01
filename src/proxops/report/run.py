"""The report of one run folder (``proxops run NAME --out DIR --report``): DIR/report.html, one
self-contained page (:mod:`proxops.report.html`) with the headline first -- how the run ended,
Δv, final and minimum range, wall time -- then every summary value and the run's figures."""

from __future__ import annotations

from pathlib import Path

from proxops.analysis.formatting import format_quantity
from proxops.report.html import write_html
from proxops.runner import summary_markdown


def write_run_report(out: Path, summary: dict) -> Path:
    """Write ``out/report.html`` from the run's summary and the figures saved in ``out``."""

    out = Path(out)
    ok = summary.get("success")
    cards = [("outcome", str(summary.get("status", "?")),
              ("success" if ok else "failed") + (f"; stopped: {summary['stop_reason']}" if summary.get("stop_reason") else "")),
             ("total Δv", format_quantity(summary.get("total_dv_mps", float("nan")), "total_dv_mps"), ""),
             ("final range", format_quantity(summary.get("final_range_m", float("nan")), "final_range_m"),
              f"minimum {format_quantity(summary.get('min_range_m', float('nan')), 'min_range_m')}"),
             ("wall time", format_quantity(summary.get("wall_time_s", float("nan")), "wall_time_s"),
              f"{format_quantity(summary.get('sim_time_s', float('nan')), 'sim_time_s')} simulated")]
    lines = [f"# Run: {summary.get('scenario')}", "", "## Summary", ""] + summary_markdown(summary) + [""]
    figures = sorted(out.glob("*.png"))
    if figures:
        lines += ["## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figures] + [""]
    return write_html(out / "report.html", f"Run: {summary.get('scenario')} ({summary.get('system')})", cards,
                      "\n".join(lines))
