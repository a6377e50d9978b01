"""Benchmark: the hybrid system end to end (hybrid-mpc-capture.md §VII, issue 16 items 6-8).

Prints
1. the wall time of the whole ``hybrid-capture`` run (goal < 20 s), split into the
   controller steps (sum of the per-step times) and the rest (plant: RK4 + contact guard +
   jumps; engine), the median / p95 / max controller step, and the run's outcome;
2. the plant alone: the same 800 s of free flight from eq. 78 with zero input (contacts
   located) per simulated second;
3. with ``--mc``: the 50-run ``hybrid-capture-mc`` campaign on 2 workers (wall time and the
   outcome table).

The machine is shared: the load average is printed with the times.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_hybrid_system.py [--mc] [--runs 50] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # as the CLI does (proxops/cli.py):
    os.environ.setdefault(_var, "1")  # a threaded BLAS on the shared 2 cores makes each MPC step ~15x slower

import numpy as np  # noqa: E402


def whole_run() -> dict:
    from proxops.analysis.runs import execute
    from proxops.scenarios.loader import load_scenario

    loaded = load_scenario("hybrid-capture")
    execute(load_scenario("hybrid-capture", ["sim.duration_s=5"]))  # JIT / solver set-up outside the timing
    t0 = time.perf_counter()
    summary, results = execute(loaded)
    wall = time.perf_counter() - t0
    res = next(iter(results.values()))
    ctrl = float(np.sum(res.solve_time_s))
    print(f"hybrid-capture: {summary['sim_time_s']:.0f} s simulated in {wall:.2f} s wall (goal < 20 s); "
          f"controller steps {ctrl:.2f} s, plant + engine {wall - ctrl:.2f} s; load {os.getloadavg()[0]:.1f}")
    st = summary["solve_time_ms"]
    print(f"  controller step: median {st['median']:.2f} ms, p95 {st['p95']:.2f} ms, max {st['max']:.2f} ms "
          f"over {summary['steps']} steps")
    print(f"  outcome: {summary['status']}; {summary['sequence']}")
    return summary


def plant_only(duration_s: float = 800.0) -> None:
    from proxops.dynamics.two_rigid_bodies import HybridInitialState, HybridParams, truth_state_from_initial
    from proxops.propagation.hybrid_plant import HybridCapturePlant

    params = HybridParams()
    plant = HybridCapturePlant(params, truth_state_from_initial(params, HybridInitialState()))
    plant.propagate_events(0.0, plant.initial_state(), np.zeros(6), 1.0)  # JIT
    y, n_events = plant.initial_state(), 0
    t0 = time.perf_counter()
    for k in range(int(duration_s)):
        y, ev = plant.propagate_events(float(k), y, np.zeros(6), 1.0)
        n_events += len(ev)
    wall = time.perf_counter() - t0
    print(f"plant alone (eq. 78, no control): {duration_s:.0f} s in {wall:.3f} s wall "
          f"({wall / duration_s * 1e3:.3f} ms per simulated s), {n_events} events; load {os.getloadavg()[0]:.1f}")


def campaign(runs: int, workers: int) -> None:
    from proxops.analysis.campaign import run_campaign
    from proxops.systems.hybrid import outcome_table

    t0 = time.perf_counter()
    res = run_campaign("hybrid-capture-mc", n_runs=runs, workers=workers)
    wall = time.perf_counter() - t0
    print(f"hybrid-capture-mc: {runs} runs on {workers} workers in {wall:.1f} s wall "
          f"({wall / runs:.2f} s per run); load {os.getloadavg()[0]:.1f}")
    print(outcome_table(res.table))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mc", action="store_true", help="also run the Monte Carlo campaign")
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    plant_only()
    whole_run()
    if args.mc:
        campaign(args.runs, args.workers)


if __name__ == "__main__":
    main()
