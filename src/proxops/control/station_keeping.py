"""Station keeping about a Hill-frame hold point: discrete LQR or PD (continuous thrust).

Both exercise the engine with the cheapest possible control law; the LQR gain comes
from the discrete algebraic Riccati equation of the exact CW ZOH model.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_discrete_are

from proxops.core.cw import cw_discretize_zoh, cw_rhs
from proxops.contracts import Command


class LqrStationKeeping:
    """u = -K (x - x_ref) with K from the DARE of the CW ZOH model (Q = diag(q_pos, q_vel), R = r I)."""

    def __init__(self, n: float, dt: float, hold_position_m, q_pos: float = 1.0, q_vel: float = 100.0, r: float = 1e6):
        self.dt = float(dt)
        self.x_ref = np.concatenate([np.asarray(hold_position_m, float), np.zeros(3)])
        A, B = cw_discretize_zoh(n, dt)
        Q = np.diag([q_pos] * 3 + [q_vel] * 3)
        R = r * np.eye(3)
        P = solve_discrete_are(A, B, Q, R)
        self.K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)

    def reset(self, t0: float, x0: np.ndarray) -> None:
        pass

    def step(self, t: float, x_est: np.ndarray) -> Command:
        return Command(u=-self.K @ (x_est - self.x_ref), mode="hold")


class PdStationKeeping:
    """u = -kp (r - r_ref) - kd v, plus CW gravity-gradient cancellation (m/s^2)."""

    def __init__(self, n: float, dt: float, hold_position_m, kp: float = 1e-3, kd: float = 6e-2):
        self.dt, self.n, self.kp, self.kd = float(dt), n, kp, kd
        self.r_ref = np.asarray(hold_position_m, float)

    def reset(self, t0: float, x0: np.ndarray) -> None:
        pass

    def step(self, t: float, x_est: np.ndarray) -> Command:
        r, v = x_est[:3], x_est[3:6]
        cw_accel = cw_rhs(t, x_est, np.zeros(3), self.n)[3:6]  # unforced CW acceleration
        return Command(u=-self.kp * (r - self.r_ref) - self.kd * v - cw_accel, mode="hold")
