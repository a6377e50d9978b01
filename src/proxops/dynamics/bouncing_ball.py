"""Bouncing ball: the reference plant for events and jump maps (closed-form contacts).

State ``[h, v]`` (height m above the floor, vertical velocity m/s, up positive); control
``u`` (1,) an extra vertical acceleration (m/s^2, ZOH). Flow (exact): ``h(tau) = h + v tau +
(u - g) tau^2 / 2``, ``v(tau) = v + (u - g) tau``. Guard ``h = 0`` crossed downwards; jump map
``v+ = -e v-`` (coefficient of restitution ``e``), ``h+ = 0``. When the rebound speed is below
``rest_speed_mps`` the ball comes to rest on the floor (mode ``"rest"``; it leaves the floor
again only when ``u > g``) - without this the contacts accumulate (Zeno) at
``t_inf = t_1 + 2 e v_1 / (g (1 - e))``.

Closed forms from rest at height h0 (u = 0): first contact ``t_1 = sqrt(2 h0 / g)`` at impact
speed ``v_1 = sqrt(2 g h0)``; the k-th rebound speed is ``e^k v_1`` and contact k+1 follows
contact k after ``2 e^k v_1 / g``.

Guard location: :func:`proxops.dynamics.plant.locate_guard` (scan + bisection) on the exact
flow, to ``tol_s`` (default 1e-9 s); so each contact time is located within ``tol_s`` and the
post-impact speed within ``e g tol_s``.
"""

from __future__ import annotations

import numpy as np

from proxops.core.layout import Block, StateLayout
from proxops.dynamics.plant import PlantBase, locate_guard


class BouncingBall(PlantBase):
    """Plant (proxops.contracts.Plant) with events: floor contacts with restitution."""

    n_x, n_u = 2, 1
    layout = StateLayout(2, (Block("position", "position", 0, 1, ("h",)), Block("velocity", "velocity", 1, 2, ("v",))))
    has_events = True

    def __init__(self, h0_m: float, v0_mps: float = 0.0, g_mps2: float = 9.81, restitution: float = 0.8,
                 tol_s: float = 1e-9, rest_speed_mps: float = 1e-3):
        self.x0 = np.array([h0_m, v0_mps], dtype=float)
        self.g, self.e, self.tol_s, self.rest_speed = float(g_mps2), float(restitution), float(tol_s), float(rest_speed_mps)

    def initial_state(self) -> np.ndarray:
        return self.x0.copy()

    def relative_state(self, state: np.ndarray) -> np.ndarray:
        return np.asarray(state, dtype=float)

    def mode(self, state: np.ndarray) -> str:
        return "rest" if state[0] == 0.0 and state[1] == 0.0 else "flight"

    def _flow(self, x: np.ndarray, a: float, tau: float) -> np.ndarray:
        return np.array([x[0] + x[1] * tau + 0.5 * a * tau * tau, x[1] + a * tau])

    def propagate(self, t: float, state: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        return self.propagate_events(t, state, u, dt)[0]

    def propagate_events(self, t: float, state: np.ndarray, u: np.ndarray, dt: float):
        a = float(u[0]) - self.g
        x = np.asarray(state, dtype=float)
        events = []
        done = 0.0
        while done < dt:
            left = dt - done
            if x[0] <= 0.0 and x[1] <= 0.0 and a <= 0.0:  # resting on the floor
                return np.zeros(2), events
            hit = locate_guard(lambda x0, tau: self._flow(x0, a, tau), lambda y: y[0], x, left, self.tol_s) \
                if x[0] > 0.0 or x[1] > 0.0 else None
            if hit is None:
                return self._flow(x, a, left), events
            tau, x_hit = hit
            done += tau
            v_minus = x_hit[1]
            v_plus = -self.e * v_minus
            if v_plus < self.rest_speed:
                events.append((t + done, "contact", f"impact {v_minus:.6g} m/s, at rest"))
                x = np.zeros(2)
            else:
                events.append((t + done, "contact", f"impact {v_minus:.6g} m/s -> {v_plus:.6g} m/s"))
                x = np.array([0.0, v_plus])
        return x, events

    def apply_impulse(self, t: float, state: np.ndarray, dv: np.ndarray) -> np.ndarray:
        return np.array([state[0], state[1] + float(dv[0])])
