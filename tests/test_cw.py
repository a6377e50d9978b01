"""proxops.core.cw (CW STM and discretisations) against independent references:
numerical integration of the CW ODE, the matrix exponential, the semigroup property,
and the srf LVLH convention (textbook LVLH CW form and srf-hopping-mpc.md sec. 4.1)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from proxops.core.cw import (
    cw_discretize_impulsive,
    cw_discretize_zoh,
    cw_input_matrix_zoh,
    cw_matrices,
    cw_rhs,
    cw_stm,
    mean_motion,
)
from proxops.core.constants import R_EARTH
from proxops.frames.lvlh import HILL_TO_LVLH, HILL_TO_LVLH_STATE, hill_to_lvlh, lvlh_to_hill

N = mean_motion(R_EARTH + 500e3)  # ~1.1e-3 rad/s
PERIOD = 2 * np.pi / N
X0S = [
    np.array([100.0, -200.0, 50.0, 0.1, -0.05, 0.02]),
    np.array([0.0, 1000.0, 0.0, 0.0, 0.0, 0.0]),
    np.array([-30.0, 0.0, 10.0, 0.0, 2 * N * 30.0, -0.01]),
]


def integrate_cw(x0, tau, u=np.zeros(3)):
    sol = solve_ivp(lambda t, x: cw_rhs(t, x, u, N), (0, tau), x0, method="DOP853", rtol=1e-13, atol=1e-14)
    return sol.y[:, -1]


def rel_err(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("x0", X0S)
@pytest.mark.parametrize("tau", [10.0, 0.3 * PERIOD, 1.7 * PERIOD])
def test_stm_matches_numerical_integration(x0, tau):
    assert rel_err(cw_stm(N, tau) @ x0, integrate_cw(x0, tau)) < 1e-9


def test_stm_identity_and_semigroup_and_expm():
    assert np.array_equal(cw_stm(N, 0.0), np.eye(6))
    t1, t2 = 700.0, 2100.0
    assert np.allclose(cw_stm(N, t1 + t2), cw_stm(N, t2) @ cw_stm(N, t1), rtol=1e-12, atol=1e-12)
    A, _ = cw_matrices(N)
    for tau in (5.0, 0.5 * PERIOD, 2 * PERIOD):
        ref = expm(A * tau)
        assert np.linalg.norm(cw_stm(N, tau) - ref) / np.linalg.norm(ref) < 1e-10


@pytest.mark.parametrize("dt", [1.0, 60.0, 0.25 * PERIOD])
def test_zoh_matches_augmented_expm_and_integration(dt):
    A, B = cw_matrices(N)
    M = np.zeros((9, 9))
    M[:6, :6] = A
    M[:6, 6:] = B
    E = expm(M * dt)
    Ad, Bd = cw_discretize_zoh(N, dt)
    assert np.linalg.norm(Ad - E[:6, :6]) / np.linalg.norm(E[:6, :6]) < 1e-10
    assert np.linalg.norm(Bd - E[:6, 6:]) / np.linalg.norm(E[:6, 6:]) < 1e-10
    u = np.array([1e-3, -2e-3, 5e-4])
    x0 = X0S[0]
    assert rel_err(Ad @ x0 + Bd @ u, integrate_cw(x0, dt, u)) < 1e-9
    assert np.array_equal(cw_input_matrix_zoh(N, dt), Bd)


def test_impulsive_form():
    dt = 600.0
    dv = np.array([0.05, -0.02, 0.01])
    Ad, Bd = cw_discretize_impulsive(N, dt)
    x0 = X0S[0]
    bumped = x0 + np.concatenate([np.zeros(3), dv])
    assert rel_err(Ad @ x0 + Bd @ dv, integrate_cw(bumped, dt)) < 1e-9


def test_hill_and_srf_lvlh_describe_the_same_motion():
    """Textbook CW in the srf LVLH frame (x V-bar, y -normal, z R-bar), written here
    independently: xdd = 2n zd, ydd = -n^2 y, zdd = 3n^2 z - 2n xd."""
    A_l = np.zeros((6, 6))
    A_l[:3, 3:] = np.eye(3)
    A_l[3, 5] = 2 * N
    A_l[4, 1] = -N * N
    A_l[5, 2] = 3 * N * N
    A_l[5, 3] = -2 * N
    A_h, B_h = cw_matrices(N)
    T = HILL_TO_LVLH_STATE
    assert np.allclose(T @ A_h @ T.T, A_l, atol=1e-20)
    assert np.allclose(T @ B_h @ HILL_TO_LVLH.T, B_h, atol=0)  # B = [0; I] in both frames
    for x0 in X0S:
        for tau in (300.0, 0.8 * PERIOD):
            hill_then_map = hill_to_lvlh(cw_stm(N, tau) @ x0)
            lvlh_direct = expm(A_l * tau) @ hill_to_lvlh(x0)
            assert rel_err(hill_then_map, lvlh_direct) < 1e-10
            assert np.allclose(lvlh_to_hill(lvlh_direct), cw_stm(N, tau) @ x0, rtol=1e-9, atol=1e-9)


def test_srf_vbar_radial_hop_returns_with_perpendicular_velocity():
    """srf-hopping-mpc.md sec. 4.1, eqs. 5-7: from a V-bar hold point, a radial impulse vz0
    (LVLH) gives after half an orbit p_x = p_x0 + 4 vz0 / n, p_z = 0, v_x = 0, v_z = -vz0,
    and the chaser is back at the hold point after a full orbit."""
    px0, vz0 = -2000.0, 0.3
    x0_lvlh = np.array([px0, 0, 0, 0, 0, vz0])
    x_half = hill_to_lvlh(cw_stm(N, PERIOD / 2) @ lvlh_to_hill(x0_lvlh))
    expected = np.array([px0 + 2 * (1 - np.cos(np.pi)) / N * vz0, 0, 0, 0, 0, np.cos(np.pi) * vz0])
    assert np.allclose(x_half, expected, atol=1e-9)
    x_full = hill_to_lvlh(cw_stm(N, PERIOD) @ lvlh_to_hill(x0_lvlh))
    assert np.allclose(x_full, x0_lvlh, atol=1e-9)
