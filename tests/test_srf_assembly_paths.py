"""The lean per-solve paths of the srf MPC and its PIQP adapter against the plain constructions they
replace: the one-pass data scan of PiqpQP.update_fast (vs numpy's per-field checks), the free-drift
verdict kernel (vs np.all / np.min of the eq. 28 definitions), the drift-invariant samples (vs
np.mean of a list), EnergyDrift.invariant (vs the array path) and G's per-build entries written in
place (vs a fresh COO -> CSC gather of the same values). Equalities are bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp

from proxops.constraints.keep_out import KeepOutSphere
from proxops.control.srf_mpc import (EnergyDrift, SrfMpc, SrfMpcConfig, _drift_verdict_kernel, _Samples,
                                     build_schedule)
from proxops.core.cw import cw_stm, mean_motion
from proxops.errors import ProxopsInputError
from proxops.frames.lvlh import lvlh_vector_to_hill
from proxops.guidance.hop_times import plan_hops
from proxops.solvers import SolveStatus, make_solver
from proxops.solvers.piqp_qp import _scan_fast


def _scan_reference(A, G, c, b, h_l, h_u, x_lb, x_ub, free_now):
    """What BadData.check, first_crossed and _free_variables compute, field by field in numpy."""
    bad = [not np.isfinite(v).all() for v in (A, G, c, b)] + [bool(np.isnan(v).any()) for v in (h_l, h_u, x_lb, x_ub)]
    h_bad, x_bad = np.flatnonzero(h_l > h_u), np.flatnonzero(x_lb > x_ub)
    crossed = (1, int(h_bad[0])) if h_bad.size else (2, int(x_bad[0])) if x_bad.size else (0, -1)
    fixed = (x_lb == x_ub) & np.isfinite(x_lb)
    free = np.flatnonzero(~fixed)
    return bad, crossed, free, bool(np.any(x_lb[fixed] != 0.0)), np.array_equal(free, free_now)


@pytest.mark.parametrize("seed", range(8))
def test_scan_fast_equals_the_per_field_checks(seed):
    rng = np.random.default_rng(seed)
    n, m, p = 30, 20, 4
    A, G, c, b = rng.normal(size=40), rng.normal(size=70), rng.normal(size=n), rng.normal(size=p)
    h_l, h_u = -rng.random(m), rng.random(m)
    x_lb, x_ub = -rng.random(n), rng.random(n)
    fixed = rng.random(n) < 0.4
    x_lb[fixed] = x_ub[fixed] = np.where(rng.random(fixed.sum()) < 0.5, 0.0, rng.normal(size=fixed.sum()))
    x_lb[~fixed & (rng.random(n) < 0.2)] = -np.inf  # infinite lower bounds are allowed
    x_lb[0] = x_ub[0] = np.inf  # an infinite "fixed" pair is not fixed
    for arr, k in ((A, seed % 4), (h_l, seed % 5)):  # NaN / inf injected in some seeds
        if seed % 3 == 0:
            arr[k] = np.nan if seed % 2 else np.inf
    if seed % 4 == 1:
        h_l[m - 2], h_u[m - 2] = 1.0, 0.0
    if seed % 4 == 2:
        k = int(np.flatnonzero(~fixed)[1])
        x_lb[k], x_ub[k] = 2.0, 1.0
    ref_bad, ref_crossed, ref_free, ref_shifted, _ = _scan_reference(A, G, c, b, h_l, h_u, x_lb, x_ub, None)
    for free_now in (ref_free, ref_free[:-1], np.empty(0, dtype=np.intp)):
        out = np.empty(n, dtype=np.intp)
        bad, crossed, at, n_free, same, shifted = _scan_fast(A, G, c, b, h_l, h_u, x_lb, x_ub, free_now, out)
        assert [bool(bad >> k & 1) for k in range(8)] == ref_bad
        assert (crossed, at) == ref_crossed
        assert np.array_equal(out[:n_free], ref_free) and shifted == ref_shifted
        assert same == np.array_equal(ref_free, free_now)


def test_update_fast_with_nonzero_fixed_values_equals_update_native():
    """Fixed variables at nonzero values (their terms moved into c, b, h): the one-pass scan's 'shifted' flag
    gives the same PIQP data and the same objective as update_native's own computation."""
    rng = np.random.default_rng(11)
    n, p, m = 12, 2, 8
    L = rng.normal(size=(n, n))
    P = sp.csc_matrix(np.triu(L @ L.T + n * np.eye(n)))
    A = sp.random(p, n, density=0.6, random_state=1, format="csc")
    G = sp.random(m, n, density=0.5, random_state=2, format="csc")
    for M in (A, G):
        M.sort_indices()
        M.indices.flags.writeable = M.indptr.flags.writeable = False
    fast, ref = (make_solver("QP", "piqp", drop_fixed=True) for _ in range(2))
    x0 = rng.uniform(-0.5, 0.5, n)
    lb, ub = np.full(n, -1.0), np.full(n, 1.0)
    for s in (fast, ref):
        s.setup_native(P, rng.normal(size=n), A, A @ x0, G, G @ x0 - 0.2, G @ x0 + 0.2, lb, ub)
        s.update_native(A=A, G=G)
    for step in range(4):
        lb, ub = np.full(n, -1.0), np.full(n, 1.0)
        k = rng.choice(n, 3 + step, replace=False)
        xf = x0.copy()
        if step % 2 == 0:
            xf[k] = 0.0  # fixed at zero (nothing moved into c, b, h) or at x0 (moved)
        lb[k] = ub[k] = xf[k]
        fields = dict(c=rng.normal(size=n), b=A @ xf, h_l=G @ xf - 0.2, h_u=G @ xf + 0.2, x_lb=lb, x_ub=ub, A=A, G=G)
        fast.update_fast(**fields)
        ref.update_native(**{key: (v.copy() if isinstance(v, np.ndarray) else v) for key, v in fields.items()})
        a, r = fast.solve(), ref.solve()
        assert a.status == r.status == SolveStatus.OPTIMAL
        assert np.array_equal(a.x, r.x) and a.objective == r.objective
        Pf = P.toarray() + np.triu(P.toarray(), 1).T
        assert a.objective == pytest.approx(0.5 * a.x @ Pf @ a.x + fields["c"] @ a.x, rel=1e-12, abs=1e-12)


