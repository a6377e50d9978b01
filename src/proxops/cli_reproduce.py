"""``proxops reproduce``: the command behind every headline claim, one table (see
:mod:`proxops.report.reproduction` for the claims and their verdicts)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from proxops.cli_common import emit, check_out_dir
from proxops.report.reproduction import markdown, reproduce as run, write_markdown


def reproduce(
    system: Annotated[str, typer.Argument(help="srf, los, reach, underactuated, cortex, hybrid or all.")] = "all",
    quick: Annotated[bool, typer.Option("--quick", help="Reduced campaigns (goal < 2 min on 2 cores); reduced rows say so.")] = False,
    out: Annotated[Optional[Path], typer.Option("--out", help="Folder for reproduction.md, campaigns and figures "
                                                "(default: out/ for a full run, nothing for --quick).")] = None,
    workers: Annotated[int, typer.Option("--workers", help="Local worker processes for the campaigns.")] = 2,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout.")] = False,
):
    """Run the commands behind every paper claim and print claim | paper | ours | verdict, our own goals
    (wall times, Monte Carlo success rates) in a separate table, and the *-ekf navigation table (with all).
    Campaigns are cached under OUT/cache and reused by the next run."""

    if out is None and not quick:
        out = Path("out")
    if out is not None:
        check_out_dir(out)
    result = run(system, quick=quick, out=out, workers=workers, progress=not as_json)
    if out is not None:
        result["report"] = str(write_markdown(result, Path(out) / "reproduction.md"))
    text = markdown(result, notes=False)
    text += f"\ntotal wall time {result['wall_time_s']:.1f} s"
    if "report" in result:
        text += f"\nwritten to {result['report']}"
    emit(result, as_json, text)
