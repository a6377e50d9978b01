"""``proxops cortex``: CORTEX reference generation (Wijayatunga et al. §3.1, §5.1).

Mounted by :mod:`proxops.cli` as a group::

    proxops cortex reference --axis -0.7071 -0.7071 0 [--json] [--out DIR]
    proxops cortex references --n 100 --workers 2 --out DIR [--json] [--resume]

``reference`` JSON: the plan summary (tau1_s, tau2_s, hold1_s, hold2_s, dv1_mps, dv2_mps,
dv_total_mps, tof_s, total_time_s, iterations, status, plan_wall_time_s, check_*).
``references`` plans the Fibonacci axes as a grid campaign (Parquet rows under DIR/runs)
and prints median/IQR of delta-v, TOF and compute time next to §5.1.1.
"""

from __future__ import annotations

import importlib
import json
import math
import threading
import time
from pathlib import Path
from typing import Annotated, Optional

import typer

from proxops.cli_common import check_out_dir, emit, friendly_errors, json_default
from proxops.errors import input_error
from proxops.exec.backends import MAX_WORKERS, shutdown_pools
from proxops.exec.prestart import prestart
from proxops.scenarios.loader import load_scenario
from proxops.systems.cortex import (PAPER_5_1_1, campaign_statistics, plan_scenario, references_scenario,
                                    statistics_table)

FIGURES_MODULE = "proxops.plotting.cortex"  # Figs. 11-12 of `references` (matplotlib)

cortex_app = typer.Typer(help="CORTEX convex reference generation (fly-around + final approach, eclipse holds).",
                         no_args_is_help=True, rich_markup_mode=None)


def _load(scenario: str, overrides: list[str]):
    """A cortex scenario, or a one-line error naming --scenario (another system has no [geometry])."""
    loaded = load_scenario(scenario, overrides)
    _require_cortex(scenario, loaded.scenario.system)
    return loaded


def _require_cortex(scenario: str, system) -> None:
    if system != "cortex":
        raise input_error("--scenario", scenario, f"is a {system!r} scenario; give a cortex one (system = "
                          "\"cortex\", e.g. cortex-reference)")


@cortex_app.command("reference")
@friendly_errors
def reference(
    axis: Annotated[Optional[tuple[float, float, float]], typer.Option("--axis", help="Docking axis X Y Z in Hill (x radial, y along-track, z normal); normalised. Default: the scenario's.")] = None,
    scenario: Annotated[str, typer.Option("--scenario", help="Scenario file or built-in name.")] = "cortex-reference",
    set_: Annotated[list[str], typer.Option("--set", help="Override a scenario key, e.g. --set planner.dt_cp2_s=5.")] = [],
    out: Annotated[Optional[Path], typer.Option("--out", help="Write trajectory.parquet, summary.json and a 3-D figure here.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout.")] = False,
):
    """Plan one reference (outer search, CP1, CP2, holds) and print its summary."""
    if out is not None:
        check_out_dir(out)

    loaded = _load(scenario, list(set_))
    sc = loaded.scenario
    plan = plan_scenario(sc, axis=list(axis) if axis is not None else None)
    summary = plan.summary()
    if out is not None:
        summary["files"] = [str(p) for p in write_plan(sc, plan, Path(out), summary)]
    emit(summary, as_json, format_plan(summary))  # an infeasible plan is a status (exit 0), not an error


def write_plan(sc, plan, out: Path, summary: dict) -> list[Path]:
    """trajectory.parquet (t, phase, x..vz, dvx..dvz), summary.json, reference_3d.png."""
    import pandas as pd

    from proxops.plotting.cortex import plan_figure  # matplotlib: only with --out

    out.mkdir(parents=True, exist_ok=True)
    traj = plan.trajectory()
    frame = pd.DataFrame({"t_s": traj["t"], "phase": traj["phase"]})
    for i, name in enumerate(("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")):
        frame[name] = traj["x"][:, i] if len(traj["t"]) else []
    for i, name in enumerate(("dvx_mps", "dvy_mps", "dvz_mps")):
        frame[name] = traj["dv"][:, i] if len(traj["t"]) else []
    paths = [out / "trajectory.parquet", out / "summary.json"]
    frame.to_parquet(paths[0], index=False)
    paths[1].write_text(json.dumps(summary, indent=2, default=json_default))
    if len(traj["t"]):
        paths.append(plan_figure(sc, plan, out / "reference_3d.png"))
    return paths


