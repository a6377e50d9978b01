"""A/B of the CORTEX planner and supervisor against a previous revision, alternated in one process
(issue 32: on a shared machine only ratios inside one process are figures; CPU time, load printed).

The previous revision's planner (guidance/cortex/{holds,phases,reference}.py, the approach-cone module)
and supervisor (control/cortex_{supervisor,tracking}.py) are read with ``git show REV:path`` into a
temporary package ``prevcortex``; everything else is this tree's. Prints:

1. CPU per reference plan, previous vs current, alternated axis by axis over N Fibonacci axes, with the
   largest differences of the plans (statuses, durations, node states, impulses, total delta-v);
2. the supervisor's own CPU per engine step (CortexSupervisor.step minus its CP_g solves) and the CPU
   of one CP_g solve, previous vs current, on cortex-nominal (CW truth), runs alternated.

Run: ``.venv/bin/python benchmarks/bench_cortex_ab.py [--rev main] [--n 40] [--runs 3]`` from the repository.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import importlib  # noqa: E402
import math  # noqa: E402
import re  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

FILES = {"holds": "guidance/cortex/holds.py", "phases": "guidance/cortex/phases.py",
         "reference": "guidance/cortex/reference.py", "approach_cone": "constraints/approach_cone.py",
         "cortex_supervisor": "control/cortex_supervisor.py", "cortex_tracking": "control/cortex_tracking.py"}


def load_previous(rev: str):
    """The previous revision's modules as package ``prevcortex`` (imports among them rewritten)."""
    root = Path(tempfile.mkdtemp(prefix="prevcortex-"))
    pkg = root / "prevcortex"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for name, path in FILES.items():
        text = subprocess.run(["git", "show", f"{rev}:src/proxops/{path}"], check=True, capture_output=True,
                              text=True).stdout
        text = re.sub(r"proxops\.guidance\.cortex\.(holds|phases|reference)", r"prevcortex.\1", text)
        text = text.replace("from proxops.guidance.cortex import holds", "from prevcortex import holds")
        text = re.sub(r"proxops\.constraints\.approach_cone", "prevcortex.approach_cone", text)
        text = re.sub(r"proxops\.control\.cortex_tracking", "prevcortex.cortex_tracking", text)
        text = text.replace("from proxops.sim.protocols import", "from proxops.contracts import")  # moved since
        text = text.replace("self.solver.setup(None,", "self.solver.setup_native(None,")  # the adapter's native set-up
        (pkg / f"{name}.py").write_text(text)
    sys.path.insert(0, str(root))
    return {name: importlib.import_module(f"prevcortex.{name}") for name in FILES}


def _load() -> str:
    return f"load {' '.join(open('/proc/loadavg').read().split()[:3])}, {os.cpu_count()} CPUs"


def plans(prev, n: int) -> None:
    from proxops.guidance.cortex import reference as cur
    from proxops.guidance.cortex.config import fibonacci_axes
    from proxops.scenarios.loader import load_scenario
    from proxops.systems.cortex_setup import config_from_scenario, eclipse_profile

    sc = load_scenario("cortex-reference").scenario
    cfg, prof = config_from_scenario(sc), eclipse_profile(sc)
    pcfg = prev["reference"].CortexConfig(**cfg.__dict__)
    run = {0: lambda e: prev["reference"].plan_reference(e, pcfg, eclipse=prof),
           1: lambda e: cur.plan_reference(e, cfg, eclipse=prof)}
    for e in fibonacci_axes(3):  # warm-up
        run[0](e), run[1](e)
    cpu = {0: [], 1: []}
    same, dx, ddv, dtot = 0, 0.0, 0.0, 0.0
    for i, e in enumerate(fibonacci_axes(n)):
        got = {}
        for w in ((0, 1) if i % 2 == 0 else (1, 0)):
            c0 = time.process_time()
            got[w] = run[w](e)
            cpu[w].append(time.process_time() - c0)
        a, b = got[0], got[1]
        same += (str(a.status) == str(b.status) and (a.tau1_s == b.tau1_s or math.isnan(a.tau1_s) and math.isnan(b.tau1_s))
                 and (a.tau2_s == b.tau2_s or math.isnan(a.tau2_s) and math.isnan(b.tau2_s))
                 and a.kos_iterations == b.kos_iterations and a.scp_iterations == b.scp_iterations
                 and a.evaluations_cp1 == b.evaluations_cp1 and a.evaluations_cp2 == b.evaluations_cp2)
        for pa, pb in ((a.cp1, b.cp1), (a.cp2, b.cp2)):
            if pa is not None and pb is not None and pa.x is not None and pb.x is not None and pa.x.shape == pb.x.shape:
                dx = max(dx, float(np.abs(pa.x - pb.x).max()))
                ddv = max(ddv, float(np.abs(pa.dv - pb.dv).max()))
        if math.isfinite(a.dv_total_mps) and math.isfinite(b.dv_total_mps):
            dtot = max(dtot, abs(a.dv_total_mps - b.dv_total_mps))
    p, c = np.array(cpu[0]), np.array(cpu[1])
    print(f"reference plan, {n} Fibonacci axes alternated ({_load()}): CPU per plan previous median {np.median(p):.4f} s, "
          f"current median {np.median(c):.4f} s (IQR {np.subtract(*np.percentile(c, [75, 25])):.4f}); ratio previous/current "
          f"{np.median(p) / np.median(c):.2f} (sums {p.sum() / c.sum():.2f}); goal 0.05 s per axis")
    print(f"  same status, durations, durations tried and KOS/SCP iterations {same}/{n}; largest differences: node state {dx:.3g} (m, m/s), impulse {ddv:.3g} m/s, "
          f"total delta-v {dtot:.3g} m/s")


