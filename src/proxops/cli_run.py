"""``proxops run`` and ``proxops demo``: one closed-loop simulation, the demonstration scenarios.

Imported by :mod:`proxops.cli` only when one of these commands runs (its lazy command table).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from proxops import runner
from proxops.analysis.formatting import format_quantity
from proxops.cli_common import EXIT_RUN_FAILED, STATE, check_out_dir, check_out_file, emit
from proxops.errors import input_error
from proxops.report.run import write_run_report
from proxops.scenarios.loader import load_scenario


def run(
    scenario: Annotated[str, typer.Argument(help="Scenario file or built-in name.")],
    out: Annotated[Optional[Path], typer.Option("--out", help="Write time series (Parquet), summary and figures here.")] = None,
    set_: Annotated[list[str], typer.Option("--set", help="Override a key: --set sim.duration_s=600.")] = [],
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed (default: sim.seed).")] = None,
    figures: Annotated[bool, typer.Option("--figures/--no-figures", help="Draw figures when --out is given.")] = True,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout.")] = False,
    oem: Annotated[Optional[Path], typer.Option("--oem", help="CCSDS OEM of the chaser (+ -target, -hill files).")] = None,
    mat: Annotated[Optional[Path], typer.Option("--mat", help="MATLAB .mat of the time series and summary.")] = None,
    report: Annotated[bool, typer.Option("--report", help="Also write OUT/report.html (headline, summary, figures; needs --out).")] = False,
):
    """Run one closed-loop simulation and print its summary (exit code 4 if the run finished but failed)."""
    if seed is not None and not 0 <= seed < 2**63:
        raise input_error("--seed", seed, "allowed a whole number from 0 to 2^63 - 1")
    if report and out is None:
        raise input_error("--report", True, "needs --out DIR (the report is DIR/report.html beside the figures)")
    if out is not None:
        check_out_dir(out)
    check_out_file(oem, "--oem")
    check_out_file(mat, "--mat")
    loaded = load_scenario(scenario, set_)
    summary = runner.run_scenario(loaded, seed=seed, out=out, figures=figures,
                           progress=not as_json and not STATE["quiet"], oem=oem, mat=mat)
    if report:
        summary["report"] = str(write_run_report(out, summary))
    emit(summary, as_json, format_summary(summary))
    if not summary["success"]:  # the system's own test, as campaigns count it (analysis.runs.execute)
        typer.echo(f"error: the run finished but failed (status {summary.get('status')!r}); exit code "
                   f"{EXIT_RUN_FAILED}", err=True)
        raise typer.Exit(EXIT_RUN_FAILED)


RUN_LINE_KEYS = ("status", "docked", "steps", "dock_time_s", "final_range_m", "total_dv_mps", "value_function_increases",
                 "mean_iterations", "controller_wall_time_s")


def format_summary(s: dict) -> str:
    """The readable run summary: every number rounded to the resolution of its unit and shown
    with it, nested blocks as ``key  sub value, sub value`` (``--json`` keeps full precision)."""
    def q(key: str) -> str:
        return format_quantity(s[key], key)

    solve = s.get("solve_time_ms") or {}
    events = ", ".join(f"{kind} {count}" for kind, count in (s.get("events") or {}).items()) or "none"
    lines = [
        f"scenario      {s.get('scenario', '')} ({s.get('system', '')})",
        f"status        {s['status']}" + (f" ({'success' if s['success'] else 'failed'}"
                                            + (f"; stopped: {s['stop_reason']})" if s.get("stop_reason") else ")")
                                            if "success" in s else ""),
        f"final range   {q('final_range_m')}, speed {q('final_speed_mps')}",
        f"min range     {q('min_range_m')}",
        f"total dv      {q('total_dv_mps')}",
        f"sim time      {q('sim_time_s')} in {q('wall_time_s')} wall",
        f"solve time    median {format_quantity(solve.get('median', 0.0), 'solve_time_ms')}, "
        f"p95 {format_quantity(solve.get('p95', 0.0), 'solve_time_ms')}",
        f"events        {events}",
    ]
    skip = {"scenario", "system", "status", "final_range_m", "final_speed_mps", "min_range_m", "total_dv_mps",
            "sim_time_s", "wall_time_s", "solve_time_ms", "events", "steps", "solver_failures", "out", "export"}
    extra = [k for k, v in s.items() if k not in skip and not isinstance(v, list)]
    width = max([13, *(len(k) for k in extra)])
    for key in extra:  # rounded to the resolution of its unit (--json keeps full precision)
        value = s[key]
        if isinstance(value, dict) and value and all(isinstance(v, dict) for v in value.values()):
            # one closed loop per line (e.g. the general and averaged NMPC of underactuated-compare)
            lines.append(f"{key}")
            for label, sub in value.items():
                shown = [k for k in RUN_LINE_KEYS if k in sub] or [k for k, v in sub.items() if not isinstance(v, (dict, list))][:6]
                lines.append(f"  {label}: " + ", ".join(f"{k} {format_quantity(sub[k], k)}" for k in shown))
            continue
        if isinstance(value, dict):
            parts = [f"{sub} {format_quantity(v, key if sub in ('median', 'p95', 'max', 'min', 'mean') else sub)}"
                     for sub, v in value.items() if not isinstance(v, (dict, list))]
            text = ", ".join(parts) or "-"
        else:
            text = format_quantity(value, key)
        lines.append(f"{key:<{width}} {text}")
    if "out" in s:
        lines.append(f"written to    {s['out']}")
    for role, path in (s.get("export") or {}).items():
        lines.append(f"{role:<13} {path}")
    return "\n".join(lines)


def demo(out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out"),
         workers: Annotated[Optional[int], typer.Option("--workers", "-w", help="Local worker processes (default: usable CPUs; 1 = in this process).")] = None):
    """Run the built-in demonstration scenarios and write a report under OUT."""
    report = runner.run_demo(check_out_dir(out), workers=workers)
    typer.echo(f"demo report written to {report}")
