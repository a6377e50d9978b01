"""Benchmark + figure: hybrid capture physics (hybrid-mpc-capture.md §IV, issue 16 items 1-3).

Prints
1. the agreement of the paper's relative model f_0 (eq. 32) with the direct two-rigid-body
   truth over a 100 s tumbling arc (3.9 deg/s chief tumble, eq. 78 deputy rates, a smooth
   time-varying input), block by block, with our corrections and with the printed G2 of
   eq. 21 -- the "agreement figure" numbers (``--fig PATH`` also draws it);
2. the jump maps against the truth impulse: g_0 (eqs. 34-39) with the corrected and the
   printed eq. 38, eq. 33 corrected/printed against the truth's contact velocity;
3. the first contact of the free-flying eq. 78 approach located by root finding on the
   guard vs a 1 ms brute-force scan, its impulse for e = 0, 0.5, 1 and the momentum /
   energy changes across the jump;
4. the cost of one truth RHS evaluation and of the 100 s reference integration.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_hybrid_physics.py [--fig out/hybrid_agreement.png]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import solve_ivp

from proxops.analysis.hybrid_model_check import AGREEMENT_BLOCKS, TUMBLE, relative_model_agreement
from proxops.analysis.hybrid_model_check import test_input as u_of_t
from proxops.dynamics.hybrid_relative import (
    impact_velocity,
    post_capture_rhs,
    relative_contact_jump,
    relative_from_truth,
)
from proxops.dynamics.two_rigid_bodies import (
    HybridInitialState,
    HybridParams,
    contact_frame,
    contact_guard,
    contact_jump,
    contact_normal_velocity,
    kinetic_energy,
    momenta,
    propagate_truth,
    truth_rhs,
    truth_state_from_initial,
)

P = HybridParams()
BLOCKS = AGREEMENT_BLOCKS


def agreement(ts):
    _, X, err = relative_model_agreement(duration_s=float(ts[-1]), samples=ts.size, params=P)
    return X, err


def post_capture_agreement(ts):
    """f_1 (eq. 52, corrected / printed) vs the latched two-body truth from a rigidly docked
    start with a ~2 deg/s chief tumble and no input."""
    from proxops.core.quaternion import quat_to_dcm

    p = np.array([-0.5, 0.5, 0.5, 0.5])
    R = quat_to_dcm(p).T
    d = P.P_c - P.P_d
    omc = np.array([-0.02, 0.03, -0.01])
    ic = HybridInitialState(rho0_m=tuple(R.T @ d), rho0_dot_m_s=tuple(R.T @ np.cross(omc, d)), omega_rad_s=(0, 0, 0),
                            q=(0, 0, 0, 1), omega_c_rad_s=tuple(omc), p=tuple(p))  # fmt: skip
    x0 = truth_state_from_initial(P, ic)
    sol = propagate_truth(x0, (ts[0], ts[-1]), P, t_eval=ts, latched=True, rtol=1e-10)
    X = np.array([relative_from_truth(sol.y[:, k], P) for k in range(ts.size)])
    out = {}
    for corrected in (True, False):
        r = solve_ivp(lambda t, y: post_capture_rhs(y, np.zeros(6), P, corrected), (ts[0], ts[-1]), X[0],
                      method="DOP853", rtol=1e-10, atol=1e-12, t_eval=ts)  # fmt: skip
        out[corrected] = np.abs(X - r.y.T)
    return X, out


def first_contact():
    x0 = truth_state_from_initial(P, HybridInitialState())
    ev = lambda t, y: contact_guard(y, P)  # noqa: E731
    ev.terminal, ev.direction = True, -1
    t0 = time.perf_counter()
    sol = propagate_truth(x0, (0.0, 60.0), P, events=ev)
    t_root_wall = time.perf_counter() - t0
    t_root, x_c = sol.t_events[0][0], sol.y_events[0][0]
    dense = solve_ivp(lambda t, y: truth_rhs(t, y, np.zeros(6), P), (0.0, t_root + 1.0), x0, method="DOP853",
                      rtol=1e-11, atol=1e-12, dense_output=True)  # fmt: skip
    ts = np.arange(0.0, t_root + 1.0, 1e-3)
    g = np.array([contact_guard(dense.sol(t), P) for t in ts])
    k = int(np.argmax(g <= 0.0))
    return t_root, x_c, (ts[k - 1], ts[k]), t_root_wall


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--fig", default=None, help="write the agreement figure (PNG) here")
    args = ap.parse_args()

    ts = np.linspace(0.0, 100.0, 201)
    X, err = agreement(ts)
    print("== f_0 (eq. 32) vs direct two-body truth, 100 s tumbling arc (max |error| over 201 samples) ==")
    print(f"  {'block':<16} {'corrected':>12} {'printed G2':>12}   range of the truth value")
    for name, sl in BLOCKS:
        print(f"  {name:<16} {err[True][:, sl].max():12.2e} {err[False][:, sl].max():12.2e}   {np.ptp(X[:, sl], axis=0).max():.3g}")

    Xp, errp = post_capture_agreement(np.linspace(0.0, 100.0, 101))
    print("\n== post-capture f_1 (eq. 52) vs latched two-body truth, rigid docked start, 100 s ==")
    print("   (an approximate model: the chief is the composite rigid body of eq. 51)")
    print(f"  {'block':<16} {'corrected':>12} {'printed':>12}   range of the truth value")
    for name, sl in BLOCKS:
        print(f"  {name:<16} {errp[True][:, sl].max():12.2e} {errp[False][:, sl].max():12.2e}   {np.ptp(Xp[:, sl], axis=0).max():.3g}")

    t_root, x_c, bracket, wall = first_contact()
    print("\n== first contact of the free-flying eq. 78 approach (no control) ==")
    print(f"  root finding on g(x): t = {t_root:.6f} s ({wall * 1e3:.0f} ms); 1 ms brute-force bracket "
          f"[{bracket[0]:.3f}, {bracket[1]:.3f}] s; paper (controlled): 11 s")  # fmt: skip
    r, n = contact_frame(x_c, P)
    xr = relative_from_truth(x_c, P)
    v = contact_normal_velocity(x_c, P)
    print(f"  contact point r = {np.round(r, 4).tolist()} m, normal n = {np.round(n, 4).tolist()}")
    print(f"  v_rel truth {v:.6f} m/s; eq. 33 corrected {impact_velocity(xr, r, n, P):.6f}; "
          f"printed {impact_velocity(xr, r, n, P, corrected=False):.6f} m/s")  # fmt: skip
    p0, h0 = momenta(x_c, P)
    k0 = kinetic_energy(x_c, P)
    for e in (0.0, 0.5, 1.0):
        xp, gamma, r, n = contact_jump(x_c, P, e)
        p1, h1 = momenta(xp, P)
        xrp = relative_from_truth(xp, P)
        g_c = np.abs(relative_contact_jump(xr, gamma, r, n, P) - xrp).max()
        g_p = np.abs(relative_contact_jump(xr, gamma, r, n, P, corrected=False) - xrp).max()
        print(f"  e = {e:3.1f}: gamma = {gamma:.4f} N s, |dP| = {np.abs(p1 - p0).max():.1e} N s, "
              f"|dH| = {np.abs(h1 - h0).max():.1e} N m s, dKE = {kinetic_energy(xp, P) - k0:+.4e} J; "
              f"g_0 vs truth {g_c:.1e} (printed eq. 38: {g_p:.1e})")  # fmt: skip

    x0 = truth_state_from_initial(P, TUMBLE)
    n_eval = 20000
    t0 = time.perf_counter()
    for _ in range(n_eval):
        truth_rhs(0.0, x0, np.zeros(6), P)
    per = (time.perf_counter() - t0) / n_eval
    t0 = time.perf_counter()
    sol = propagate_truth(x0, (0.0, 100.0), P, u_of_t=u_of_t)
    print(f"\n== cost == truth RHS {per * 1e6:.1f} us/eval; 100 s DOP853 rtol 1e-11: {sol.nfev} evals, "
          f"{time.perf_counter() - t0:.3f} s")  # fmt: skip

    if args.fig:
        from proxops.plotting.hybrid import plot_model_agreement

        plot_model_agreement(ts, err, BLOCKS, args.fig)
        print(f"figure written: {args.fig}")

if __name__ == "__main__":
    main()
