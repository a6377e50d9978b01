"""Spherical keep-out zone (KOZ) with its control barrier function (Silva et al. 2026 eqs. 26-28).

Generic (any radius and centre, any frame whose first six state entries are
``[p, v]``; Hill/RTN in proxops)::

    h(x)     = |p - c|^2 - r^2                    (eq. 26, > 0 outside the sphere)
    hdot(x)  = 2 (p - c) . v                      (eq. 27)
    g(x)     = hdot(x) + alpha h(x) >= 0          (eq. 28, the CBF condition)

Solver rows (all linear in the state, for QP/LP-based MPCs):

* :meth:`KeepOutSphere.halfspace` -- supporting half-space at a reference point:
  ``n . (p - c) >= r`` with ``n = (p_ref - c) / |p_ref - c|``. Every point of the
  half-space is outside the sphere (sound inner approximation of the non-convex
  outside-of-sphere set).
* :meth:`KeepOutSphere.cbf_linearization` -- first-order expansion of ``g`` about a
  reference state: ``g(x) ~ g(x_ref) + grad g(x_ref) . (x - x_ref)``. ``g`` is an
  indefinite quadratic, so this row is NOT conservative on its own; callers must check
  the true ``g`` (:meth:`cbf_value`) on the solution and re-linearise or reject
  (proxops.control.srf_mpc does both).

Simulation check: :meth:`violation` (engine constraint hook) returns
``r - |p - c|`` in metres (> 0 means inside the KOZ).
"""

from __future__ import annotations

import math

import numpy as np

from proxops.errors import input_error


class KeepOutSphere:
    """Sphere of ``radius_m`` around ``center_m`` (same frame as the states passed in)."""

    def __init__(self, radius_m: float, center_m=(0.0, 0.0, 0.0), name: str = "keep_out"):
        radius_m = float(radius_m)
        if not (math.isfinite(radius_m) and radius_m > 0.0):
            raise input_error("keep_out radius_m", radius_m, "must be finite and > 0", "m")
        center = np.asarray(center_m, dtype=float)
        if center.shape != (3,) or not np.all(np.isfinite(center)):
            raise input_error("keep_out center_m", np.asarray(center_m).tolist(), "must be 3 finite numbers", "m")
        self.radius_m = radius_m
        self.center_m = center
        self._center_xyz = tuple(center.tolist())  # plain floats for the per-step violation
        self.name = name

    # ------------------------------------------------------------------ geometry
    def distance_to_surface(self, positions) -> np.ndarray:
        """|p - c| - r for positions (..., 3) (m; > 0 outside)."""
        p = np.asarray(positions, dtype=float)
        return np.linalg.norm(p - self.center_m, axis=-1) - self.radius_m

    def contains(self, position) -> bool:
        """True when ``position`` (3,) is inside or on the sphere."""
        return bool(self.distance_to_surface(position) <= 0.0)

    def violation(self, t: float, x) -> float:
        """Engine hook: r - |p - c| (m), > 0 inside the KOZ."""
        cx, cy, cz = self._center_xyz
        dx, dy, dz = float(x[0]) - cx, float(x[1]) - cy, float(x[2]) - cz
        # = -distance_to_surface(x[:3]): the same sum of squares (in order) and sqrt, on floats
        return -(math.sqrt(dx * dx + dy * dy + dz * dz) - self.radius_m)

    def violations(self, t, states) -> np.ndarray:
        """Vectorised :meth:`violation` over samples: ``r - |p - c|`` (m) for states (n, >= 3) at
        times ``t`` (n,) (the engine screens a coast with it; equal to :meth:`violation` up to
        rounding)."""
        return -self.distance_to_surface(np.asarray(states, dtype=float)[:, :3])

    # ------------------------------------------------------------------ CBF (eqs. 26-28)
    def h(self, states) -> np.ndarray:
        """Eq. (26) for states (..., >= 3) (m^2)."""
        x = np.asarray(states, dtype=float)
        d = x[..., :3] - self.center_m
        return np.sum(d * d, axis=-1) - self.radius_m**2

    def h_dot(self, states) -> np.ndarray:
        """Eq. (27) for states (..., 6) (m^2/s)."""
        x = np.asarray(states, dtype=float)
        return 2.0 * np.sum((x[..., :3] - self.center_m) * x[..., 3:6], axis=-1)

    def cbf_value(self, states, alpha_per_s: float) -> np.ndarray:
        """Eq. (28) left side g = hdot + alpha h (m^2/s); >= 0 means the condition holds."""
        return self.h_dot(states) + alpha_per_s * self.h(states)

    def cbf_linearization(self, x_ref, alpha_per_s: float) -> tuple[np.ndarray, np.ndarray]:
        """``(grad, g_ref)`` with ``g(x) ~ g_ref + grad . (x - x_ref)`` for states (..., 6).

        grad = [2 v + 2 alpha (p - c), 2 (p - c)] (shape (..., 6)). Not conservative (see module doc)."""
        x = np.asarray(x_ref, dtype=float)
        d = x[..., :3] - self.center_m
        grad = np.concatenate([2.0 * x[..., 3:6] + 2.0 * alpha_per_s * d, 2.0 * d], axis=-1)
        return grad, self.cbf_value(x, alpha_per_s)

    def halfspace(self, p_ref) -> tuple[np.ndarray, np.ndarray]:
        """Supporting half-spaces ``n . p >= b`` at reference positions (..., 3): ``(n, b)``.

        ``n`` is the unit vector from the centre towards ``p_ref``; b = r + n . c. A reference
        at the centre has no direction: ``ProxopsInputError``."""
        p = np.asarray(p_ref, dtype=float)
        d = p - self.center_m
        norm = np.linalg.norm(d, axis=-1, keepdims=True)
        if np.any(norm <= 1e-12 * max(1.0, self.radius_m)):
            raise input_error("keep_out reference position", p.tolist(), "must differ from the KOZ centre", "m")
        n = d / norm
        return n, self.radius_m + n @ self.center_m