def test_drift_verdict_kernel_equals_numpy_on_nan_and_boundaries():
    rng = np.random.default_rng(3)
    center, radius, alpha = np.array([5.0, -3.0, 1.0]), 40.0, 0.01
    for trial in range(30):
        xs = rng.normal(scale=60.0, size=(17, 6))
        if trial % 5 == 0:
            xs[trial % 17, trial % 6] = np.nan
        d = np.linalg.norm(xs[:, :3] - center, axis=1)
        p = xs[:, :3] - center
        g = 2.0 * np.einsum("fk,fk->f", p, xs[:, 3:]) + alpha * (np.einsum("fk,fk->f", p, p) - radius**2)
        d_ok = float(np.median(d[np.isfinite(d)])) if trial % 2 else 0.0  # a threshold some samples miss
        g_ok = -1e-6 * alpha * radius**2
        ok, g_min, d_min = _drift_verdict_kernel(xs, center, radius, alpha, d_ok, g_ok)
        assert ok == bool(np.all(d >= d_ok) and np.all(g >= g_ok))
        assert np.array_equal(np.float64(d_min), np.min(d), equal_nan=True)
        np.testing.assert_allclose(g_min, np.min(g), rtol=1e-12)  # g's sums in another order than einsum's
        assert math.isnan(g_min) == bool(np.isnan(g).any())


def test_samples_mean_is_numpys_mean_of_the_list():
    rng = np.random.default_rng(4)
    s, times, values = _Samples(capacity=4), [], []
    for k in range(300):  # growth past the capacity, single and block appends
        if k % 7 == 0:
            t = np.arange(5) + 10.0 * k
            v = rng.normal(scale=1e-3, size=5) + 0.37
            s.extend(t, v)
            times += t.tolist()
            values += v.tolist()
        else:
            s.append(10.0 * k, float(rng.normal(scale=1e-3)) + 0.37)
            times.append(10.0 * k)
            values.append(float(s.values()[-1]))
    assert float(s.values().mean()) == float(np.mean(values))
    lo = times[150] - 1e-9
    assert float(s.values(lo).mean()) == float(np.mean([v for t, v in zip(times, values) if t >= lo]))
    s.clear()
    assert s.values().size == 0


def _ephemeris(n_pts=4000, dt=10.0):
    mu, a = 3.986004418e14, 6878e3
    n = math.sqrt(mu / a**3)
    t = np.arange(n_pts) * dt
    states = np.column_stack([a * np.cos(n * t), a * np.sin(n * t), 0 * t,
                              -a * n * np.sin(n * t), a * n * np.cos(n * t), 0 * t])
    return EnergyDrift(dt, states, mu, 1.08263e-3, 6378.137e3)


def test_energy_invariant_equals_the_array_path_and_refuses_off_grid_times():
    model = _ephemeris()
    rng = np.random.default_rng(5)
    for _ in range(20):
        t = 10.0 * int(rng.integers(0, 4000))
        x = rng.normal(scale=[500, 500, 50, 0.5, 0.5, 0.05])
        assert model.invariant(t, x) == float(model.invariants(np.array([t]), x[None, :])[0])
    with pytest.raises(ProxopsInputError):
        model.invariant(15.0, np.zeros(6))


