"""The ``proxops`` command line: a thin layer over scenarios, the simulator and analysis.

Every command prints a readable summary, or with ``--json`` exactly one JSON object
on stdout. Input errors print one line and exit with code 2 (traceback with --debug).
"""

from __future__ import annotations

import os

# The MPCs solve many small dense problems: BLAS threads only compete for the cores
# (measured: closed-loop DAQP update+solve 0.4 ms -> 0.24 ms with one thread).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import json  # noqa: E402
import sys
from pathlib import Path
from typing import Annotated, Optional

import typer

from proxops import __version__
from proxops.cli_common import EXIT_CODES_HELP, STATE, ProxopsGroup, configure_logging, emit, friendly_errors

app = typer.Typer(
    name="proxops",
    cls=ProxopsGroup,
    help="Spacecraft rendezvous and proximity operations: guidance, MPC, closed-loop simulation, Monte Carlo.",
    epilog=EXIT_CODES_HELP,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # help text is plain text: [dispersions] is a word, not a style tag
)


def _version(value: bool):
    if value:
        typer.echo(f"proxops {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[Optional[bool], typer.Option("--version", callback=_version, is_eager=True, help="Print the version.")] = None,
    debug: Annotated[bool, typer.Option("--debug", help="Show tracebacks for errors.")] = False,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="More lines on stderr: every stage with its detail.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Only errors on stderr: no stage lines, no progress bars.")] = False,
):
    STATE["debug"] = debug
    configure_logging(verbose=verbose, quiet=quiet)


# --------------------------------------------------------------------------- scenarios
@app.command()
@friendly_errors
def scenarios(as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False):
    """List the built-in scenarios."""
    from proxops.scenarios.loader import list_builtin

    items = list_builtin()
    rows = [{"name": i["name"], "description": i["description"], "system": i["system"]} for i in items]
    width = max((len(r["name"]) for r in rows), default=4)
    text = "\n".join(f"{r['name']:<{width}}  {r['description']}" for r in rows)
    if as_json:
        sys.stdout.write(json.dumps(rows) + "\n")
    else:
        typer.echo(text)


@app.command()
@friendly_errors
def validate(
    scenario: Annotated[str, typer.Argument(help="Scenario file or built-in name.")],
    set_: Annotated[list[str], typer.Option("--set", help="Override a key: --set sim.duration_s=600.")] = [],
    as_json: Annotated[bool, typer.Option("--json")] = False,
):
    """Validate a scenario file (exit 0 if valid, 2 with a one-line error otherwise)."""
    from proxops.runner import check_scenario
    from proxops.scenarios.loader import load_scenario

    loaded = load_scenario(scenario, set_)
    check_scenario(loaded)
    sc = loaded.scenario
    emit({"valid": True, "name": sc.name, "system": sc.system, "source": loaded.source}, as_json,
         f"{loaded.source}: valid ({sc.system} scenario '{sc.name}')")


# --------------------------------------------------------------------------- run
@app.command()
@friendly_errors
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
    from proxops.cli_common import EXIT_RUN_FAILED, check_out_dir
    from proxops.errors import input_error
    from proxops.runner import run_scenario
    from proxops.scenarios.loader import load_scenario

    if seed is not None and not 0 <= seed < 2**63:
        raise input_error("--seed", seed, "allowed a whole number from 0 to 2^63 - 1")
    if report and out is None:
        raise input_error("--report", True, "needs --out DIR (the report is DIR/report.html beside the figures)")
    if out is not None:
        check_out_dir(out)
    from proxops.cli_export import check_out_file

    check_out_file(oem, "--oem")
    check_out_file(mat, "--mat")
    loaded = load_scenario(scenario, set_)
    summary = run_scenario(loaded, seed=seed, out=out, figures=figures,
                           progress=not as_json and not STATE["quiet"], oem=oem, mat=mat)
    if report:
        from proxops.report.run import write_run_report

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
    from proxops.analysis.formatting import format_quantity

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


# --------------------------------------------------------------------------- demo
@app.command()
@friendly_errors
def demo(out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out")):
    """Run the built-in demonstration scenarios and write a report under OUT."""
    from proxops.cli_common import check_out_dir
    from proxops.runner import run_demo

    report = run_demo(check_out_dir(out))
    typer.echo(f"demo report written to {report}")


def _mount_optional() -> None:
    """Mount the subcommands that systems provide (kept in their own modules)."""
    import importlib

    for module, attr, name, kind in (
        ("proxops.cli_srf", "hop_times", "hop-times", "command"),
        ("proxops.cli_reach", "reach_app", "reach", "group"),
        ("proxops.cli_cortex", "cortex_app", "cortex", "group"),
        ("proxops.cli_campaign", "mc", "mc", "command"),
        ("proxops.cli_campaign", "report", "report", "command"),
        ("proxops.cli_keys", "keys", "keys", "command"),
        ("proxops.cli_propagate", "propagate", "propagate", "command"),
        ("proxops.cli_reproduce", "reproduce", "reproduce", "command"),
        ("proxops.cli_export", "export", "export", "command"),
        ("proxops.cli_export", "data", "data", "command"),
    ):
        try:
            mod = importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if exc.name == module:
                continue
            raise
        obj = getattr(mod, attr)
        if kind == "group":
            app.add_typer(obj, name=name)
        else:
            app.command(name=name)(friendly_errors(obj))


_mount_optional()
