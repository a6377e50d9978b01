"""Clohessy-Wiltshire (Hill) relative dynamics about a circular orbit.

Frame: Hill/RTN, x radial out, y along-track, z orbit normal; state
``[x, y, z, vx, vy, vz]`` (m, m/s); control is an acceleration (m/s^2) or an
impulsive velocity change (m/s).

    xdd = 3 n^2 x + 2 n yd + ax
    ydd = -2 n xd + ay
    zdd = -n^2 z + az
"""

from __future__ import annotations

import numpy as np

from proxops.core.constants import MU_EARTH


def mean_motion(sma_m: float, mu: float = MU_EARTH) -> float:
    """Mean motion n = sqrt(mu / a^3) (rad/s)."""
    return float(np.sqrt(mu / sma_m**3))


def cw_matrices(n: float) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time CW model (A, B) with xdot = A x + B a."""
    A = np.zeros((6, 6))
    A[0:3, 3:6] = np.eye(3)
    A[3, 0] = 3.0 * n * n
    A[3, 4] = 2.0 * n
    A[4, 3] = -2.0 * n
    A[5, 2] = -n * n
    B = np.zeros((6, 3))
    B[3:6, :] = np.eye(3)
    return A, B


def cw_stm(n: float, tau: float) -> np.ndarray:
    """Closed-form CW state-transition matrix Phi(tau) (Vallado eq. 6-66, Hill frame)."""
    s, c = np.sin(n * tau), np.cos(n * tau)
    return np.array(
        [
            [4 - 3 * c, 0, 0, s / n, 2 * (1 - c) / n, 0],
            [6 * (s - n * tau), 1, 0, -2 * (1 - c) / n, (4 * s - 3 * n * tau) / n, 0],
            [0, 0, c, 0, 0, s / n],
            [3 * n * s, 0, 0, c, 2 * s, 0],
            [-6 * n * (1 - c), 0, 0, -2 * s, 4 * c - 3, 0],
            [0, 0, -n * s, 0, 0, c],
        ]
    )


def cw_input_matrix_zoh(n: float, dt: float) -> np.ndarray:
    """Exact ZOH input matrix B_d = int_0^dt Phi(s) ds B for a constant acceleration (closed form)."""
    s, c = np.sin(n * dt), np.cos(n * dt)
    n2 = n * n
    return np.array(
        [
            [(1 - c) / n2, 2 * (n * dt - s) / n2, 0],
            [-2 * (n * dt - s) / n2, (4 * (1 - c) - 1.5 * n2 * dt * dt) / n2, 0],
            [0, 0, (1 - c) / n2],
            [s / n, 2 * (1 - c) / n, 0],
            [-2 * (1 - c) / n, (4 * s - 3 * n * dt) / n, 0],
            [0, 0, s / n],
        ]
    )


def cw_discretize_zoh(n: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation (A_d, B_d) for zero-order-hold acceleration over ``dt`` s."""
    return cw_stm(n, dt), cw_input_matrix_zoh(n, dt)


def cw_discretize_impulsive(n: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Discretisation for an impulse at the start of the step: x+ = Phi(dt) (x + [0; dv]).

    Returns (A_d, B_d) = (Phi, Phi[:, 3:6])."""
    phi = cw_stm(n, dt)
    return phi, phi[:, 3:6].copy()


def cw_rhs(t: float, x: np.ndarray, u: np.ndarray, n: float) -> np.ndarray:
    """CW right-hand side f(t, x, u, n) (m/s, m/s^2)."""
    return np.array(
        [
            x[3],
            x[4],
            x[5],
            3 * n * n * x[0] + 2 * n * x[4] + u[0],
            -2 * n * x[3] + u[1],
            -n * n * x[2] + u[2],
        ]
    )
