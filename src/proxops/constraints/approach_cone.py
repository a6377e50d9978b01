"""Approach cone of a final approach (Wijayatunga et al. eqs. 19f/20f).

Generic over the frame (Hill/RTN in proxops); positions are relative to the target.

Approach cone (eq. 20f), a second-order cone in the position::

    ||r|| cos(alpha_c) <= e . r          (e: unit docking axis)

:meth:`ApproachCone.soc` gives it as solver rows ``||F z + g|| <= c'z + d`` for a
position that is a slice of the decision vector; :meth:`ApproachCone.violation` is
the engine hook ``||r|| cos(alpha_c) - e . r`` (m, > 0 outside the cone). The plume
constraint of the same approach is :mod:`proxops.constraints.plume`.
"""

from __future__ import annotations

import math

import numpy as np

from proxops.errors import input_error


def _unit_axis(axis, name: str = "approach axis") -> np.ndarray:
    e = np.asarray(axis, dtype=float)
    if e.shape != (3,) or not np.all(np.isfinite(e)):
        raise input_error(name, np.asarray(axis).tolist(), "must be 3 finite numbers")
    norm = float(np.linalg.norm(e))
    if norm < 1e-12:
        raise input_error(name, e.tolist(), "must have a non-zero length (it is normalised)")
    return e / norm


def half_angle(value: float, name: str) -> float:
    """A half-angle in (0, 90 deg) (rad), else the one-line input error naming ``name``."""
    value = float(value)
    if not (math.isfinite(value) and 0.0 < value < 0.5 * math.pi):
        raise input_error(name, math.degrees(value) if math.isfinite(value) else value,
                          "must satisfy 0 < angle < 90", "deg")
    return value


class ApproachCone:
    """Cone of half-angle ``half_angle_rad`` about the unit ``axis`` with its apex at the target."""

    def __init__(self, axis, half_angle_rad: float, name: str = "approach_cone"):
        self.axis = _unit_axis(axis)
        self.half_angle_rad = half_angle(half_angle_rad, "approach cone half-angle")
        self.name = name

    def margin(self, positions) -> np.ndarray:
        """e . r - ||r|| cos(alpha) for positions (..., 3) (m; >= 0 inside the cone)."""
        r = np.asarray(positions, dtype=float)
        return r @ self.axis - np.linalg.norm(r, axis=-1) * math.cos(self.half_angle_rad)

    def contains(self, position, tol_m: float = 0.0) -> bool:
        return bool(self.margin(position) >= -tol_m)

    def violation(self, t: float, x) -> float:
        """Engine hook: ||r|| cos(alpha) - e . r (m), > 0 outside the cone."""
        return float(-self.margin(np.asarray(x, dtype=float)[:3]))

    def soc(self, n_var: int, pos_index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Eq. (20f) as ``||F z + g|| <= c'z + d`` for the position ``z[pos_index:pos_index+3]``:
        ``||r|| <= (e . r) / cos(alpha)`` (returns F (3, n_var), g, c, d)."""
        F = np.zeros((3, n_var))
        F[:, pos_index : pos_index + 3] = np.eye(3)
        c = np.zeros(n_var)
        c[pos_index : pos_index + 3] = self.axis / math.cos(self.half_angle_rad)
        return F, np.zeros(3), c, 0.0
