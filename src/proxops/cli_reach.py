"""``proxops reach``: safe-start certification of the tumbling-target approach
(Iskender 2026 §8-11). Mounted by proxops.cli as a command group.

    proxops reach table [--grid 300] [--json] [--out DIR]       Table 2 + hierarchy + backward kernel (+ Table 4 times)
    proxops reach map --omega-deg-s W --a-max-mps2 A --out DIR [--mc DIR]  one combination's maps (overlay with a campaign)
    proxops reach mc [--workers K] [--scheduler ADDR] --out DIR  the §9 Monte Carlo campaign, Figs. 2-3, certification check
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Annotated, Optional

import numpy as np
import typer

from proxops.cli_common import (check_out_dir, make_app, emit as _emit, friendly_errors as _friendly,
                                json_default as _default)
from proxops.errors import ProxopsInputError
from proxops.exec.backends import MAX_WORKERS
from proxops.analysis import feasibility_maps as F
from proxops.analysis import reach as R
from proxops.exec.prestart import REACH_MAX_GRID as MAX_GRID
from proxops.exec.prestart import REACH_MAX_IC_AXIS as MAX_IC_AXIS
from proxops.exec.prestart import REACH_SCENARIO, prestart, reach_overrides
from proxops.plotting import reach as P

reach_app = make_app(
    "reach",
    "Safe-start regions for the approach to a tumbling target: Table 2, hierarchy, backward LP, Monte Carlo maps.",
)


def _check_grid(grid: int, y_max_m: float = 320.0) -> None:
    if not 3 <= grid <= MAX_GRID:
        raise ProxopsInputError(f"--grid = {grid}: give a whole number of points from 3 to {MAX_GRID} "
                                f"(memory grows as grid^2; the paper uses 300)")
    if not (np.isfinite(y_max_m) and y_max_m > 0):
        raise ProxopsInputError(f"--y-max-m = {y_max_m} m: give a positive, finite extent")


def _check_rates(omegas, amaxs) -> None:
    if not all(np.isfinite(w) and w > 0 for w in omegas):
        raise ProxopsInputError(f"--omega-deg-s = {list(omegas)} deg/s: tumble rates must be finite and > 0")
    if not all(np.isfinite(a) and a > 0 for a in amaxs):
        raise ProxopsInputError(f"--a-max-mps2 = {list(amaxs)} m/s^2: thrust authorities must be finite and > 0")


def _fmt(v, width=7, digits=1) -> str:
    return f"{'-':>{width}}" if v is None or (isinstance(v, float) and np.isnan(v)) else f"{v:>{width}.{digits}f}"


# --------------------------------------------------------------------------- table
@reach_app.command("table")
@_friendly
def table(
    grid: Annotated[int, typer.Option("--grid", help="Grid points per axis (paper: 300).")] = 300,
    y_max_m: Annotated[float, typer.Option("--y-max-m", help="Grid extent along y_B (m); 320 reproduces Table 2.")] = 320.0,
    backward: Annotated[bool, typer.Option("--backward/--no-backward", help="Compute the backward LP kernel.")] = True,
    backward_start: Annotated[str, typer.Option("--backward-start", help="Initial velocity of the backward LP: inertial (as eq. 13) or body (at rest in F_B, as §9).")] = "inertial",
    out: Annotated[Optional[Path], typer.Option("--out", help="Write figures (Fig. 1, scaling, double integrator) and table.json here.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
):
    """Table 2 (nominal), stochastic/robust regions, pointwise hierarchy, backward kernel, Table 4 timings."""
    _check_grid(grid, y_max_m)
    if backward_start not in ("inertial", "body"):
        raise ProxopsInputError(f"--backward-start = {backward_start!r}: allowed inertial, body")
    if out is not None:
        check_out_dir(out)
    results, timings, g = R.reach_table(n_points=grid, y_max_m=y_max_m, backward=backward,
                                        initial_velocity=backward_start)
    combos = [r.as_json() for r in results]
    payload = {
        "grid": {"n_points": grid, "y_max_m": y_max_m, "inside_points": int(g.inside.sum())},
        "combinations": combos,
        "hierarchy_violations_total": int(sum(r.hierarchy_violations for r in results)),
        "max_abs_diff_nominal_vs_paper_pp": float(np.nanmax([abs(c["nominal_pct"] - c["paper_nominal_pct"]) for c in combos])),
        "backward_start": backward_start,
        "timings_s": {k: round(v, 4) for k, v in timings.items()},
        "paper_timings_s": R.PAPER_TIMES_S,
        "speedup_vs_paper": R.PAPER_TIMES_S["total"] / timings["total"] if timings["total"] > 0 else None,
        "assumptions": R.DEFAULTS_NOTE,
    }
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        files = [P.hierarchy_figure(results, g, out / "fig1_hierarchy.png"), P.scaling_figure(results, out / "scaling.png")]
        secs = R.double_integrator_sections()
        polys = {k: s.polygon(64, refine_tol=1e-3) for k, s in secs.items()}
        files.append(P.double_integrator_figure(polys, out / "double_integrator.png", R.DoubleIntegratorCase()))
        (out / "table.json").write_text(json.dumps(payload, indent=2, default=_default))
        payload["files"] = [str(f) for f in files] + [str(out / "table.json")]
    lines = [
        f"Safe fraction of the LOS corridor (%), grid {grid}x{grid}, y_B <= {y_max_m:g} m "
        f"(paper values in brackets; backward LP start: {backward_start})",
        f"{'w deg/s':>7} {'a m/s2':>7} {'nominal':>15} {'stoch':>7} {'robust':>15} {'backward':>16} {'viol':>5}",
    ]
    for c in combos:
        pb = c["paper_backward_pct"]
        pr = c["paper_robust_pct"]
        lines.append(
            f"{c['omega_deg_s']:>7g} {c['a_max_mps2']:>7.2f} {c['nominal_pct']:>7.1f} [{c['paper_nominal_pct']:>5.1f}]"
            f" {c['stochastic_pct']:>7.1f} {c['robust_pct']:>7.1f} [{_fmt(pr, 5)}]"
            f" {_fmt(c['backward_pct'], 8)} [{_fmt(pb, 5)}] {c['hierarchy_violations']:>5d}"
        )
    t = payload["timings_s"]
    lines.append(
        f"Table 4 (s): forward {t.get('forward', 0):.3f} [2.4], stochastic {t.get('stochastic', 0):.3f} [2.4], "
        f"robust {t.get('robust', 0):.3f} [2.2], backward LP {t.get('backward', 0):.3f} [46.0], "
        f"total {t['total']:.3f} [53]"
    )
    lines.append(f"pointwise hierarchy violations: {payload['hierarchy_violations_total']}; "
                 f"max |nominal - paper| = {payload['max_abs_diff_nominal_vs_paper_pp']:.2f} pp")
    _emit(payload, as_json, "\n".join(lines))


# --------------------------------------------------------------------------- map
@reach_app.command("map")
@_friendly
def map_(
    omega_deg: Annotated[float, typer.Option("--omega-deg-s", "--omega-deg", help="Tumble rate w_t, deg/s.")],
    amax: Annotated[float, typer.Option("--a-max-mps2", "--amax", help="Thrust authority a_max, m/s^2.")],
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    grid: Annotated[int, typer.Option("--grid", help="Grid points per axis.")] = 300,
    y_max_m: Annotated[float, typer.Option("--y-max-m", help="Grid extent along y_B (m).")] = 320.0,
    mc: Annotated[Optional[Path], typer.Option("--mc", help="Campaign folder of `proxops reach mc`: overlay its map.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
):
    """Nominal, stochastic, robust and backward maps of one (w_t, a_max) as a figure and JSON."""
    _check_grid(grid, y_max_m)
    _check_rates([omega_deg], [amax])
    check_out_dir(out)
    g = R.body_grid(n_points=grid, y_max_m=y_max_m)
    res = R.analyse_combo(g, omega_deg, amax)
    payload = res.as_json()
    fmap = None
    if mc is not None:
        fmap = F.feasibility_map(F.read_outcomes(mc), g, omega_deg, amax)
        payload["monte_carlo"] = F.certify_combination(fmap, g, res)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"reach_w{omega_deg:g}_a{amax:g}"
    fig = P.combo_map_figure(res, g, out / f"{stem}.png", fmap)
    np.savez_compressed(out / f"{stem}_masks.npz", x_m=g.x_m, y_m=g.y_m, inside=g.inside, nominal=res.nominal,
                        stochastic=res.stochastic, robust=res.robust,
                        backward=res.backward if res.backward is not None else np.zeros(0, bool),
                        mc=fmap.mask if fmap is not None else np.zeros(0, bool))
    (out / f"{stem}.json").write_text(json.dumps(payload, indent=2, default=_default))
    payload["files"] = [str(fig), str(out / f"{stem}_masks.npz"), str(out / f"{stem}.json")]
    text = (f"w_t = {omega_deg:g} deg/s, a_max = {amax:g} m/s^2, r_sync = {res.r_sync_m:.1f} m: nominal "
            f"{res.pct['nominal']:.1f} %, stochastic {res.pct['stochastic']:.1f} %, robust {res.pct['robust']:.1f} %, "
            f"backward {res.pct.get('backward', float('nan')):.1f} %, hierarchy violations {res.hierarchy_violations}")
    if fmap is not None:
        m = payload["monte_carlo"]
        text += (f"\nMC: {m['mc_pct_ics']:.1f}% of ICs feasible, {m['mc_pct_grid']:.1f}% of the grid; nominal-certified "
                 f"but MC-infeasible: {m['nominal_grid_points_mc_infeasible']}/{m['nominal_grid_points']} grid points, "
                 f"{m['nominal_ics_mc_infeasible']}/{m['nominal_ics']} ICs")
    text += f"\nwrote {fig}"
    _emit(payload, as_json, text)


# --------------------------------------------------------------------------- mc
def _prestart_workers(workers: Optional[int], n_runs: int, duration_s: float) -> None:
    """Start the local pool now, as ``proxops mc`` does (:func:`proxops.exec.prestart.prestart`; no
    effect when :func:`proxops.exec.entry.main` started it before this module's imports): the fork
    server builds a §9 closed loop once (los-tumble in its Monte Carlo configuration; best effort),
    so each forked worker starts with the los modules imported and its kernels loaded."""
    prestart(REACH_SCENARIO, n_runs, workers, reach_overrides(duration_s))


@reach_app.command("mc")
@_friendly
def mc(
    out: Annotated[Path, typer.Option("--out", help="Campaign folder (Parquet rows, manifest, figures).")],
    workers: Annotated[Optional[int], typer.Option("--workers", help="Local worker processes (default: usable CPUs).")] = None,
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", help="Dask scheduler tcp://HOST:PORT or scheduler file.")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Complete an interrupted campaign in OUT.")] = False,
    duration_s: Annotated[float, typer.Option("--duration-s", help="Simulated time per run (paper: 400 s).")] = 400.0,
    grid: Annotated[int, typer.Option("--grid", help="Analytical grid points per axis for the maps.")] = 300,
    n_y: Annotated[int, typer.Option("--n-y", help="IC rows in y_B (paper 15).")] = 15,
    n_x: Annotated[int, typer.Option("--n-x", help="ICs per row in x_B (paper 13).")] = 13,
    omega_deg: Annotated[Optional[list[float]], typer.Option("--omega-deg-s", "--omega-deg", help="Tumble rates, deg/s; repeat. Default 1..5.")] = None,
    amax: Annotated[Optional[list[float]], typer.Option("--a-max-mps2", "--amax", help="Thrust authorities, m/s^2; repeat. Default 0.2 0.1 0.05 0.02.")] = None,
    progress: Annotated[bool, typer.Option("--progress/--no-progress", help="Progress bar on stderr.")] = True,
    viability_check: Annotated[bool, typer.Option("--viability-check", help="Also decide, by a 400-step LP, whether each certified-but-failed IC could be kept in the corridor by any controller.")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
):
    """§9 Monte Carlo feasibility sweep (20 x 195 closed-loop runs, J2 truth), maps and certification check."""
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise ProxopsInputError(f"--workers = {workers}: give a whole number from 1 to {MAX_WORKERS}")
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise ProxopsInputError(f"--duration-s = {duration_s}: must be a finite number > 0 s")
    _check_grid(grid)
    for name, n in (("--n-x", n_x), ("--n-y", n_y)):
        if not 1 <= n <= MAX_IC_AXIS:
            raise ProxopsInputError(f"{name} = {n}: give a whole number of initial conditions from 1 to {MAX_IC_AXIS}")
    _check_rates(omega_deg or (), amax or ())

    check_out_dir(out, campaign=True)
    if scheduler is None and not resume:
        n_combos = len(omega_deg or R.PAPER_OMEGAS_DEG_S) * len(amax or R.PAPER_A_MAX_MPS2)
        _prestart_workers(workers, n_combos * n_x * n_y, duration_s)
    omegas = tuple(omega_deg) if omega_deg else R.PAPER_OMEGAS_DEG_S
    amaxs = tuple(amax) if amax else R.PAPER_A_MAX_MPS2
    positions = F.mc_initial_positions(n_y=n_y, n_x=n_x)
    t0 = time.perf_counter()
    outcomes, wall, new_runs = F.run_mc(out, omegas, amaxs, positions, duration_s, workers, scheduler, resume,
                                        progress)
    # After the campaign, not overlapped with it: computed in a thread of this process while the pool
    # ran, this work (1.2 s of CPU) slowed the campaign about as much as it saved (measured).
    g = R.body_grid(n_points=grid)
    sweep = F.aggregate_sweep(outcomes, g, omegas, amaxs, viability=viability_check, duration_s=duration_s)
    rows, maps, results, totals = sweep.rows, sweep.maps, sweep.results, sweep.totals
    files = [P.mc_sweep_figure(outcomes, out / "fig2_mc_sweep.png")]
    key = (2.0, 0.10) if (2.0, 0.10) in maps else next(iter(maps))
    files.append(P.overlay_figure(results[key], maps[key], g, out / "fig3_overlay.png"))
    n_runs = len(outcomes)
    payload = {
        "runs": n_runs,
        "feasible": int(outcomes["feasible"].sum()),
        "errors": int(outcomes["error"].sum()),
        "new_runs": new_runs,
        "wall_time_s": wall,
        "elapsed_s": time.perf_counter() - t0,
        "runs_per_min": 60.0 * new_runs / wall if new_runs and wall > 0 else None,
        "combinations": rows,
        # the sweep's totals, named as before: nominal_certified_* (the rows say nominal_*)
        **{k.replace("nominal_", "nominal_certified_", 1) if not k.startswith("frac_") else k: v
           for k, v in totals.items() if k.startswith(("nominal_", "frac_"))},
        "paper_wall_time_s": [7200.0, 14400.0],
        "files": [str(f) for f in files],
    }
    (out / "mc_summary.json").write_text(json.dumps(payload, indent=2, default=_default))
    speed = (f"{new_runs} new in {wall:.1f} s ({payload['runs_per_min']:.0f} runs/min; paper 2-4 h on 8 cores)"
             if payload["runs_per_min"] else "no new runs (resumed a finished campaign)")
    lines = [f"{n_runs} runs ({payload['feasible']} feasible, {payload['errors']} errors); {speed}",
             f"{'w deg/s':>7} {'a m/s2':>7} {'MC IC %':>8} {'MC grid %':>9} {'nominal %':>9} {'cert. but MC-infeasible (grid / ICs)':>38}"]
    for r in rows:
        lines.append(f"{r['omega_deg_s']:>7g} {r['a_max_mps2']:>7.2f} {r['mc_pct_ics']:>8.1f} {r['mc_pct_grid']:>9.1f} "
                     f"{r['nominal_pct']:>9.1f} {r['nominal_grid_points_mc_infeasible']:>12d}/{r['nominal_grid_points']:<6d}"
                     f" {r['nominal_ics_mc_infeasible']:>6d}/{r['nominal_ics']:<4d}")
    t = totals
    lines.append(f"nominal-certified grid points that MC finds infeasible: {t['nominal_grid_points_mc_infeasible']}/"
                 f"{t['nominal_grid_points']} ({100 * t['frac_nominal_grid_mc_infeasible']:.2f}%); ICs: "
                 f"{t['nominal_ics_mc_infeasible']}/{t['nominal_ics']} ({100 * t['frac_nominal_ics_mc_infeasible']:.2f}%)")
    lines.append(f"  inside the hull of the ICs (interpolated, not extrapolated): "
                 f"{t['nominal_grid_points_in_ic_hull_mc_infeasible']}/{t['nominal_grid_points_in_ic_hull']} "
                 f"({100 * t['frac_nominal_grid_in_ic_hull_mc_infeasible']:.2f}%)")
    if viability_check:
        not_viable, viable = t["certified_failed_ics_not_viable"], t["certified_failed_ics_viable"]
        mc_not_viable = t["mc_feasible_ics_not_viable"]
        payload.update(certified_failed_ics_not_viable=not_viable, certified_failed_ics_viable=viable,
                       mc_feasible_ics_not_viable=mc_not_viable)
        lines.append(f"  of the certified ICs that failed: {not_viable} cannot be kept in the corridor by any "
                     f"controller for {duration_s:g} s from rest in F_B (LP), {viable} could (the MPC failed); "
                     f"MC-feasible ICs the LP calls non-viable: {mc_not_viable}")
        (out / "mc_summary.json").write_text(json.dumps(payload, indent=2, default=_default))
    lines += [f"wrote {f}" for f in files]
    _emit(payload, as_json, "\n".join(lines))