def format_plan(s: dict) -> str:
    s = {k: (math.nan if v is None else v) for k, v in s.items()}
    lines = [
        f"status        {s['status']}" + (f" ({s['reason']})" if s.get("reason") else ""),
        f"axis (Hill)   [{s['axis_x']:.4f}, {s['axis_y']:.4f}, {s['axis_z']:.4f}]",
        f"tau1, tau2    {s['tau1_s']:.1f} s, {s['tau2_s']:.1f} s",
        f"holds         tau_h1 {s['hold1_s']:.1f} s, tau_h2 {s['hold2_s']:.1f} s",
        f"delta-v       CP1 {s['dv1_mps']:.4f} + CP2 {s['dv2_mps']:.4f} = {s['dv_total_mps']:.4f} m/s",
        f"TOF           {s['tof_s']:.1f} s (tau1 + tau2; {s['total_time_s']:.1f} s with holds)",
        f"iterations    CP1 durations tried {s['evaluations_cp1']}, KOS solves {s['kos_iterations']}; "
        f"CP2 durations tried {s['evaluations_cp2']}, SCP solves {s['scp_iterations']}",
        f"compute time  {s['plan_wall_time_s']:.3f} s (median SOCP solve: CP1 {s['cp1_solve_time_median_s'] * 1e3:.2f} ms, "
        f"CP2 {s['cp2_solve_time_median_s'] * 1e3:.2f} ms)",
    ]
    if "check_passed" in s:
        lines.append(
            f"checks        {'passed' if s['check_passed'] else 'FAILED'}: dynamics {s['check_dynamics_residual']:.1e}, "
            f"max |dv|/(a_bar dt) {s['check_impulse_ratio_max']:.6f}, KOS node margin {s['check_kos_node_margin_m']:.3f} m, "
            f"worst arc penetration {s['check_kos_arc_penetration_m']:.3f} m (true KOS {s['check_kos_arc_true_penetration_m']:.3f} m), "
            f"cone margin {s['check_cone_margin_m']:.1e} m, plume margin {s['check_plume_margin_deg']:.1e} deg")
    if s.get("files"):
        lines.append(f"written       {', '.join(s['files'])}")
    return "\n".join(lines)


def _import_quietly(module: str) -> None:
    """Import ``module`` now (a thread's head start); a failure is left to the import that needs it."""
    try:
        importlib.import_module(module)
    except Exception:  # noqa: BLE001 - reported where the figures are drawn
        pass


@cortex_app.command("references")
@friendly_errors
def references(
    n: Annotated[int, typer.Option("--n", help="Number of Fibonacci-sphere docking axes.")] = 100,
    workers: Annotated[Optional[int], typer.Option("--workers", help="Local worker processes (default: usable CPUs; 1 = in this process).")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="Campaign folder (resumable; Parquet rows, figures).")] = None,
    scenario: Annotated[str, typer.Option("--scenario", help="Scenario file or built-in name.")] = "cortex-reference",
    set_: Annotated[list[str], typer.Option("--set", help="Override a scenario key.")] = [],
    resume: Annotated[bool, typer.Option("--resume", help="Complete an interrupted campaign in --out.")] = False,
    figures: Annotated[bool, typer.Option("--figures/--no-figures", help="Draw Figs. 11-12 into OUT.")] = True,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout.")] = False,
):
    """Plan the references of N Fibonacci-sphere axes as a campaign; statistics next to §5.1.1."""
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise input_error("--workers", workers, f"must be a whole number from 1 to {MAX_WORKERS}")
    if out is not None:
        check_out_dir(out, campaign=True)
    data = references_scenario(scenario, n)
    # the pool starts now (if proxops.exec.entry has not started it): its fork server plans once (the workers'
    prestart(scenario, n, workers, list(set_))  # warm-up) while this process imports the campaign engine
    # the campaign engine (pandas, pyarrow): this command's, not `cortex reference`'s
    from proxops.analysis.campaign import _campaign_system, load_campaign, run_campaign  # noqa: PLC2701
    draw = out is not None and figures
    if draw:  # matplotlib (0.45-0.6 s) imported while the workers plan, not after them
        threading.Thread(target=_import_quietly, args=(FIGURES_MODULE,), daemon=True).start()
    t0 = time.perf_counter()
    # Fig. 11 is drawn from the plans' node positions in the rows (metric.trace.*): no series saved
    res = run_campaign(data, workers=workers, out=out, resume=resume, progress=not as_json, overrides=list(set_))
    wall = time.perf_counter() - t0
    st = campaign_statistics(res.table)
    st["campaign_wall_s"] = wall
    st["workers"] = workers
    st["paper"] = PAPER_5_1_1
    files = []
    if draw:
        from proxops.plotting.cortex import references_figures  # (waits for the import above to finish)

        shutdown_pools()  # the workers are done: no pool thread left when a figure is drawn in a forked child

        camp = load_campaign(out)
        files = [str(p) for p in references_figures(camp, _campaign_system(camp.manifest).scenario, PAPER_5_1_1, Path(out))]
        st["files"] = files
    if out is not None:
        st["out"] = str(out)
    text = statistics_table(st) + f"\n\n{st['n_ok']}/{st['n_plans']} plans ok; campaign wall time {wall:.2f} s on {workers} workers"
    if files:
        text += "\nfigures: " + ", ".join(files)
    emit(st, as_json, text)
