"""A/B per-call cost of the solver consumers before/after the move onto forms + make_solver (issue 31
item 3), in ONE process, alternated in blocks (so machine load hits both alike), and the largest
difference of their answers.

The "before" tree is an older proxops renamed to ``proxops_old`` (so both import side by side)::

    mkdir -p /tmp/solvers_old && cd /tmp/solvers_old && git -C REPO archive BASE src/proxops | tar -x \
      && mv src/proxops proxops_old && rm -rf src && find proxops_old -name '*.py' -exec sed -i -E \
      's/\\bproxops\\./proxops_old./g; s/from proxops import/from proxops_old import/g' {} +
    PYTHONPATH=REPO/src:/tmp/solvers_old python benchmarks/ab_solver_interface.py [--rounds 15]

Prints per consumer: median per-call CPU time of the process (ms) of each side, the median and
quartiles of the per-round ratio new/old, and the largest |new - old| of the answers.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np


def _time(fn, calls: int) -> float:
    """CPU time of this process per call, ms (less sensitive than wall time to other processes on the cores)."""
    t0 = time.process_time()
    for i in range(calls):
        fn(i)
    return (time.process_time() - t0) / calls * 1e3


def thrusters(pkg):
    th = __import__(f"{pkg}.actuators.thrusters", fromlist=["x"])
    alloc = th.Allocator(th.six_thruster_layout())
    rng = np.random.default_rng(1)
    cmds = rng.uniform(-0.3, 0.3, (64, 6))
    return (lambda i: alloc.solve(cmds[i % 64])), (lambda: np.concatenate([alloc.solve(c).duty for c in cmds]))


def polytope_support(pkg):
    R = __import__(f"{pkg}.analysis.reach", fromlist=["x"])
    corridor = R.LosCorridor()
    grid = R.body_grid(corridor, 300, R.DEFAULT_GRID_Y_MAX_M)
    sec = R.backward_section(corridor, np.radians(1.0), 0.1,
                             ((grid.x_m[0], grid.y_m[0]), (grid.x_m[-1], grid.y_m[-1])))
    dirs = [np.array([math.cos(a), math.sin(a)]) for a in np.linspace(0, 2 * np.pi, 48, endpoint=False)]
    return (lambda i: sec.support_point(dirs[i % 48])), (lambda: np.concatenate([sec.support_point(d)[1] for d in dirs]))


def polytope_point_lp(pkg):
    R = __import__(f"{pkg}.analysis.reach", fromlist=["x"])
    corridor = R.LosCorridor()
    grid = R.body_grid(corridor, 300, R.DEFAULT_GRID_Y_MAX_M)
    sec = R.backward_section(corridor, np.radians(1.0), 0.1,
                             ((grid.x_m[0], grid.y_m[0]), (grid.x_m[-1], grid.y_m[-1])))
    rng = np.random.default_rng(2)
    pts = np.column_stack([rng.uniform(grid.x_m[0], grid.x_m[-1], 64), rng.uniform(grid.y_m[0], grid.y_m[-1], 64)])

    def one(i):
        ok = sec._point_feasible(pts[i % 64])
        sec._set(lb=sec.lb, ub=sec.ub)
        return ok

    return one, (lambda: np.array([one(i) for i in range(64)], float))


def cortex_tracking(pkg, plume: bool):
    ct = __import__(f"{pkg}.control.cortex_tracking", fromlist=["x"])
    cw = __import__(f"{pkg}.core.cw", fromlist=["x"])
    ac = __import__(f"{pkg}.constraints.approach_cone", fromlist=["x"])
    n = cw.mean_motion(6878.1e3)
    axis = np.array([-1.0, -1.0, 0.0]) / math.sqrt(2)
    prob = ct.TrackingSOCP(n, 15, 2.0, 2.4e-3, 10.0, cone=ac.ApproachCone(axis, math.radians(10)), plume=plume)
    x0 = np.concatenate([17.0 * axis, -0.02 * axis])
    xT = np.concatenate([16.0 * axis + [0.3, -0.3, 0.0], np.zeros(3)])
    shifts = np.linspace(-0.2, 0.2, 16)
    g = np.tile([[0.0, 0.0, 1.0]], (15, 1))

    def one(i):
        if plume:
            prob.set_plume(g + 0.01 * (i % 3))
        return prob.solve(x0 + np.array([shifts[i % 16], 0, 0, 0, 0, 0]), xT)

    return one, (lambda: np.concatenate([one(i)[0].ravel() for i in range(16)]))


def srf_piqp_update(pkg):
    """The srf solver path in isolation: a QuadraticProgram with A_eq on PIQP, update(b_eq, bu) + solve."""
    sol = __import__(f"{pkg}.solvers", fromlist=["x"])
    rng = np.random.default_rng(4)
    n, m, p = 60, 80, 12
    M = rng.normal(size=(n, n))
    P = M @ M.T / n + np.eye(n)
    A = rng.normal(size=(m, n))
    Aeq = rng.normal(size=(p, n))
    form = sol.QuadraticProgram(P, rng.normal(size=n), A, np.full(m, -np.inf), np.ones(m), -np.ones(n), np.ones(n),
                                Aeq, np.zeros(p))
    s = sol.make_solver(form, "piqp") if hasattr(sol, "make_solver") else sol.make_qp_solver("piqp")
    if not hasattr(sol, "make_solver"):
        s.setup(form)
    beqs = rng.normal(size=(16, p)) * 0.05

    def one(i):
        s.update(b_eq=beqs[i % 16], bu=np.ones(m) * (1 + 0.01 * (i % 5)))
        return s.solve()

    return one, (lambda: np.concatenate([one(i).x for i in range(16)]))


CASES = {
    "thrusters Allocator.solve (HiGHS)": (thrusters, 200),
    "polytope support_point (DAQP LP)": (polytope_support, 480),
    "polytope point-feasibility LP (HiGHS)": (polytope_point_lp, 128),
    "cortex TrackingSOCP.solve, cone (Clarabel)": (lambda pkg: cortex_tracking(pkg, False), 32),
    "cortex TrackingSOCP.solve, cone + plume (Clarabel)": (lambda pkg: cortex_tracking(pkg, True), 32),
    "srf-like PIQP update + solve (QP with A_eq)": (srf_piqp_update, 64),
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=15, help="alternated old/new rounds per consumer")
    args = ap.parse_args()
    for label, (make, calls) in CASES.items():
        sides = {pkg: make(pkg) for pkg in ("proxops_old", "proxops")}
        answers = {pkg: np.asarray(ans(), float) for pkg, (_, ans) in sides.items()}
        times = {pkg: [] for pkg in sides}
        for _ in range(args.rounds):
            for pkg, (fn, _) in sides.items():
                times[pkg].append(_time(fn, calls // 2))
        ratios = [n / o for n, o in zip(times["proxops"], times["proxops_old"])]
        q1, med, q3 = statistics.quantiles(ratios, n=4)
        old, new = statistics.median(times["proxops_old"]), statistics.median(times["proxops"])
        diff = float(np.max(np.abs(answers["proxops"] - answers["proxops_old"])))
        print(f"{label:52s} old {old:7.4f} ms  new {new:7.4f} ms  new/old median {med:5.3f} [{q1:5.3f}, {q3:5.3f}]"
              f"  max|diff| {diff:.1e}")


if __name__ == "__main__":
    main()
