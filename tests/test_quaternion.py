"""Quaternion/DCM utilities: Hamilton algebra, rotation conventions, kinematics.

Independent references: the Hamilton unit relations, the Rodrigues formula
(hybrid-mpc-capture.md eq. 2), numerical integration of the DCM kinematics
R' = R w^x, and matrix composition."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from proxops.core import quaternion as Q
from proxops.errors import ProxopsInputError

RNG = np.random.default_rng(12)
I_, J_, K_, ONE = np.eye(4)


def random_quats(n):
    return Q.quat_normalize(RNG.normal(size=(n, 4)))


def rodrigues(axis, angle):
    """Active rotation matrix, hybrid-mpc-capture.md eq. 2."""
    n = np.asarray(axis) / np.linalg.norm(axis)
    nx = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    return np.eye(3) + np.sin(angle) * nx + (1 - np.cos(angle)) * nx @ nx


def test_hamilton_unit_relations():
    assert np.allclose(Q.quat_multiply(I_, J_), K_)
    assert np.allclose(Q.quat_multiply(J_, K_), I_)
    assert np.allclose(Q.quat_multiply(K_, I_), J_)
    for unit in (I_, J_, K_):
        assert np.allclose(Q.quat_multiply(unit, unit), -ONE)
    # i j k = -1
    assert np.allclose(Q.quat_multiply(Q.quat_multiply(I_, J_), K_), -ONE)


def test_rotation_of_x_about_z_by_90_deg_gives_y():
    q = Q.quat_from_axis_angle([0, 0, 1], np.pi / 2)
    assert np.allclose(Q.quat_rotate(q, [1, 0, 0]), [0, 1, 0], atol=1e-15)


@pytest.mark.parametrize("angle", [0.3, 1.7, np.pi - 1e-9, -2.5])
def test_dcm_matches_rodrigues_and_paper_eq4_is_transpose(angle):
    axis = np.array([0.3, -0.5, 0.8])
    q = Q.quat_from_axis_angle(axis, angle)
    R = Q.quat_to_dcm(q)
    assert np.allclose(R, rodrigues(axis, angle), atol=1e-14)
    # hybrid-mpc-capture.md eq. 4 (passive form) equals R^T
    qv, qw = q[:3], q[3]
    eq4 = (qw**2 - qv @ qv) * np.eye(3) + 2 * np.outer(qv, qv) - 2 * qw * Q.skew(qv)
    assert np.allclose(eq4, R.T, atol=1e-14)


def test_rotate_equals_sandwich_product_and_dcm():
    q = random_quats(20)
    v = RNG.normal(size=(20, 3))
    vq = np.concatenate([v, np.zeros((20, 1))], axis=1)
    sandwich = Q.quat_multiply(Q.quat_multiply(q, vq), Q.quat_conjugate(q))
    assert np.allclose(sandwich[:, :3], Q.quat_rotate(q, v), atol=1e-13)
    assert np.allclose(np.abs(sandwich[:, 3]), 0, atol=1e-13)
    assert np.allclose(np.einsum("nij,nj->ni", Q.quat_to_dcm(q), v), Q.quat_rotate(q, v), atol=1e-13)
    assert np.allclose(Q.quat_rotate_inverse(q, Q.quat_rotate(q, v)), v, atol=1e-13)


def test_composition_matches_matrix_product():
    p, q = random_quats(2)
    assert np.allclose(Q.quat_to_dcm(Q.quat_multiply(p, q)), Q.quat_to_dcm(p) @ Q.quat_to_dcm(q), atol=1e-14)


def test_dcm_is_proper_rotation():
    R = Q.quat_to_dcm(random_quats(10))
    for m in R:
        assert np.allclose(m @ m.T, np.eye(3), atol=1e-14)
        assert np.isclose(np.linalg.det(m), 1.0)


def test_dcm_to_quat_round_trip_including_half_turns():
    qs = list(random_quats(50))
    # rotations by pi (qw = 0) and near-identity exercise every Shepperd branch
    qs += [np.array([1.0, 0, 0, 0]), np.array([0, 1.0, 0, 0]), np.array([0, 0, 1.0, 0]), Q.IDENTITY]
    qs += [Q.quat_normalize([0.6, 0.8, 0.0, 1e-9])]
    for q in qs:
        back = Q.dcm_to_quat(Q.quat_to_dcm(q))
        assert back[3] >= 0
        assert min(np.linalg.norm(back - q), np.linalg.norm(back + q)) < 1e-12


def test_axis_angle_round_trip():
    axis = np.array([1.0, 2.0, -2.0]) / 3.0
    for angle in (1e-8, 0.4, 3.0):
        got_axis, got_angle = Q.quat_to_axis_angle(Q.quat_from_axis_angle(axis, angle))
        assert np.isclose(got_angle, angle, rtol=1e-12, atol=1e-15)
        assert np.allclose(got_axis, axis, atol=1e-8 if angle < 1e-6 else 1e-13)
    axis0, angle0 = Q.quat_to_axis_angle(Q.IDENTITY)
    assert angle0 == 0.0 and np.allclose(axis0, [1, 0, 0])
    # q and -q are the same rotation
    q = Q.quat_from_axis_angle(axis, 0.4)
    assert np.isclose(Q.quat_to_axis_angle(-q)[1], 0.4)
    assert np.isclose(Q.quat_angle_between(q, -q), 0.0, atol=1e-12)
    assert np.isclose(Q.quat_angle_between(Q.IDENTITY, q), 0.4)


def test_kinematics_matches_dcm_kinematics_and_closed_form():
    """qdot = 0.5 Omega(w) q integrated numerically == R' = R w^x integrated == quat_propagate."""
    w = np.array([0.02, -0.05, 0.03])
    q0 = Q.quat_normalize([0.1, 0.2, -0.3, 0.9])
    T = 100.0
    assert np.allclose(Q.omega_matrix(w) @ q0, 2 * Q.quat_kinematics(q0, w))
    sol_q = solve_ivp(lambda t, q: 0.5 * Q.omega_matrix(w) @ q, (0, T), q0, rtol=1e-12, atol=1e-14)
    R0 = Q.quat_to_dcm(q0)
    sol_R = solve_ivp(lambda t, r: (r.reshape(3, 3) @ Q.skew(w)).ravel(), (0, T), R0.ravel(), rtol=1e-12, atol=1e-14)
    qT = sol_q.y[:, -1]
    assert np.allclose(Q.quat_to_dcm(qT), sol_R.y[:, -1].reshape(3, 3), atol=1e-9)
    assert np.allclose(Q.quat_propagate(q0, w, T), qT, atol=1e-9)
    # zero rate keeps the attitude exactly
    assert np.allclose(Q.quat_propagate(q0, np.zeros(3), 10.0), q0)


def test_bad_input_raises_clear_error():
    with pytest.raises(ProxopsInputError, match="quaternion"):
        Q.quat_normalize([0, 0, 0, 0])
    with pytest.raises(ProxopsInputError, match="rotation axis"):
        Q.quat_from_axis_angle([0, 0, 0], 1.0)


def test_numba_kernels_equal_the_numpy_functions():
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = Q.quat_normalize(rng.standard_normal(4))
        w = rng.standard_normal(3)
        np.testing.assert_allclose(Q.dcm_kernel(q), Q.quat_to_dcm(q), atol=1e-15)
        np.testing.assert_allclose(Q.kinematics_kernel(q, w), Q.quat_kinematics(q, w), atol=1e-15)
        p = Q.quat_normalize(rng.standard_normal(4))
        np.testing.assert_allclose(Q.multiply_kernel(p, q), Q.quat_multiply(p, q), atol=1e-15)
