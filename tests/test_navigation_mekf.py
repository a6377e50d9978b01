"""Attitude MEKF (issue 28 item 4): error dynamics against finite differences of an independent
integration, Van Loan Q_d against quadrature, and consistency by Monte Carlo against an independent
truth (torque-free rotation with white angular-acceleration noise integrated by scipy solve_ivp at
tight tolerance, not the filter's RK4): NEES/NIS in their chi-square bands, convergence from 20 deg,
unit quaternion, a dropout window, and a mistuned filter that the same test catches."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad_vec, solve_ivp
from scipy.linalg import expm
from scipy.stats import chi2

from proxops.errors import ProxopsInputError
from proxops.navigation.consistency import mean_band
from proxops.navigation.mekf import AttitudeMEKF, attitude_error, error_dynamics, van_loan

J_TEST = np.diag([80.0, 120.0, 150.0])  # kg m^2, three distinct moments: the rate nutates
W0 = np.radians([1.5, -2.0, 3.0])  # rad/s


def _qmul(p, q):
    """Hamilton product written out (scalar last), independent of proxops.core.quaternion."""
    px, py, pz, pw = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qx, qy, qz, qw = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([pw * qx + qw * px + py * qz - pz * qy,
                     pw * qy + qw * py + pz * qx - px * qz,
                     pw * qz + qw * pz + px * qy - py * qx,
                     pw * qw - px * qx - py * qy - pz * qz], axis=-1)


def _exp(phi):
    """exp(phi / 2) as a unit quaternion, rows of phi (..., 3)."""
    phi = np.asarray(phi, float)
    a = np.linalg.norm(phi, axis=-1, keepdims=True)
    s = np.where(a > 0, np.sin(0.5 * a) / np.where(a > 0, a, 1.0), 0.5)
    return np.concatenate([phi * s, np.cos(0.5 * a)], axis=-1)


def _truth_rhs(J, accel):
    """Vectorised torque-free rotation of R bodies (state rows [q (4), w (3)]) with a constant
    angular acceleration ``accel`` (R, 3) added: qdot = 0.5 q (x) [w, 0], J wdot = -w x J w."""
    Jd = np.diag(J)

    def rhs(t, y):
        y = y.reshape(-1, 7)
        q, w = y[:, :4], y[:, 4:]
        wq = np.concatenate([w, np.zeros((w.shape[0], 1))], axis=1)
        Jw = w * Jd
        wdot = -np.cross(w, Jw) / Jd + accel
        return np.concatenate([0.5 * _qmul(q, wq), wdot], axis=1).ravel()

    return rhs


def _integrate(y, J, accel, t0, t1):
    sol = solve_ivp(_truth_rhs(J, accel), (t0, t1), y.ravel(), method="DOP853", rtol=1e-12, atol=1e-13)
    out = sol.y[:, -1].reshape(-1, 7)
    out[:, :4] /= np.linalg.norm(out[:, :4], axis=1, keepdims=True)
    return out


def test_error_dynamics_match_finite_differences():
    """F of the module docstring against the time derivative of the true body-frame error between a
    perturbed and the nominal solution (solve_ivp, central differences in time)."""
    q0 = _exp(np.radians([20.0, -35.0, 50.0]))
    w0 = np.radians([3.0, -4.0, 6.0])
    F = error_dynamics(w0, J_TEST, np.linalg.inv(J_TEST))
    eps, h = 1e-6, 1e-3
    for i in range(6):
        e0 = np.zeros(6)
        e0[i] = eps
        nom = np.concatenate([q0, w0])[None, :]
        per = np.concatenate([_qmul(q0, _exp(e0[:3])), w0 + e0[3:]])[None, :]
        errs = []
        for tt in (h, -h):
            a = _integrate(nom, J_TEST, np.zeros((1, 3)), 0.0, tt)[0]
            b = _integrate(per, J_TEST, np.zeros((1, 3)), 0.0, tt)[0]
            errs.append(np.concatenate([attitude_error(a[:4], b[:4]), b[4:] - a[4:]]))
        de = (errs[0] - errs[1]) / (2 * h)
        np.testing.assert_allclose(de / eps, F[:, i], rtol=2e-4, atol=2e-6)


def test_van_loan_matches_quadrature():
    """Q_d = int_0^dt expm(F s) Qc expm(F s)^T ds and Phi = expm(F dt)."""
    F = error_dynamics(np.radians([3.0, -4.0, 6.0]), J_TEST, np.linalg.inv(J_TEST), bias=True)
    Qc = np.diag([0.0] * 3 + [2e-7] * 3 + [1e-10] * 3)
    dt = 2.5
    phi, qd = van_loan(F, Qc, dt)
    ref, _ = quad_vec(lambda s: expm(F * s) @ Qc @ expm(F * s).T, 0.0, dt, epsabs=1e-22)
    np.testing.assert_allclose(phi, expm(F * dt), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(qd, ref, rtol=1e-8, atol=1e-20)


def _monte_carlo(runs=30, steps=150, dt=1.0, q_true=1e-7, q_filter=1e-7, sigma=math.radians(0.5),
                 att0_sigma=math.radians(20.0) / math.sqrt(3.0), rate0_sigma=math.radians(0.5),
                 dropout=(), pieces=4, seed=11):
    """Filters against the independent truth: R bodies rotating torque-free from W0 (random initial
    attitude), driven by white angular acceleration of PSD q_true realised as piecewise-constant
    accelerations N(0, q_true / h) over ``pieces`` pieces h of each step. Returns NEES (runs, steps),
    NIS (all updates), trace of the attitude covariance (runs, steps) and max | |q| - 1 |."""
    rng = np.random.default_rng(seed)
    y = np.zeros((runs, 7))
    y[:, :4] = _exp(rng.uniform(-math.pi, math.pi, (runs, 3)))
    y[:, 4:] = W0
    P0 = np.diag([att0_sigma ** 2] * 3 + [rate0_sigma ** 2] * 3)
    L0 = np.linalg.cholesky(P0)
    filters = []
    for r in range(runs):
        e = L0 @ rng.standard_normal(6)
        filters.append(AttitudeMEKF(_qmul(y[r, :4], _exp(-e[:3])), y[r, 4:] - e[3:], P0, np.diag(J_TEST), q_filter,
                                    gate_probability=1 - 1e-12))
    nees = np.zeros((runs, steps))
    tr = np.zeros((runs, steps))
    norm_err = 0.0
    h = dt / pieces
    for k in range(steps):
        for j in range(pieces):
            accel = rng.standard_normal((runs, 3)) * math.sqrt(q_true / h)
            y = _integrate(y, J_TEST, accel, k * dt + j * h, k * dt + (j + 1) * h)
        v = rng.standard_normal((runs, 3)) * sigma
        for r, f in enumerate(filters):
            f.predict(dt)
            if k not in dropout:
                f.update_attitude(_qmul(y[r, :4], _exp(v[r])), sigma)
            nees[r, k] = f.nees(y[r, :4], y[r, 4:])
            tr[r, k] = np.trace(f.P[:3, :3])
            norm_err = max(norm_err, abs(np.linalg.norm(f.q) - 1.0))
    nis = np.concatenate([f.nis for f in filters])
    return nees, nis, tr, norm_err


def test_nees_consistent_with_dropout_window():
    """30 runs x 150 s (1 Hz pose attitude, 0.5 deg), from 20 deg rms initial attitude error and
    0.5 deg/s rate error, no measurement in epochs 60..89: the run-averaged NEES over all epochs,
    over the window and over the 60 epochs after it lies in the 95 % band of a 30-run mean of
    chi2(6); the per-epoch mean is inside it at >= 90 % of the epochs (95 % expected); NIS mean in
    the pooled chi2(3) band; the attitude covariance grows monotonically through the window; the
    quaternion stays unit to 1e-12."""
    runs, window = 30, range(60, 90)
    nees, nis, tr, norm_err = _monte_carlo(runs=runs, dropout=window)
    lo, hi = mean_band(runs, 6)
    assert (lo, hi) == pytest.approx(tuple(chi2.ppf([0.025, 0.975], 180) / 30))
    mean_k = nees.mean(axis=0)
    assert lo <= mean_k.mean() <= hi, (mean_k.mean(), lo, hi)
    assert lo <= mean_k[60:90].mean() <= hi, mean_k[60:90].mean()
    assert lo <= mean_k[90:].mean() <= hi, mean_k[90:].mean()
    inside = np.mean((mean_k >= lo) & (mean_k <= hi))
    assert inside >= 0.90, inside
    lo_n, hi_n = chi2.ppf([0.0005, 0.9995], nis.size * 3) / nis.size
    assert lo_n <= nis.mean() <= hi_n, (nis.mean(), lo_n, hi_n)
    assert np.all(np.diff(tr[:, 59:90], axis=1) > 0.0)  # grows from the last update through the window
    assert tr[:, 90].max() < tr[:, 89].min()  # the first update after it shrinks it again
    assert norm_err < 1e-12


def test_mistuned_filter_fails_the_same_test():
    """The test can fail: with 100x less process noise than the truth, mean NEES leaves the band."""
    runs = 30
    nees, _, _, _ = _monte_carlo(runs=runs, steps=80, q_filter=1e-9, seed=5)
    lo, hi = mean_band(runs, 6)
    assert nees[:, 20:].mean() > hi


def test_converges_from_20_deg_error():
    """A 20 deg initial attitude error (P0: 20 deg per axis) and 1 deg/s rate error: after 60 s of
    1 Hz 0.5 deg measurements, attitude error < 3 sqrt(trace P_att) and < 0.5 deg, rate error
    < 3 sqrt(trace P_rate); the first update already removes > 90 % of the error."""
    rng = np.random.default_rng(2)
    sigma = math.radians(0.5)
    y = np.concatenate([_exp(np.radians([10.0, 40.0, -70.0])), W0])[None, :]
    err0 = math.radians(20.0) * np.array([1.0, -2.0, 2.0]) / 3.0
    P0 = np.diag([math.radians(20.0) ** 2] * 3 + [math.radians(1.0) ** 2] * 3)
    f = AttitudeMEKF(_qmul(y[0, :4], _exp(-err0)), W0 + np.radians([1.0, 0.0, 0.0]), P0, J_TEST, 1e-8)
    assert np.degrees(np.linalg.norm(attitude_error(f.q, y[0, :4]))) == pytest.approx(20.0)
    for k in range(60):
        y = _integrate(y, J_TEST, np.zeros((1, 3)), float(k), float(k + 1))
        f.predict(1.0)
        f.update_attitude(_qmul(y[0, :4], _exp(sigma * rng.standard_normal(3))), sigma)
        if k == 0:
            assert np.linalg.norm(attitude_error(f.q, y[0, :4])) < 0.1 * math.radians(20.0)
    e = f.error(y[0, :4], y[0, 4:])
    assert np.linalg.norm(e[:3]) < min(3 * math.sqrt(np.trace(f.P[:3, :3])), math.radians(0.5))
    assert np.linalg.norm(e[3:]) < 3 * math.sqrt(np.trace(f.P[3:, 3:]))


def test_gyro_bias_and_rate_updates():
    """With rate measurements carrying a constant bias and attitude updates, the bias is estimated:
    error < 3 sigma and the 9-state NEES < chi2.ppf(0.999, 9)."""
    rng = np.random.default_rng(4)
    b_true = np.radians([0.2, -0.1, 0.15])
    y = np.concatenate([_exp(np.radians([5.0, 10.0, 15.0])), W0])[None, :]
    P0 = np.diag([math.radians(5.0) ** 2] * 3 + [math.radians(0.5) ** 2] * 3 + [math.radians(0.5) ** 2] * 3)
    f = AttitudeMEKF(y[0, :4], y[0, 4:], P0, J_TEST, 1e-9, gyro_bias=True, q_bias_psd=1e-14)
    s_att, s_rate = math.radians(0.5), math.radians(0.01)
    for k in range(150):
        y = _integrate(y, J_TEST, np.zeros((1, 3)), float(k), float(k + 1))
        f.predict(1.0)
        f.update_attitude(_qmul(y[0, :4], _exp(s_att * rng.standard_normal(3))), s_att)
        f.update_rate(y[0, 4:] + b_true + s_rate * rng.standard_normal(3), s_rate)
    e = f.error(y[0, :4], y[0, 4:], b_true)
    assert np.all(np.abs(e[6:]) < 3 * np.sqrt(np.diag(f.P)[6:]))
    assert f.nees(y[0, :4], y[0, 4:], b_true) < chi2.ppf(0.999, 9)


def test_frame_rate_rotating_reference():
    """In a reference frame A turning at w_A about z, a body at rest in A (inertial rate w_A)
    keeps its attitude relative to A."""
    n = 1.1e-3
    q0 = _exp(np.radians([0.0, 0.0, 30.0]))
    f = AttitudeMEKF(q0, [0.0, 0.0, n], np.eye(6) * 1e-4, J_TEST, 0.0, frame_rate_rad_s=[0.0, 0.0, n])
    f.predict(600.0)
    assert np.degrees(np.linalg.norm(attitude_error(f.q, q0))) < 1e-9


def test_gate_rejects_an_outlier_and_bad_input():
    f = AttitudeMEKF([0, 0, 0, 1], [0, 0, 0], np.eye(6) * 1e-6, [1, 2, 3], 1e-9)
    out = f.update_attitude(_exp(np.radians([30.0, 0.0, 0.0])), math.radians(0.5))
    assert not out.accepted and f.rejected == 1 and f.events[0][0] == "nav-rejected"
    assert out.nis == pytest.approx(math.radians(30.0) ** 2 / (1e-6 + math.radians(0.5) ** 2))
    with pytest.raises(ProxopsInputError, match="P0"):
        AttitudeMEKF([0, 0, 0, 1], [0, 0, 0], np.eye(9), [1, 2, 3], 1e-9)
    with pytest.raises(ProxopsInputError, match="inertia"):
        AttitudeMEKF([0, 0, 0, 1], [0, 0, 0], np.eye(6), [1, -2, 3], 1e-9)
    with pytest.raises(ProxopsInputError, match="sigma"):
        f.update_attitude([0, 0, 0, 1], 0.0)


def test_add_rate_is_the_checked_reset_with_the_known_increments():
    """``add_rate`` (HybridNavigation's per-sample known inputs: a rate increment, a widened rate
    covariance) leaves rate and covariance exactly as ``reset`` with the incremented values does, so a
    prediction and an update after either agree (the attitude to rounding: ``reset`` renormalises q);
    unlike ``reset`` it keeps the filter's counters."""
    J = np.diag([10.0, 14.0, 9.0])
    q0 = np.array([0.1, -0.2, 0.3, 0.9])
    w0, P0 = np.array([0.01, -0.02, 0.015]), np.diag([1e-4] * 3 + [1e-6] * 3)
    a = AttitudeMEKF(q0, w0, P0, J, 1e-8, gyro_bias=False)
    b = AttitudeMEKF(q0, w0, P0, J, 1e-8, gyro_bias=False)
    for f in (a, b):
        f.predict(1.0)
        f.update_attitude(np.array([0.11, -0.19, 0.31, 0.9]), 0.01)
    P = a.P
    P[3:6, 3:6] += 1e-4 * np.eye(3)
    dw = np.array([1e-3, -2e-3, 5e-4])
    a.reset(a.q, a.omega + dw, P)
    b.add_rate(dw, 1e-4)
    np.testing.assert_array_equal(a.omega, b.omega)
    np.testing.assert_array_equal(a.P, b.P)
    assert (a.updates, len(a.nis), b.updates, len(b.nis)) == (0, 0, 1, 1)
    for f in (a, b):
        f.predict(1.0)
        f.update_attitude(np.array([0.12, -0.18, 0.3, 0.9]), 0.01)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.omega, b.omega, rtol=1e-13, atol=0)
    np.testing.assert_allclose(a.P, b.P, rtol=1e-12, atol=0)
    before = (b.q, b.omega, b.P)
    b.add_rate()  # nothing known: nothing changes
    for x, y in zip(before, (b.q, b.omega, b.P)):
        np.testing.assert_array_equal(x, y)
    with pytest.raises(ProxopsInputError):
        a.reset(a.q, a.omega, -P)
