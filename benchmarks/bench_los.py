"""Benchmark of the ``los`` system (tumbling-target-reachability.md, issue 5; issue 32 item 2).

1. Horizon scaling of the closed-loop controller step (issue 32 item 2): for N = 20, 40, 80, 160,
   the los-tumble loop (2 deg/s, 0.1 m/s^2, start 60 m on the docking axis, J2 truth, 300 steps),
   per controller step: wall time (``perf_counter_ns``) of the whole step (guidance + MPC), of DAQP's
   own calls (``daqp.Model.update`` and ``.solve``, timed through a proxy around the adapter's model;
   the proxy's ~0.2 us per call is booked to "own"), and "own" = step - DAQP; medians per step, the
   shares from sums over the steps not preempted (step < 3x the median), and the log-log growth of
   the medians between successive N. Goal: own < 30 % of the step at N = 40, own growing no faster
   than DAQP. On a loaded machine the ratios inside one run are the figures (the load average is
   printed); a second table splits "own" into guidance, LosMpc and the solver adapter's Python, and gives the
   solver share as ``make bench`` (benchmarks/ab.py) counts it: the adapter's update/solve calls included.
   ``--ab REV`` runs the same loop with ``control/los_mpc.py`` of commit REV (read with ``git show``;
   its ``solver.setup(`` call renamed to ``setup_native(`` as the solver adapters now require; the guidance is
   this tree's on both sides: benchmarks/ab.py compares whole releases)
   alternated with this tree's, in the same process.
2. QP solve time per step (median, p95) of the eq.-(11) MPC on DAQP, N_p = 20 and 40,
   measured inside closed-loop runs against J2 truth (goal: median < 0.2 ms at N_p = 40;
   issue reference: 0.09 ms).
3. Wall time of one 400 s closed-loop run with J2 truth (goal < 0.3 s), per component.
4. r_sync validation: all 15 Table 3 combinations, co-rotating starts on the docking axis
   at 0.4 r_sync (hard constraints) and 1.5 r_sync (soft constraints), 600 s.
   ``--quick`` skips it.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/bench_los.py [--quick] [--scaling-only] [--ab REV]``
(best with OPENBLAS_NUM_THREADS=1 on a shared 2-core machine).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import importlib.util  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from proxops.control import los_regimes  # noqa: E402
from proxops.dynamics.tumbling_target import sync_range  # noqa: E402
from proxops.sim.engine import simulate  # noqa: E402
from proxops.systems.los import (  # noqa: E402
    SWEEP_A_MAX_MPS2,
    SWEEP_RATES_DEG_S,
    build_setup,
    default_scenario,
    run_case,
)

GOAL_SOLVE_MS = 0.2
ISSUE_SOLVE_MS = 0.09
GOAL_RUN_S = 0.3


def _scenario(config: str, duration_s: float = 400.0):
    return default_scenario(sim={"duration_s": duration_s, "dt_s": 1.0}, target={"tumble_rate_deg_s": 2.0},
                            chaser={"a_max_mps2": 0.1, "initial_body_position_m": [5.0, 120.0, -3.0]},
                            mpc={"config": config})


def solve_times() -> None:
    print("QP solve time per step (DAQP, warm start, closed loop 2 deg/s, 0.1 m/s^2, start 120 m, J2 truth)")
    for config, n_p in (("monte-carlo", 20), ("single", 40)):
        setup = build_setup(_scenario(config, 600.0))
        res = simulate(setup)
        st = res.solve_time_s[1:-1] * 1e3  # first solve is the cold start
        st = st[st > 0]
        build = res.info.get("mpc_build_ms", np.array([np.nan]))
        iters = res.info.get("mpc_iterations", np.array([np.nan]))
        med, p95 = np.median(st), np.percentile(st, 95)
        print(f"  N_p = {n_p}: median {med:.3f} ms, p95 {p95:.3f} ms, max {st.max():.3f} ms, "
              f"iterations median {np.nanmedian(iters):.0f} / max {np.nanmax(iters):.0f}, "
              f"QP data update median {np.nanmedian(build):.3f} ms"
              + (f"  | goal {GOAL_SOLVE_MS} ms: ratio {med / GOAL_SOLVE_MS:.2f}, issue ref {ISSUE_SOLVE_MS} ms: "
                 f"ratio {med / ISSUE_SOLVE_MS:.2f}" if n_p == 40 else ""))


def run_wall_time() -> None:
    print("Wall time of one 400 s closed-loop run, J2 truth")
    for config in ("monte-carlo", "single"):
        setup = build_setup(_scenario(config))
        simulate(build_setup(_scenario(config, 5.0)))  # JIT / imports warm
        times = []
        for _ in range(3):
            setup = build_setup(_scenario(config))
            t0 = time.perf_counter()
            res = simulate(setup)
            times.append(time.perf_counter() - t0)
        best = min(times)
        print(f"  {config:11s}: best of 3 {best:.3f} s (median {np.median(times):.3f} s), "
              f"{len(res.t) - 1} steps, {best / (len(res.t) - 1) * 1e3:.3f} ms/step | goal {GOAL_RUN_S} s: "
              f"ratio {best / GOAL_RUN_S:.2f}")
    # where the time goes (one run, per step)
    setup = build_setup(_scenario("monte-carlo"))
    plant, ctrl, con = setup.plant, setup.controller, setup.constraints[0]
    s = plant.initial_state()
    x = plant.relative_state(s)
    ctrl.reset(0.0, x)
    acc = dict(truth=0.0, body_state=0.0, controller=0.0, corridor_check=0.0)
    for k in range(400):
        t = float(k)
        a = time.perf_counter()
        x = plant.relative_state(s)
        b = time.perf_counter()
        con.violation(t, x)
        c = time.perf_counter()
        cmd = ctrl.step(t, x)
        d = time.perf_counter()
        s = plant.propagate(t, s, cmd.u, 1.0)
        e = time.perf_counter()
        acc["body_state"] += b - a
        acc["corridor_check"] += c - b
        acc["controller"] += d - c
        acc["truth"] += e - d
    print("  per step (monte-carlo): " + ", ".join(f"{k} {v / 400 * 1e3:.3f} ms" for k, v in acc.items()))


def r_sync_validation() -> None:
    print("r_sync validation (Table 3 combinations, co-rotating start on the axis, 600 s, J2 truth)")
    print("  | w_t | a_max | r_sync | 0.4 r_sync hard: violations / feasible / hold | 1.5 r_sync soft: violations (max m) |")
    ok_in = ok_out = 0
    for w in SWEEP_RATES_DEG_S:
        for a in SWEEP_A_MAX_MPS2:
            r_sync = sync_range(a, np.radians(w))
            inside = run_case(w, a, [0.0, 0.4 * r_sync, 0.0], mpc_config="single")
            outside = run_case(w, a, [0.0, 1.5 * r_sync, 0.0], mpc_config="single", constraint_mode="soft")
            ok_in += inside["los_violations"] == 0 and inside["feasible"]
            ok_out += outside["los_violations"] > 0
            print(f"  | {w:g} | {a:.2f} | {r_sync:6.1f} | {inside['los_violations']} / {inside['feasible']} / "
                  f"{inside['hold_reached']} | {outside['los_violations']} ({outside['max_violation_m']:.3g}) |")
    print(f"  inside r_sync without violations: {ok_in}/15; outside with violations: {ok_out}/15 "
          "(paper §10.6: 15/15 and 15/15)")


SCALING_N = (20, 40, 80, 160)
_GUIDED_QP_DATA = los_regimes._guided_qp_data
SCALING_STEPS = 300
GOAL_OWN_SHARE_N40 = 0.30


class _TimedModel:
    """Proxy around a ``daqp.Model``: books the time (ns, ``clock``) of its ``update`` and ``solve`` calls."""

    def __init__(self, model, clock):
        self._m, self._clock, self.ns = model, clock, 0

    def update(self, **kw):
        t0 = self._clock()
        out = self._m.update(**kw)
        self.ns += self._clock() - t0
        return out

    def solve(self):
        t0 = self._clock()
        out = self._m.solve()
        self.ns += self._clock() - t0
        return out


def _old_mpc_module(rev: str):
    """``control/los_mpc.py`` of commit ``rev`` as a module (the A side of --ab)."""
    root = Path(__file__).resolve().parents[1]
    src = subprocess.run(["git", "show", f"{rev}:src/proxops/control/los_mpc.py"], cwd=root, check=True,
                         capture_output=True, text=True).stdout
    src = src.replace("self._solver.setup(", "self._solver.setup_native(")  # the adapters' native entry now
    path = Path(os.environ.get("TMPDIR", "/tmp")) / f"los_mpc_{rev}.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location(f"los_mpc_{rev}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    if not hasattr(module.LosMpc, "solve_raw"):  # before the guidance called solve_raw: the same tuple from solve
        def solve_raw(self, t, x_body, x_ref, u_prev=None):
            sol = self.solve(t, x_body, x_ref, u_prev)
            return (sol.status, sol.u0, sol.theta_rad, sol.inputs, sol.solve_time_s, sol.build_time_s,
                    sol.iterations, sol.max_slack_m, sol.info)
        module.LosMpc.solve_raw = solve_raw
    if not hasattr(module.LosMpc, "lean_inputs"):  # before the guidance ran the QP data kernel itself: solve_raw
        module.LosMpc.lean_inputs = lambda self: None
    return module


def _timed_method(obj, name: str, clock, acc: dict, key: str, depth: list | None = None) -> None:
    """Replace ``obj.name`` by a wrapper that books its time (``clock``, ns) into ``acc[key]``; wrappers sharing
    ``depth`` (a one-element list) book only the outermost of nested calls."""
    real = getattr(obj, name)
    acc.setdefault(key, 0)
    depth = [0] if depth is None else depth

    def wrapper(*args, **kwargs):
        depth[0] += 1
        t0 = clock()
        try:
            return real(*args, **kwargs)
        finally:
            depth[0] -= 1
            if depth[0] == 0:
                acc[key] += clock() - t0

    setattr(obj, name, wrapper)


def _scaling_run(N: int, steps: int, mpc_module=None, split: bool = False):
    """One closed loop of ``steps`` samples at horizon N; per-step (step, DAQP) wall time in us
    (the first 3 steps - DAQP set-up, cold working set - left out). ``split``: also time the MPC's
    part (``LosMpc.solve_raw`` / ``solve_staged`` and the guidance's fused QP data kernel
    ``los_regimes._guided_qp_data``, whose guidance part is < 0.1 us) and the solver adapter's update/solve calls
    (wrappers, ~0.3 us each, booked to the caller);
    returns (step, DAQP, LosMpc.solve, adapter calls) then."""
    clock = time.perf_counter_ns  # ~50 ns a call (vDSO); thread_time_ns is a system call, ~0.5-1 us under load
    sc = default_scenario(sim={"duration_s": float(steps), "dt_s": 1.0}, target={"tumble_rate_deg_s": 2.0},
                          chaser={"a_max_mps2": 0.1, "initial_body_position_m": [0.0, 60.0, 0.0]},
                          mpc={"config": "single", "horizon": N})
    setup = build_setup(sc)
    plant, ctrl = setup.plant, setup.controller
    if mpc_module is not None:
        m = ctrl.mpc
        ctrl.mpc = mpc_module.LosMpc(m.model, m.corridor, m.a_max, m.cfg)
    s = plant.initial_state()
    ctrl.reset(0.0, plant.relative_state(s))
    step_us, daqp_us, mpc_us, adapter_us = (np.zeros(steps) for _ in range(4))
    proxy = None
    acc = {}
    if split:
        depth = [0]  # solve_raw calls solve_staged: booked once
        for obj, name in ((ctrl.mpc, "solve_raw"), (ctrl.mpc, "solve_staged"), (los_regimes, "_guided_qp_data")):
            _timed_method(obj, name, clock, acc, "mpc", depth)
    for k in range(steps):
        x = plant.relative_state(s)
        if proxy is None and ctrl.mpc._solver is not None:
            proxy = ctrl.mpc._solver._model = _TimedModel(ctrl.mpc._solver._model, clock)
            if split:
                adapter_depth = [0]
                for name in ("update_fast", "solve", "solve_fast", "solve_bounds_fast"):
                    _timed_method(ctrl.mpc._solver, name, clock, acc, "adapter", adapter_depth)
        before = proxy.ns if proxy is not None else 0
        a0 = dict(acc)
        t0 = clock()
        cmd = ctrl.step(float(k), x)
        step_us[k] = (clock() - t0) / 1e3
        daqp_us[k] = ((proxy.ns if proxy is not None else 0) - before) / 1e3
        if split:
            mpc_us[k] = (acc["mpc"] - a0["mpc"]) / 1e3
            adapter_us[k] = (acc.get("adapter", 0) - a0.get("adapter", 0)) / 1e3
        s = plant.propagate(float(k), s, cmd.u, 1.0)
    if split:
        los_regimes._guided_qp_data = _GUIDED_QP_DATA  # the module's own kernel again
        return step_us[3:], daqp_us[3:], mpc_us[3:], adapter_us[3:]
    return step_us[3:], daqp_us[3:]


def horizon_scaling(ab_rev: str | None = None, steps: int = SCALING_STEPS, repeats: int = 2) -> dict:
    """Section 1 of the module doc; returns {(side, N): (median step us, median DAQP us, own share)}."""
    load = open("/proc/loadavg").read().split()[:3] if os.path.exists("/proc/loadavg") else ["?"] * 3
    print(f"Horizon scaling of the los controller step (wall time per step, {steps} steps x {repeats}, "
          f"{os.cpu_count()} CPUs, load average {' '.join(load)})")
    sides = {"this tree": None}
    if ab_rev:
        sides = {ab_rev: _old_mpc_module(ab_rev), "this tree": None}
    print("  | side | N | step us (median) | DAQP us (update + solve) | own us | own share of the step | "
          "solver share | own growth | DAQP growth |")
    out, prev = {}, {}
    for N in SCALING_N:
        for module in sides.values():
            _scaling_run(N, 8, module)  # JIT, caches, memoised blocks
        acc = {side: ([], []) for side in sides}
        for _ in range(repeats):
            for side, module in sides.items():  # alternated in one process
                st, dq = _scaling_run(N, steps, module)
                acc[side][0].append(st)
                acc[side][1].append(dq)
        for side in sides:
            st, dq = np.concatenate(acc[side][0]), np.concatenate(acc[side][1])
            keep = st < 3.0 * np.median(st)  # steps preempted by other processes left out of the sums
            own = st - dq
            share = own[keep].sum() / st[keep].sum()
            med_own, med_dq = float(np.median(own)), float(np.median(dq))
            grow = ""
            if side in prev:
                n0, o0, d0 = prev[side]
                k = np.log(N / n0)
                grow = f"N^{np.log(med_own / o0) / k:.2f} | N^{np.log(med_dq / d0) / k:.2f}"
            else:
                grow = "- | -"
            prev[side] = (N, med_own, med_dq)
            out[(side, N)] = (float(np.median(st)), med_dq, share)
            goal = (f"  (goal own < {GOAL_OWN_SHARE_N40:.0%}: ratio {share / GOAL_OWN_SHARE_N40:.2f})"
                    if N == 40 and side == "this tree" else "")
            print(f"  | {side} | {N} | {np.median(st):.1f} | {med_dq:.1f} | {med_own:.1f} | {share:.2f} | "
                  f"{1 - share:.2f} | {grow} |{goal}")
    print("  Where \"own\" goes (this tree; medians per step, us; wrappers of ~0.3 us per call booked to the caller):")
    print("  | N | guidance + supervisor | LosMpc (kernel, glue) | solver adapter (Python) | DAQP | MPC own share of "
          "LosMpc.solve | solver share with the adapter's calls (make bench's definition) |")
    for N in SCALING_N:
        st, dq, mp, ad = (np.concatenate(a) for a in zip(*(_scaling_run(N, steps, None, split=True)
                                                           for _ in range(repeats))))
        keep = st < 3.0 * np.median(st)
        mpc_own = (mp - dq)[keep].sum() / mp[keep].sum()
        print(f"  | {N} | {np.median(st - mp):.1f} | {np.median(mp - ad):.1f} | {np.median(ad - dq):.1f} | "
              f"{np.median(dq):.1f} | {mpc_own:.2f} | {ad[keep].sum() / st[keep].sum():.2f} |")
    if ab_rev:
        for N in SCALING_N:
            a, b = out[(ab_rev, N)], out[("this tree", N)]
            print(f"  N = {N}: step {b[0]:.1f} us vs {a[0]:.1f} us at {ab_rev} (ratio {b[0] / a[0]:.2f}); "
                  f"own share {b[2]:.2f} vs {a[2]:.2f}")
    return out


def main() -> None:
    ab = None
    if "--ab" in sys.argv:
        ab = sys.argv[sys.argv.index("--ab") + 1]
    horizon_scaling(ab)
    if "--scaling-only" in sys.argv:
        return
    solve_times()
    run_wall_time()
    if "--quick" not in sys.argv:
        r_sync_validation()


if __name__ == "__main__":
    main()
