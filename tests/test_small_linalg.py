"""Small numba kernels against their references: the Cholesky kernels of proxops.core.small_linalg (the
navigation filters' NEES and whitened innovations) against LAPACK through numpy on random symmetric
positive definite matrices; the single-quaternion propagation against the numpy form."""

import numpy as np

from proxops.core.small_linalg import mahalanobis_squared, whitened


def test_whitened_and_mahalanobis_match_lapack_on_random_spd_matrices():
    rng = np.random.default_rng(7)
    for n in (2, 3, 6, 9):
        for _ in range(50):
            B = rng.standard_normal((n, n))
            A = B @ B.T + 10.0 ** rng.uniform(-6, 0) * np.eye(n)  # condition numbers up to ~1e7
            v = rng.standard_normal(n) * 10.0 ** rng.uniform(-3, 3)
            L = np.linalg.cholesky(A)
            np.testing.assert_allclose(whitened(A, v), np.linalg.solve(L, v), rtol=1e-7, atol=0)
            ref = float(v @ np.linalg.solve(A, v))
            assert abs(mahalanobis_squared(A, v) - ref) <= 1e-7 * ref


def test_not_positive_definite_gives_nan_not_an_exception():
    """A covariance that lost positive definiteness yields NaN (a NaN NIS is rejected by the gate)."""
    A = np.diag([1.0, -1.0, 2.0])
    assert np.isnan(mahalanobis_squared(A, np.ones(3)))
    assert np.isnan(whitened(A, np.ones(3))).any()


def test_quaternion_propagate_kernel_has_the_bits_of_the_numpy_form():
    """core.quaternion.propagate_kernel (the tumbling target's attitude at t) against quat_propagate, the
    numpy form it replaces on that path: equal bit for bit over random attitudes, rates (1e-6-1 rad/s)
    and times, and at zero rate."""
    from proxops.core.quaternion import propagate_kernel, quat_propagate

    rng = np.random.default_rng(11)
    for _ in range(2000):
        q = rng.standard_normal(4)
        q /= np.linalg.norm(q)
        w = rng.standard_normal(3) * 10.0 ** rng.uniform(-6, 0)
        dt = float(rng.uniform(0.0, 1e4))
        np.testing.assert_array_equal(propagate_kernel(q, w, dt), quat_propagate(q, w, dt))
    np.testing.assert_array_equal(propagate_kernel(q, np.zeros(3), 5.0), quat_propagate(q, np.zeros(3), 5.0))


def test_gated_kalman_update_is_the_textbook_joseph_form():
    """core.small_linalg.gated_kalman_update (the EKF's and the MEKF's update) against the Joseph form
    (I - K H) P (I - K H)^T + K R K^T and x + K nu with K = P H^T (H P H^T + R)^-1 from numpy; a NIS
    above the gate (and a NaN one) is rejected with P unchanged."""
    from proxops.core.small_linalg import gated_kalman_update

    rng = np.random.default_rng(2)
    for n in (6, 9):
        for _ in range(30):
            B = rng.standard_normal((n, n))
            P = B @ B.T + 0.1 * np.eye(n)
            H = rng.standard_normal((3, n))
            C = rng.standard_normal((3, 3))
            R = C @ C.T + 0.01 * np.eye(3)
            nu = rng.standard_normal(3)
            S = H @ P @ H.T + R
            K = P @ H.T @ np.linalg.inv(S)
            nis = float(nu @ np.linalg.solve(S, nu))
            I_KH = np.eye(n) - K @ H
            dx, P_new, S_out, nis_out, ok = gated_kalman_update(P, H, R, nu, 1e9)
            assert ok and abs(nis_out - nis) <= 1e-10 * nis
            np.testing.assert_allclose(S_out, S, rtol=1e-13, atol=1e-13)
            np.testing.assert_allclose(dx, K @ nu, rtol=1e-8, atol=1e-12)
            np.testing.assert_allclose(P_new, I_KH @ P @ I_KH.T + K @ R @ K.T, rtol=1e-8, atol=1e-11)
            dx, P_same, _, _, ok = gated_kalman_update(P, H, R, nu, 0.5 * nis)
            assert not ok and dx.size == 0 and P_same is P
    _, _, _, nis_nan, ok = gated_kalman_update(np.eye(6), np.zeros((3, 6)), np.eye(3), np.full(3, np.nan), 1e9)
    assert np.isnan(nis_nan) and not ok
