"""``proxops mc`` and ``proxops report``: Monte Carlo campaigns from the command line.

Listed in the lazy command table of :mod:`proxops.cli` (input errors -> one line, exit code 2).
"""

from __future__ import annotations

import json
import logging
import math
import sys
from pathlib import Path
from typing import Annotated, Optional

import typer

from proxops.analysis.campaign import CampaignInterrupted, load_campaign, run_campaign
from proxops.analysis.statistics import format_navigation_consistency, format_text_table
from proxops.cli_common import Interrupted, check_out_dir
from proxops.errors import ProxopsError, ProxopsInputError
from proxops.exec.backends import MAX_WORKERS
from proxops.exec.prestart import prestart
from proxops.report.campaign import write_report


def mc(
    scenario: Annotated[str, typer.Argument(help="Scenario file or built-in name (its dispersions table says what varies).")],
    runs: Annotated[Optional[int], typer.Option("--runs", "-n", help="Number of runs (default: the grid size when the dispersions declare grids; on --resume the folder's).")] = None,
    workers: Annotated[Optional[int], typer.Option("--workers", "-w", help="Local worker processes (default: usable CPUs; 1 = in this process).")] = None,
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", help="Dask scheduler tcp://HOST:PORT or scheduler file (JSON).")] = None,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Campaign seed (default: the scenario's sim.seed).")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="Results folder (default: out/mc-<scenario>).")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Complete the campaign in --out: run only what is missing.")] = False,
    set_: Annotated[list[str], typer.Option("--set", help="Override a key: --set sim.duration_s=600.")] = [],
    series: Annotated[bool, typer.Option("--series/--no-series", help="Keep every run's time series (Parquet) for overlays.")] = False,
    report_: Annotated[bool, typer.Option("--report/--no-report", help="Write tables and figures under OUT/report when done.")] = False,
    connect_timeout_s: Annotated[float, typer.Option("--connect-timeout-s", help="Give up connecting to --scheduler after this many seconds.")] = 5.0,
    progress: Annotated[bool, typer.Option("--progress/--no-progress", help="Progress bar on stderr (done, failed, ETA).")] = True,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout: runs, succeeded, failed, wall_time_s, statistics.")] = False,
):
    """Run a Monte Carlo campaign of a scenario (local processes or Dask) and print its statistics."""
    if runs is not None and runs < 1:
        raise ProxopsInputError(f"--runs {runs}: give a whole number of runs >= 1")
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise ProxopsInputError(f"--workers {workers}: give a whole number from 1 to {MAX_WORKERS} (1 runs in this "
                                "process)")
    if not (math.isfinite(connect_timeout_s) and connect_timeout_s > 0):
        raise ProxopsInputError(f"--connect-timeout-s {connect_timeout_s}: give a positive, finite number of seconds")
    if seed is not None and not 0 <= seed < 2**63:
        raise ProxopsInputError(f"--seed {seed}: give a whole number from 0 to 2^63 - 1")
    out = out if out is not None else Path("out") / f"mc-{Path(scenario).stem}"
    check_out_dir(out, campaign=True)
    if scheduler is None:  # local workers start now (if proxops.exec.entry has not): their imports overlap ours
        prestart(scenario, runs, workers, set_)
    log = logging.getLogger("proxops.mc")
    log.debug("campaign %s: %s runs on %s, results in %s", scenario, runs if runs is not None else "all grid",
             scheduler or f"{workers or 'all usable'} local worker(s)", out)
    try:
        result = run_campaign(scenario, n_runs=runs, workers=workers, scheduler=scheduler, seed=seed, out=out,
                              resume=resume, overrides=set_, progress=progress, keep_series=series,
                              connect_timeout_s=connect_timeout_s)
    except CampaignInterrupted as exc:
        raise Interrupted(f"{exc} (`proxops mc {scenario} --out {out} --resume`)") from None
    except ProxopsError as exc:
        if isinstance(exc, ProxopsInputError):
            raise
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(1)
    summary = result.summary()
    if summary["succeeded"]:  # a campaign where every run failed ends on its one error line (exit 3)
        log.info("campaign %s: %d runs finished in %.1f s, %d succeeded", scenario, summary["runs"],
                 result.wall_time_s, summary["succeeded"])
    if report_:
        summary["report"] = write_report(result)["report_dir"]
    if as_json:
        sys.stdout.write(json.dumps(summary, default=str) + "\n")
    else:
        typer.echo(format_campaign(summary, result.headline_statistics()))
        if report_ and (Path(summary["report"]) / "paper_table.md").is_file():
            typer.echo("\n" + (Path(summary["report"]) / "paper_table.md").read_text())
    if summary["runs"] and not summary["succeeded"]:  # finished, but nothing worked: scripts must see it
        typer.echo(f"error: all {summary['runs']} runs failed (first error: {_first_error(result)}); "
                   "exit code 3", err=True)
        raise typer.Exit(3)


def _first_error(result) -> str:
    t = result.table
    bad = t[t["error"].astype(str) != ""] if "error" in t else t.iloc[0:0]
    if len(bad):
        return str(bad["error"].iloc[0])[:200]
    return f"status {t['status'].iloc[0]!r}" if "status" in t and len(t) else "unknown"


def report(
    folder: Annotated[Path, typer.Argument(help="Campaign folder written by `proxops mc`.")],
    report_dir: Annotated[Optional[Path], typer.Option("--report-dir", help="Where to write (default: FOLDER/report).")] = None,
    figures: Annotated[bool, typer.Option("--figures/--no-figures", help="Draw the figures.")] = True,
    max_overlay: Annotated[int, typer.Option("--max-overlay", help="Trajectories drawn in the overlay (saved series only).")] = 100,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout.")] = False,
):
    """Rebuild the statistics tables, report.md and figures of a campaign folder."""
    if max_overlay < 0:
        raise ProxopsInputError(f"--max-overlay {max_overlay}: give a whole number >= 0")
    result = load_campaign(folder)
    check_out_dir(report_dir if report_dir is not None else Path(folder) / "report", "--report-dir")
    done = write_report(result, report_dir, figures=figures, max_overlay=max_overlay)
    if as_json:
        sys.stdout.write(json.dumps(done, default=str) + "\n")
        return
    text = format_campaign(done["summary"], result.headline_statistics())
    typer.echo(text + f"\nreport written to {done['report_dir']} ({len(done['files'])} files)")


def format_campaign(summary: dict, stats) -> str:
    wall = summary.get("wall_time_s")
    wall_text = f" ({summary.get('new_runs', 0)} new in {wall:.1f} s)" if isinstance(wall, (int, float)) and math.isfinite(wall) else ""
    lines = [
        f"campaign      {summary.get('scenario')}  seed {summary.get('seed')}",
        f"runs          {summary['runs']} of {summary['n_runs']}{wall_text}",
        f"succeeded     {summary['succeeded']}",
        f"failed        {summary['failed']} ({summary['errors']} raised)",
        f"violations    {summary['with_violations']} runs {summary.get('violations_by_constraint') or ''}",
    ]
    if summary.get("navigation_consistency"):
        lines.append(format_navigation_consistency(summary["navigation_consistency"]))
    lines += [
        "",
        format_text_table(stats) if len(stats) else "(no completed runs)",
    ]
    if summary.get("report"):
        lines.append(f"\nreport written to {summary['report']} (report.html, report.md, figures)")
    elif summary.get("out"):
        lines.append(f"\nresults in {summary['out']}; `proxops report {summary['out']}` draws tables and figures")
    return "\n".join(lines)
