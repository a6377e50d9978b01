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