def supervisor(prev, runs: int) -> None:
    from proxops.control import cortex_tracking as cur_tr
    from proxops.scenarios.loader import load_scenario
    from proxops.sim.engine import simulate
    from proxops.systems.cortex_loop import build_setup

    sup, ac = prev["cortex_supervisor"], prev["approach_cone"]
    sc = load_scenario("cortex-nominal", ["truth.model=cw"]).scenario
    solve_cpu = [0.0]
    for mod in (prev["cortex_tracking"], cur_tr):
        orig = mod.TrackingSOCP.solve

        def timed_solve(self, *a, _orig=orig, **kw):
            c0 = time.process_time()
            try:
                return _orig(self, *a, **kw)
            finally:
                solve_cpu[0] += time.process_time() - c0

        mod.TrackingSOCP.solve = timed_solve

    def previous_setup():
        setup, c, _ = build_setup(sc)
        tr, rp = c.triggers, c.replanner
        trig = sup.CortexTriggers(
            r_kos_m=tr.r_kos_m, rho_bar_m=tr.rho_bar_m, cone=ac.ApproachCone(tr.cone.axis, tr.cone.half_angle_rad),
            cone_bar=ac.ApproachCone(tr.cone_bar.axis, tr.cone_bar.half_angle_rad),
            plume=ac.PlumeConstraint(tr.plume.half_angle_rad), plume_bar=ac.PlumeConstraint(tr.plume_bar.half_angle_rad),
            eps_r_m=tr.eps_r_m, plume_min_dv_mps=tr.plume_min_dv_mps, buffer_tol_m=tr.buffer_tol_m,
            cone_buffer_tol_rad=tr.cone_buffer_tol_rad)
        replanner = sup.CortexReplanner(prev["reference"].CortexConfig(**rp.cfg.__dict__), rp.axis, eclipse=rp.eclipse,
                                        t0_offset_s=rp.t0_offset_s, max_candidates=rp.max_candidates,
                                        cone_return_s=rp.cone_return_s)
        tl = sup.Timeline(c.timeline0.n, [sup.Segment(s.phase, s.t0, s.t1, s.x_hold, s.t, s.x, s.dv)
                                          for s in c.timeline0.segments])
        setup.controller = sup.CortexSupervisor(
            c.n, c.a_max, tl, trig, replanner, sup.SupervisorSettings(**dataclasses.asdict(c.s)),
            ac.ApproachCone(c.cone.axis, c.cone.half_angle_rad), plume_bar=ac.PlumeConstraint(c.plume_bar.half_angle_rad))
        return setup, setup.controller

    def one(which):
        setup, ctrl = previous_setup() if which == 0 else build_setup(sc)[:2]
        step, acc = ctrl.step, [0.0, 0]

        def timed(t, x):
            c0 = time.process_time()
            cmd = step(t, x)
            acc[0] += time.process_time() - c0
            acc[1] += 1
            return cmd

        ctrl.step = timed
        solve_cpu[0] = 0.0
        res = simulate(setup, seed=0)
        n_solve = len(ctrl.cpg.solve_times) if which else len(ctrl.solve_times)
        return (acc[0] - solve_cpu[0]) / acc[1], solve_cpu[0] / n_solve, solve_cpu[0] / acc[0], res

    out = {0: [], 1: []}
    for r in range(runs):
        for w in ((0, 1) if r % 2 == 0 else (1, 0)):
            out[w].append(one(w))
    for w, label in ((0, "previous"), (1, "current")):
        own = [o[0] * 1e6 for o in out[w]]
        print(f"supervisor {label}: own CPU per step {np.median(own):.1f} us (runs {[round(v, 1) for v in own]}), "
              f"CP_g solve {np.median([o[1] for o in out[w]]) * 1e3:.3f} ms CPU, solver share of the controller "
              f"{np.median([o[2] for o in out[w]]):.0%}")
    a, b = out[0][0][3], out[1][0][3]
    same = a.x_true.shape == b.x_true.shape and float(np.abs(a.x_true - b.x_true).max()) == 0.0
    print(f"  cortex-nominal (CW truth) outcome previous {a.meta.get('outcome')}, current {b.meta.get('outcome')}; "
          f"trajectories {'identical' if same else 'differ'} ({_load()})")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rev", default="main")
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    prev = load_previous(args.rev)
    plans(prev, args.n)
    supervisor(prev, args.runs)


if __name__ == "__main__":
    main()