def _vbar_controller(**cfg):
    n = mean_motion(8100e3)
    dt = 2 * math.pi / n / 720
    plan = plan_hops(0.0, 3, 0.5, 2000.0, 100.0, n)
    sched = build_schedule(plan.durations_s, 6, dt)
    a = lvlh_vector_to_hill([1.0, 0.0, 0.0])
    b = lvlh_vector_to_hill([0.0, 0.0, 1.0])
    d = np.array([h.start_m for h in plan.hops] + [plan.hops[-1].end_m])
    config = SrfMpcConfig(u_max_mps=3.0, vbar_rows=True, epsilon_m=50.0, hop_distance_weight_per_m2=1e-7,
                          free_drift_nodes=24, drift_free_tol_mps=1e-4, **cfg)
    return SrfMpc(n, sched, a, b, 100.0 * a, KeepOutSphere(50.0, center_m=np.array([0.0, 3.0, 0.0])), config,
                  hop_distances_m=d), n, a


def test_g_entries_written_in_place_equal_a_fresh_gather():
    """G after many builds (only the drift-gain and CBF entries rewritten) equals the matrix of a fresh
    controller's first build of the same node (every value gathered) and scipy's COO -> CSC of its values."""
    ctrl, n, a = _vbar_controller()
    rng = np.random.default_rng(6)
    x = np.concatenate([2000.0 * a, np.zeros(3)])
    cases = [(i, x + rng.normal(scale=[5, 5, 1, 1e-3, 1e-3, 1e-4]), rng.normal(scale=0.05, size=3), with_cbf)
             for i in (0, 3, 7, 12, 3) for with_cbf in (True, False, True)]
    for i, xi, u, with_cbf in cases:
        ctrl.plan[:] = rng.normal(scale=0.02, size=ctrl.plan.shape)
        got = ctrl._build(i, xi, u, 0, with_cbf=with_cbf).G
        fresh, _, _ = _vbar_controller()
        fresh.plan[:] = ctrl.plan
        want = fresh._build(i, xi, u, 0, with_cbf=with_cbf).G
        assert got.shape == want.shape and np.array_equal(got.indptr, want.indptr)
        assert np.array_equal(got.indices, want.indices) and np.array_equal(got.data, want.data)
        # independent: the CBF half-space rows are n_f' Phi(tau_f)[:3, 3:6] u_max / 1 km on the w columns
        if with_cbf:
            dense = got.toarray()
            F = ctrl._n_cbf
            xr = np.array([cw_stm(n, tau) @ (xi + np.r_[0, 0, 0, u]) for tau in ctrl.tau])
            nrm = (xr[:, :3] - ctrl.koz.center_m) / np.linalg.norm(xr[:, :3] - ctrl.koz.center_m, axis=1)[:, None]
            half = np.array([nf @ cw_stm(n, tau)[:3, 3:6] for nf, tau in zip(nrm, ctrl.tau)]) * 3.0 / 1000.0
            rows = dense[ctrl._n_g_static:ctrl._n_g_static + F, ctrl._iw:ctrl._iw + 3]
            np.testing.assert_allclose(rows, half, rtol=1e-9, atol=1e-15)


def test_target_rows_equal_numpys_gather_and_refuse_every_off_grid_time():
    model = _ephemeris(n_pts=500)
    t = 10.0 * np.arange(0, 500, 7) + 1e-9 * np.arange(0, 500, 7)  # on the grid within the 1e-6 tolerance
    k = np.rint(t / model.dt).astype(int)
    assert np.array_equal(model._targets(t), np.ascontiguousarray(model.states[k]))
    for bad in (np.array([0.0, 10.0, 15.0]), np.array([-10.0]), np.array([5000.0]), np.array([20.0, 30.0, 35.0])):
        with pytest.raises(ProxopsInputError):
            model._targets(bad)


def test_gain_at_the_node_is_the_row_of_the_predicted_gains():
    ctrl0, n, a = _vbar_controller()
    sched = ctrl0.sched
    mu, r = 3.986004418e14, 8100e3
    w = math.sqrt(mu / r**3)
    t = np.arange(sched.steps[-1] + 10) * sched.dt
    states = np.column_stack([r * np.cos(w * t), r * np.sin(w * t), 0 * t, -r * w * np.sin(w * t), r * w * np.cos(w * t), 0 * t])
    ctrl, _, _ = _vbar_controller(drift_model=EnergyDrift(sched.dt, states, mu, 1.08263e-3, 6378.137e3))
    rng = np.random.default_rng(8)
    ctrl.plan[:] = rng.normal(scale=0.02, size=ctrl.plan.shape)
    for i in (0, 2, 5, ctrl._drift_last, ctrl._drift_last + 1):
        x = np.concatenate([2000.0 * a, np.zeros(3)]) + rng.normal(scale=[5, 5, 1, 1e-3, 1e-3, 1e-4])
        assert np.array_equal(ctrl._drift_gain_at(i, x), ctrl._drift_gains(i, x)[i])
