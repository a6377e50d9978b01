"""The ``proxops`` command line: a thin layer over scenarios, the simulator and analysis.

Every command prints a readable summary, or with ``--json`` exactly one JSON object
on stdout. Input errors print one line and exit with code 2 (traceback with --debug).

One mechanism keeps the command line fast: the lazy command table :data:`COMMANDS`. Each command
lives in a ``cli_*`` module that is imported only when that command runs or prints its own
``--help`` (:class:`proxops.cli_common.LazyCommandGroup`); ``proxops --help`` lists the table's
short help and imports no command module, ``proxops keys`` imports ``cli_keys`` and what it needs.
Inside a command module the imports are at module level, except those only an option needs
(figures, reports: matplotlib) and those that must follow the early start of a campaign's pool.
"""

from __future__ import annotations

import os

# The MPCs solve many small dense problems: BLAS threads only compete for the cores
# (measured: closed-loop DAQP update+solve 0.4 ms -> 0.24 ms with one thread).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from typing import Annotated  # noqa: E402

import typer  # noqa: E402

from proxops import __version__  # noqa: E402
from proxops.cli_common import (EXIT_CODES_HELP, STATE, LazyCommand, LazyCommandGroup,  # noqa: E402
                                configure_logging, guarded, make_app)

# name -> where the command lives and the short help ``proxops --help`` shows before importing it
# (the first line of the command's docstring; tests/test_local_imports.py checks they agree).
COMMANDS = {
    "scenarios": LazyCommand("proxops.cli_scenarios", "scenarios", "command", "List the built-in scenarios."),
    "validate": LazyCommand("proxops.cli_validate", "validate", "command",
                            "Validate a scenario file (exit 0 if valid, 2 with a one-line error otherwise)."),
    "run": LazyCommand("proxops.cli_run", "run", "command",
                       "Run one closed-loop simulation and print its summary (exit code 4 if the run finished but failed)."),
    "demo": LazyCommand("proxops.cli_run", "demo", "command",
                        "Run the built-in demonstration scenarios and write a report under OUT."),
    "hop-times": LazyCommand("proxops.cli_srf", "hop_times", "command",
                             "Hop distances and times of the SRF guidance expert (Algorithm 1, eqs. 8, 14, 17-25)."),
    "mc": LazyCommand("proxops.cli_campaign", "mc", "command",
                      "Run a Monte Carlo campaign of a scenario (local processes or Dask) and print its statistics."),
    "report": LazyCommand("proxops.cli_campaign", "report", "command",
                          "Rebuild the statistics tables, report.md and figures of a campaign folder."),
    "keys": LazyCommand("proxops.cli_keys", "keys", "command",
                        "Every scenario key of a system: unit, default, allowed range and meaning."),
    "propagate": LazyCommand("proxops.cli_propagate", "propagate", "command",
                             "Propagate the uncontrolled chaser relative to the target and show what each force "
                             "model changes."),
    "reproduce": LazyCommand("proxops.cli_reproduce", "reproduce", "command",
                             "Run the commands behind every paper claim and print claim | paper | ours | verdict, "
                             "our own goals\n(wall times, Monte Carlo success rates) in a separate table, and the "
                             "*-ekf navigation table (with all).\nCampaigns are cached under OUT/cache and reused by "
                             "the next run."),
    "export": LazyCommand("proxops.cli_export", "export", "command",
                          "Export a saved run as CCSDS OEM ephemerides (EME2000, UTC) and/or a MATLAB .mat file."),
    "data": LazyCommand("proxops.cli_export", "data", "command",
                        "What environment data is shipped (space weather, Earth orientation): source, date, range."),
    "reach": LazyCommand("proxops.cli_reach", "reach_app", "group",
                         "Safe-start regions for the approach to a tumbling target: Table 2, hierarchy, backward LP, "
                         "Monte Carlo maps."),
    "cortex": LazyCommand("proxops.cli_cortex", "cortex_app", "group",
                          "CORTEX convex reference generation (fly-around + final approach, eclipse holds)."),
}


class RootGroup(LazyCommandGroup):
    lazy = COMMANDS


app = make_app(
    "proxops",
    "Spacecraft rendezvous and proximity operations: guidance, MPC, closed-loop simulation, Monte Carlo.",
    cls=RootGroup,
    epilog=EXIT_CODES_HELP,
)


def _version(value: bool):
    if value:
        typer.echo(f"proxops {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version.")] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Show tracebacks for errors.")] = False,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="More lines on stderr: every stage with its detail.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Only errors on stderr: no stage lines, no progress bars.")] = False,
):
    STATE["debug"] = debug
    configure_logging(verbose=verbose, quiet=quiet)


def run_app() -> int:
    """Run the command line on ``sys.argv`` and return the exit code (one line per error, see
    :func:`proxops.cli_common.guarded`); the console script :func:`proxops.exec.entry.main` calls it."""
    return guarded(lambda: app(standalone_mode=False))
