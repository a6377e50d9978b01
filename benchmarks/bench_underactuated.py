"""Benchmark: underactuated-docking NMPC (underactuated-docking-nmpc.md §5, issue 7).

Prints, for the general (eq. 9) and averaged-value (eq. 14) MPC, the median and p95
computation per 2-s step, steps and total time per docking, next to the paper's Python
numbers, plus the warm-solver comparison (fatrop vs IPOPT) that set the default.

    .venv/bin/python benchmarks/bench_underactuated.py [--quick] [--horizons]

Goals (issue 7): median < 5 ms per step for both variants; the whole underactuated-compare
run < 10 s. Paper: 0.58 s (averaged) and 9.34 s (general) per step, 971 s and 17 569 s in
total, 16x. The machine is shared: the 1-minute load average is printed with the numbers.

"solver" is the wall time inside the NLP solver calls alone (``info["solver_time_s"]``);
"rest" = step - solver is the controller's own work (shift, constraint check, value).
"""

from __future__ import annotations

import os
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


import numpy as np  # noqa: E402

from proxops.runner import execute  # noqa: E402
from proxops.scenarios.loader import load_scenario  # noqa: E402

PAPER = {
    "averaged": {"per_step_s": 0.58, "steps": 1676, "total_s": 971.0},
    "general": {"per_step_s": 9.34, "steps": 275, "total_s": 17569.0},
}


def _row(label: str, s: dict, wall: float) -> str:
    st = s["solve_time_ms"]
    return (f"  {label:<22} docked={str(s['docked']):<5} steps={s['steps']:>5}  step median {st['median']:7.2f} ms"
            f"  p95 {st['p95']:7.2f} ms  max {st['max']:8.1f} ms  iters {s['mean_iterations']:5.1f}"
            f"  controller {s['controller_wall_time_s']:6.2f} s  run wall {wall:6.2f} s")


def _split(result) -> str:
    """Median solver time and median rest (step - solver) per step, ms."""
    n = len(result.t) - 1
    step = result.solve_time_s[:n]
    solver = result.info.get("solver_time_s", np.full(n + 1, np.nan))[:n]
    return (f"    of which solver median {np.median(solver) * 1e3:6.2f} ms,"
            f" rest median {np.median(step - solver) * 1e3:5.2f} ms")


def bench_compare() -> dict:
    print("== underactuated-compare (Figs. 4-5 start, Table 2 limits) ==")
    loaded = load_scenario("underactuated-compare")
    t0, c0 = time.perf_counter(), time.process_time()
    summary, results = execute(loaded)
    total, cpu = time.perf_counter() - t0, time.process_time() - c0
    runs = summary["runs"]
    for label, s in runs.items():
        print(_row(f"{label} (H={s['horizon']})", s, s["wall_time_s"]))
        print(_split(results[label]))
    avg, gen = runs["averaged"], runs["general"]
    ratio = gen["solve_time_ms"]["median"] / avg["solve_time_ms"]["median"]
    print(f"  per-step ratio general/averaged (median): {ratio:.2f}x   [paper 9.34/0.58 = {9.34 / 0.58:.1f}x]")
    p95_ratio = gen["solve_time_ms"]["p95"] / avg["solve_time_ms"]["p95"]
    print(f"  per-step ratio general/averaged (p95): {p95_ratio:.2f}x")
    for label, s in runs.items():
        paper = PAPER[label]
        print(f"  {label:<9} per step {s['solve_time_ms']['median'] / 1e3:.4f} s vs paper {paper['per_step_s']} s "
              f"({paper['per_step_s'] / (s['solve_time_ms']['median'] / 1e3):.0f}x faster);"
              f" steps {s['steps']} vs {paper['steps']}; docking wall {s['wall_time_s']:.2f} s vs {paper['total_s']:.0f} s")
    print(f"  whole compare run: {total:.2f} s wall ({cpu:.2f} s CPU)  [goal < 10 s]")
    return {"ratio": ratio, "total_s": total}


def bench_case1() -> None:
    print("== underactuated-case1 start (§5), both variants ==")
    for label, overrides in (("averaged H=30", []),
                             ("general H=80", ["controller.variant=general", "controller.horizon=80"])):
        t0 = time.perf_counter()
        summary, _ = execute(load_scenario("underactuated-case1", overrides))
        print(_row(label, summary, time.perf_counter() - t0))


def bench_solvers() -> None:
    print("== warm solver: fatrop vs IPOPT (case 1 start, averaged H=30; IPOPT always does the first solve) ==")
    for solver in ("fatrop", "ipopt"):
        t0 = time.perf_counter()
        summary, _ = execute(load_scenario("underactuated-case1", [f"controller.solver={solver}"]))
        print(_row(solver, summary, time.perf_counter() - t0))


def bench_horizons() -> None:
    """General variant from the compare start at shorter horizons: the per-step cost grows
    with H. Measured once: H = 40 never reaches the terminal set (every warm solve fails,
    ~245 s for 1000 steps), so it is not run here."""
    from proxops.sim.engine import simulate
    from proxops.systems.underactuated import build_setup, run_configs

    print("== general variant vs horizon (compare start) ==")
    sc = load_scenario("underactuated-compare").scenario
    base = next(r for r in run_configs(sc) if r["label"] == "general")
    for horizon in (60, 80, 100):
        t0 = time.perf_counter()
        result = simulate(build_setup(sc, dict(base, horizon=horizon)))
        step = result.solve_time_s[: len(result.t) - 1] * 1e3
        print(f"  H={horizon:<4} outcome {result.meta.get('outcome'):<9} steps {len(step):4d}"
              f"  step median {np.median(step):6.2f} ms  p95 {np.percentile(step, 95):6.2f} ms"
              f"  run wall {time.perf_counter() - t0:5.2f} s")


def bench_case2() -> None:
    print("== underactuated-case2 (Table 3 limits), undamped and damped ==")
    t0 = time.perf_counter()
    summary, results = execute(load_scenario("underactuated-case2"))
    for label, s in summary["runs"].items():
        print(_row(label, s, s["wall_time_s"]))
    print(f"  total {time.perf_counter() - t0:.1f} s")


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    print(f"load average (1 min) at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    bench_compare()
    bench_case1()
    bench_solvers()
    if "--horizons" in argv:
        bench_horizons()
    if "--quick" not in argv:
        bench_case2()
    print(f"load average (1 min) at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
