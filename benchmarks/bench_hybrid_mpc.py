"""Benchmark: solve time per step of the hybrid capture / post-capture MPCs
(hybrid-mpc-capture.md Problems 2 and 3; issue 16 item 5; control/hybrid_mpc.py).

Prints, for T^0 (and T^1) = 5, 10, 20 s at the default 1 s period (N = 5, 10, 20 stages):
median and p95 of the whole controller step (all-in: linearisation + expm discretisation +
condensing + solver, what ``Command.solve_time_s`` records), the solver call alone (its data
update + solve) and the solver's share of the summed steps (issue 32 goal >= 50 %), the QP on
each solver by name (daqp, piqp, clarabel),
and their ratios to T = 5 s (the paper reports only that its YALMIP + SDPT3 time grows about
linearly with the horizon). Then the QP form of eq. 66 (DAQP) against the SOCP form
(Clarabel) at T^0 = 10 s: time and the exact-cost excess of the QP plan over the SOCP
optimum on the same states. Also the 0.5 s period (N = 20 at T^0 = 10 s) for the choice of
the period. Goal (issue 16): < 2 ms median per solve at T^0 = 10 s.

The states are a recorded closed loop (nonlinear relative model, scipy) replayed through a
fresh controller per variant, so every variant sees the same states in the same order
(warm starts and the re-linearised face penalty behave as in a run). Timings are wall-clock
on a shared machine: the load average is printed; compare ratios within one run.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_hybrid_mpc.py [--steps 60] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # single-threaded BLAS, as the CLI runs (proxops/cli.py)

import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from proxops.control.hybrid_mpc import (  # noqa: E402
    CaptureMPC,
    CaptureMPCConfig,
    PostCaptureMPC,
    PostCaptureMPCConfig,
    capture_weights,
    face_pointing_penalty,
    reduced_capture_state,
)
from proxops.core.quaternion import quat_from_axis_angle  # noqa: E402
from proxops.dynamics.hybrid_relative import (  # noqa: E402
    S_OM,
    S_OMC,
    S_P,
    S_Q,
    S_REF,
    S_RHO,
    S_RHOD,
    S_RN,
    S_RND,
    post_capture_rhs,
    relative_rhs,
)
from proxops.dynamics.two_rigid_bodies import HybridParams  # noqa: E402

PARAMS = HybridParams()


def _record(controller, x0, rhs, steps):
    """States seen by ``controller`` in a closed loop on ``rhs`` (scipy RK45, 1 s steps)."""
    x, states = x0.copy(), []
    controller.reset(0.0, x)
    for k in range(steps):
        states.append(x.copy())
        u = controller.step(float(k) * controller.dt, x).u
        x = solve_ivp(lambda t, xx: rhs(xx, u, PARAMS), (0.0, controller.dt), x, rtol=1e-7, atol=1e-10).y[:, -1]
        x[S_Q] /= np.linalg.norm(x[S_Q])
        x[S_P] /= np.linalg.norm(x[S_P])
    return states


def _replay(make, states, repeat, collisions=None):
    """(step times, solver times) in ms over ``repeat`` replays through fresh controllers."""
    steps, solver = [], []
    for _ in range(repeat):
        ctrl = make()
        ctrl.reset(0.0, states[0])
        if collisions is not None:
            ctrl.set_collision_count(collisions)
        for k, x in enumerate(states):
            t0 = time.perf_counter()
            cmd = ctrl.step(float(k), x)
            steps.append((time.perf_counter() - t0) * 1e3)
            solver.append(cmd.info["solver_time_s"] * 1e3)
            if not cmd.status.ok:
                print(f"  step {k}: {cmd.status}")
    return np.array(steps), np.array(solver)


def _exact_cost(mpc, x, du):
    Ad, Bd, _, _, _ = mpc.model(x[S_P], x[S_OMC], x[S_Q])
    Q, R, Qf = capture_weights(mpc.config, mpc.collisions)
    z, J = reduced_capture_state(x), 0.0
    for k in range(mpc.N):
        J += mpc.dt * du[k] @ (R * du[k])
        z = Ad @ z + Bd @ du[k]
        J += (mpc.dt * (z @ (Q * z) + face_pointing_penalty(z[0:3], mpc.v, mpc.config.face_weight))
              if k < mpc.N - 1 else z @ (Qf * z))
    return J


def _row(label, steps, solver, ref=None):
    med, p95, smed = np.median(steps), np.percentile(steps, 95), np.median(solver)
    share = solver.sum() / steps.sum()
    ratio = "" if ref is None else f"   x{med / ref:5.2f} (step)"
    print(f"  {label:<34s} step all-in median {med:6.3f} ms  p95 {p95:6.3f} ms   solver median {smed:6.3f} ms, "
          f"share {100 * share:3.0f} %{ratio}")
    return med


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=60, help="closed-loop steps recorded per controller (1 s each)")
    ap.add_argument("--repeat", type=int, default=3, help="replays of the recorded states per variant")
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f} "
          f"({os.cpu_count()} CPUs)")

    # capture: recorded with eq. 80 weights (c = 1) from an offset that saturates the box first
    x0 = np.zeros(32)
    x0[S_RHO], x0[S_RHOD], x0[S_OM] = [0.4, -0.3, 0.25], [0.01, 0.02, -0.01], [0.05, -0.04, 0.03]
    x0[S_Q] = quat_from_axis_angle(np.array([1.0, 2.0, -1.0]) / np.sqrt(6.0), 0.6)
    x0[S_P], x0[S_OMC] = [-0.5, 0.5, 0.5, 0.5], 0.0024 * np.array([-1.0, 1.0, -1.0])  # eq. 78
    recorder = CaptureMPC(PARAMS)
    recorder.set_collision_count(1)
    cap_states = _record(recorder, x0, relative_rhs, args.steps)

    print(f"\ncapture MPC (Problem 2), QP form of eq. 66 (DAQP), {args.steps} states x {args.repeat}:")
    ref = None
    for T in (5.0, 10.0, 20.0):
        for c in (0, 1):
            s, v = _replay(lambda T=T: CaptureMPC(PARAMS, CaptureMPCConfig(horizon_s=T)), cap_states, args.repeat, c)
            med = _row(f"T0 = {T:4.0f} s (N = {int(T)}), c = {c}", s, v, ref)
            if ref is None:
                ref = med
    s, v = _replay(lambda: CaptureMPC(PARAMS, CaptureMPCConfig(horizon_s=10.0, period_s=0.5)), cap_states, args.repeat, 1)
    _row("T0 = 10 s, 0.5 s period (N = 20), c=1", s, v, ref)
    print("\ncapture MPC, the QP on each solver by name (capture_mpc.solver; make_solver), T0 = 10 s, c = 1:")
    for name in ("daqp", "piqp", "clarabel"):
        s, v = _replay(lambda name=name: CaptureMPC(PARAMS, CaptureMPCConfig(solver=name)), cap_states, args.repeat, 1)
        _row(f"solver {name}", s, v, ref)

    print("\ncapture MPC, eq. 66 as an SOCP (Clarabel) vs the QP (DAQP), T0 = 10 s, c = 1:")
    for T in (5.0, 10.0, 20.0):
        s, v = _replay(lambda T=T: CaptureMPC(PARAMS, CaptureMPCConfig(horizon_s=T, face_form="socp")),
                       cap_states, 1, 1)
        _row(f"SOCP T0 = {T:4.0f} s", s, v, ref)
    # correctness of the QP form: exact cost of its plan vs the SOCP optimum on the same states
    qp = CaptureMPC(PARAMS, CaptureMPCConfig(approach_guidance=False))  # Problem 2 as printed (target rho = 0)
    socp = CaptureMPC(PARAMS, CaptureMPCConfig(face_form="socp", approach_guidance=False))
    excess, du_gap = [], []
    for ctrl in (qp, socp):
        ctrl.set_collision_count(1)
    for x in cap_states:
        a, b = qp.solve(x), socp.solve(x)
        if a["status"].ok and b["status"].ok:
            Ja, Jb = _exact_cost(qp, x, a["du"]), _exact_cost(socp, x, b["du"])
            excess.append((Ja - Jb) / Jb)
            du_gap.append(np.linalg.norm(a["u"] - b["u"]))
    excess = np.array(excess)
    print(f"  QP plan exact-cost excess over the SOCP optimum: median {np.median(excess):.2e}, "
          f"max {excess.max():.2e} (relative); |u_QP - u_SOCP| max {max(du_gap):.2e} N / N m "
          f"over {len(excess)} states")

    # post-capture: recorded from the eq. 78 chief attitude/tumble with a 5 cm CoM offset
    y0 = np.zeros(32)
    y0[S_Q] = [0.0, 0.0, 0.0, 1.0]
    y0[S_P], y0[S_OMC] = [-0.5, 0.5, 0.5, 0.5], 0.0024 * np.array([-1.0, 1.0, -1.0])
    y0[S_REF] = [0.5, -0.2, 0.1, 2e-4, -1e-3, 1e-4]
    y0[S_RN], y0[S_RND] = y0[S_REF][0:3] + [0.05, -0.03, 0.02], y0[S_REF][3:6] + [1e-3, 0.0, -1e-3]
    post_states = _record(PostCaptureMPC(PARAMS), y0, post_capture_rhs, args.steps)
    print(f"\npost-capture MPC (Problem 3, DAQP), {args.steps} states x {args.repeat}:")
    ref = None
    for T in (5.0, 10.0, 20.0):
        s, v = _replay(lambda T=T: PostCaptureMPC(PARAMS, PostCaptureMPCConfig(horizon_s=T)), post_states, args.repeat)
        med = _row(f"T1 = {T:4.0f} s (N = {int(T)})", s, v, ref)
        ref = ref or med
    print(f"\nload average at end: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")


if __name__ == "__main__":
    main()
