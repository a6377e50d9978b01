"""Benchmark of the CORTEX tracking loop (cortex-convex-guidance.md §5.1.2, issue 15).

1. CP_g solve time (Clarabel, one guidance interval of 15 impulses; with and without the cone and
   plume rows): median / p95 / max over states taken from a nominal run, by in-place ``update`` and
   by a full rebuild, next to the paper's 38.43 +- 12.8 ms (goal: median < 1 ms).
2. Wall time of one nominal run with the high-fidelity truth (``proxops run cortex-nominal``, in this
   process after a warm-up run that pays numba compilation; goal < 10 s).
3. The thruster chain on the nominal run: delta-v and propellant against the impulsive actuator.
4. Wall time of the 100-run high-error campaign on 2 workers (``proxops mc cortex-high-mc --runs 100
   --workers 2``, process start included; goal < 5 min). ``--no-campaign`` skips it.

Run: ``.venv/bin/python benchmarks/bench_cortex_tracking.py [--runs 100] [--no-campaign]``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from proxops.scenarios.loader import load_scenario  # noqa: E402
from proxops.systems.cortex_loop import PAPER_CPG_SOLVE_MS, build_setup, run_closed_loop  # noqa: E402

GOAL_MEDIAN_MS = 1.0
GOAL_RUN_S = 10.0
GOAL_CAMPAIGN_S = 300.0


def _stats(ms):
    ms = np.asarray(ms)
    return f"median {np.median(ms):.3f} ms, p95 {np.percentile(ms, 95):.3f} ms, max {ms.max():.3f} ms (n = {ms.size})"


def cpg_times():
    from proxops.control.cortex_tracking import TrackingSOCP
    from proxops.sim.engine import simulate

    sc = load_scenario("cortex-nominal", ["truth.model=cw"]).scenario
    setup, ctrl, plan = build_setup(sc)
    res = simulate(setup)
    states = res.x_est[:: ctrl.n_sub]
    targets = [ctrl.timeline0.state(t + 30.0) for t in res.t[:: ctrl.n_sub]]
    for label, coned in (("fly-around (no cone)", False), ("approach (cone + plume rows)", True)):
        prob = TrackingSOCP(ctrl.n, 15, 2.0, ctrl.a_max, 10.0, cone=ctrl.cone if coned else None, plume=coned)
        if coned:
            prob.set_plume(np.tile([0.0, 0.0, -1.0], (15, 1)))
        upd, reb = [], []
        for rep in range(5):
            for x, xt in zip(states, targets):
                t0 = time.perf_counter()
                prob.solve(x, xt)
                upd.append((time.perf_counter() - t0) * 1e3)
        for x, xt in zip(states, targets):
            t0 = time.perf_counter()
            prob.solve(x, xt, rebuild=True)
            reb.append((time.perf_counter() - t0) * 1e3)
        print(f"CP_g {label}: update in place {_stats(upd)}")
        print(f"CP_g {label}: rebuild          {_stats(reb)}  (update is {np.median(reb) / np.median(upd):.2f}x faster)")
        print(f"   vs paper {PAPER_CPG_SOLVE_MS[0]} +- {PAPER_CPG_SOLVE_MS[1]} ms: {PAPER_CPG_SOLVE_MS[0] / np.median(upd):.0f}x; "
              f"goal median < {GOAL_MEDIAN_MS} ms: {'met' if np.median(upd) < GOAL_MEDIAN_MS else 'NOT met'}")


def nominal_run():
    sc = load_scenario("cortex-nominal").scenario
    run_closed_loop(sc)  # warm-up: numba compilation of the truth kernels
    t0 = time.perf_counter()
    summary, _ = run_closed_loop(sc)
    wall = time.perf_counter() - t0
    print(f"nominal run, full truth (EGM96 20x20, NRLMSISE-00, Sun/Moon): {wall:.2f} s wall "
          f"(goal < {GOAL_RUN_S} s: {'met' if wall < GOAL_RUN_S else 'NOT met'}); status {summary['status']}, "
          f"terminal {summary['terminal_position_error_m'] * 1e3:.3f} mm / {summary['terminal_velocity_error_mps'] * 1e3:.3f} mm/s, "
          f"CP_g median {summary['solve_time_ms']['median']:.3f} ms")


def thruster_chain():
    """cortex-nominal with the thruster chain ([actuator] model = thrusters) against the impulsive slot."""
    out = {}
    for model in ("impulsive", "thrusters"):
        sc = load_scenario("cortex-nominal", [f"actuator.model={model}"]).scenario
        t0 = time.perf_counter()
        out[model], _ = run_closed_loop(sc)
        out[model]["wall"] = time.perf_counter() - t0
    i, t = out["impulsive"], out["thrusters"]
    print(f"thruster chain (eq. 32 + Algorithm 4 LP + eq. 33 PWM, six 1.2 N axis thrusters, Isp 220 s): {t['status']}, "
          f"dv {t['total_dv_mps']:.4f} m/s vs impulsive {i['total_dv_mps']:.4f} m/s; propellant {t['propellant_kg'] * 1e3:.1f} g "
          f"vs rocket equation on the impulsive dv {i['propellant_kg'] * 1e3:.1f} g ({t['propellant_kg'] / i['propellant_kg']:.2f}x, "
          f"axis thrusters burn the L1 norm); terminal {t['terminal_position_error_m'] * 1e3:.3f} mm; "
          f"wall {t['wall']:.2f} s vs {i['wall']:.2f} s; LP {t['allocation_lp_ms_mean']:.2f} ms per allocation "
          f"({t['allocations']} allocations)")


def campaign(runs: int):
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "proxops.cli", "mc", "cortex-high-mc", "--runs", str(runs),
                               "--workers", "2", "--out", f"{d}/mc", "--json"], capture_output=True, text=True)
        wall = time.perf_counter() - t0
    print(f"{runs}-run high-error campaign on 2 workers: {wall:.1f} s wall (goal < {GOAL_CAMPAIGN_S:.0f} s: "
          f"{'met' if wall < GOAL_CAMPAIGN_S else 'NOT met'}; exit {proc.returncode})")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--no-campaign", action="store_true")
    args = ap.parse_args()
    cpg_times()
    nominal_run()
    thruster_chain()
    if not args.no_campaign:
        campaign(args.runs)


if __name__ == "__main__":
    main()
