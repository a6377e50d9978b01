"""Thruster-plume constraint of a final approach (Wijayatunga et al. eqs. 19d, 21-22): the one
place where eq. 22's rows are built (the planner's CP2, :mod:`proxops.guidance.cortex.phases`, and the
tracking guidance CP_g, :mod:`proxops.control.cortex_tracking`, both take them from here).

Plume impingement (eq. 19d with the impulse of eq. 21)::

    h(r, dv) = dv . r - ||dv|| ||r|| cos(alpha_p) <= 0

i.e. the angle between the impulse (thrust acceleration) and the position of the
servicer relative to the target must be at least alpha_p: the exhaust, which leaves
opposite to the thrust, must not point within alpha_p of the target. The printed
eq. (21) has ``||v_k||`` (the velocity) in the second term while (19d) has ``||a||``;
only the impulse form is consistent with (19d) (h is then positively homogeneous
in dv, zero for no thrust), so that form is implemented.

``h`` is non-convex (bilinear plus a concave term). :meth:`PlumeConstraint.linearization`
gives the first-order row of eq. (22) about a reference ``(r_m, dv_m)``:
``a . r + g . dv <= b``. For ``dv_m = 0`` (no thrust at the reference, where h is
not differentiable in dv) the subgradient with ``u = -r_m/|r_m|`` is used: the row
becomes ``dv . r_m <= 0`` (no thrust component away from the target), a convex
subset of the allowed set for ``r = r_m``; a reference inside the forbidden cone is
moved to the cone's nearest generatrix first (tangent-plane row). The row is not conservative in ``r``;
callers check the true ``h`` on the solution (:meth:`PlumeConstraint.margin_rad`).
:meth:`PlumeConstraint.rows` gives the rows in a solver's scaled units, each divided by its
largest coefficient.
"""

from __future__ import annotations

import math

import numpy as np

from proxops.constraints.approach_cone import half_angle
from proxops.errors import input_error


class PlumeConstraint:
    """Keep the thrust at least ``half_angle_rad`` away from the target direction (eq. 19d)."""

    def __init__(self, half_angle_rad: float, name: str = "plume"):
        self.half_angle_rad = half_angle(half_angle_rad, "plume half-angle")
        self.cos = math.cos(self.half_angle_rad)
        self.name = name

    def h(self, r, dv) -> np.ndarray:
        """Eq. (21), impulse form: dv . r - ||dv|| ||r|| cos(alpha_p) (m^2/s; <= 0 allowed)."""
        r = np.asarray(r, dtype=float)
        dv = np.asarray(dv, dtype=float)
        return np.sum(dv * r, axis=-1) - np.linalg.norm(dv, axis=-1) * np.linalg.norm(r, axis=-1) * self.cos

    def angle_rad(self, r, dv) -> np.ndarray:
        """Angle between dv and r (rad), nan where either is zero."""
        r = np.asarray(r, dtype=float)
        dv = np.asarray(dv, dtype=float)
        nr, nd = np.linalg.norm(r, axis=-1), np.linalg.norm(dv, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            c = np.sum(dv * r, axis=-1) / (nr * nd)
        return np.arccos(np.clip(c, -1.0, 1.0))

    def margin_rad(self, r, dv, dv_min_mps: float = 0.0) -> np.ndarray:
        """angle(dv, r) - alpha_p (rad, >= 0 allowed); +inf where ||dv|| <= dv_min_mps (no thrust)."""
        ang = self.angle_rad(r, dv) - self.half_angle_rad
        small = np.linalg.norm(np.asarray(dv, dtype=float), axis=-1) <= dv_min_mps
        return np.where(small | np.isnan(ang), np.inf, ang)

    def violation(self, t: float, x, u) -> float:
        """Check hook for a thrusting state: alpha_p - angle(u, r) (rad), > 0 when the plume hits."""
        m = self.margin_rad(np.asarray(x, dtype=float)[:3], np.asarray(u, dtype=float)[:3])
        return float(-m) if np.isfinite(m) else -math.inf

    def linearization(self, r_ref, dv_ref, dv_zero_mps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Eq. (22) rows ``a . r + g . dv <= b`` about references (..., 3).

        h is positively homogeneous of degree one in r and in dv, so h(y_m) + grad h (y - y_m)
        = a . r + g . dv - h_m with a = dv_m - c |dv_m| r_m/|r_m|, g = r_m - c |r_m| dv_m/|dv_m|
        and h_m = g . dv_m. A reference inside the forbidden cone (h_m > 0) is first moved to the
        nearest generatrix of the cone (same |dv_m|, in the plane of r_m and dv_m), where h = 0:
        the row is then the tangent plane of the cone, which admits that generatrix instead of
        cutting away every direction with a component along r (the plain gradient at dv_m ~ r
        gives dv . r <= 0: no braking at all). References with ``|dv_m| <= dv_zero_mps`` use
        u = -r_m/|r_m|: a = 0, g = (1 + c) r_m, b = 0. For a fixed r every row is a subset
        of the allowed set (u . dv <= ||dv||)."""
        r = np.atleast_2d(np.asarray(r_ref, dtype=float))
        dv = np.atleast_2d(np.asarray(dv_ref, dtype=float))
        nr = np.linalg.norm(r, axis=-1, keepdims=True)
        nd = np.linalg.norm(dv, axis=-1, keepdims=True)
        if np.any(nr <= 1e-12):
            raise input_error("plume reference position", r.tolist(), "must differ from the target centre", "m")
        zero = nd[:, 0] <= dv_zero_mps
        rhat = r / nr
        u = dv / np.where(nd > 0, nd, 1.0)
        # a reference inside the forbidden cone is moved to the nearest cone generatrix w (same
        # plane through r), so the row is the tangent plane there and still admits w
        cos_u = np.sum(u * rhat, axis=-1)
        inside = ~zero & (cos_u > self.cos)
        if inside.any():
            perp = u - cos_u[:, None] * rhat
            pn = np.linalg.norm(perp, axis=-1, keepdims=True)
            fallback = np.cross(rhat, np.array([0.0, 0.0, 1.0]))  # u along r: pick a perpendicular
            fallback = np.where(np.linalg.norm(fallback, axis=-1, keepdims=True) < 1e-9,
                                np.cross(rhat, np.array([1.0, 0.0, 0.0])), fallback)
            perp = np.where(pn > 1e-9, perp / np.where(pn > 0, pn, 1.0),
                            fallback / np.linalg.norm(fallback, axis=-1, keepdims=True))
            w = self.cos * rhat + math.sin(self.half_angle_rad) * perp
            u = np.where(inside[:, None], w, u)
            dv = np.where(inside[:, None], nd * w, dv)
        u = np.where(zero[:, None], -rhat, u)
        a = np.where(zero[:, None], 0.0, dv - self.cos * nd * rhat)
        g = r - self.cos * nr * u
        b = np.where(zero, 0.0, np.sum(g * dv, axis=-1))
        return a, g, b

    def rows(self, r_ref, dv_ref, dv_zero_mps: float, r_unit: float | None, dv_unit: float = 1.0):
        """Eq. (22) rows about (r_ref, dv_ref) in solver units (:func:`scaled_rows`)."""
        a, g, b = self.linearization(r_ref, dv_ref, dv_zero_mps)
        return scaled_rows(a, g, b, r_unit, dv_unit)


def scaled_rows(a, g, b, r_unit: float | None, dv_unit: float = 1.0):
    """Rows ``a . r + g . dv <= b`` (physical units, (n, 3) each) in solver units r = r_unit r',
    dv = dv_unit dv', each row divided by its largest coefficient: (a', g', b'). ``r_unit`` None: the
    dv part only (r frozen at the linearisation point; a' and b' None), as the tracking guidance uses it."""
    g_s = np.asarray(g, float) * dv_unit
    if r_unit is None:
        return None, g_s / np.maximum(np.abs(g_s).max(axis=1), 1e-300)[:, None], None
    a_s = np.asarray(a, float) * r_unit
    scale = np.maximum(np.maximum(np.abs(a_s).max(axis=1), np.abs(g_s).max(axis=1)), 1e-300)
    return a_s / scale[:, None], g_s / scale[:, None], np.asarray(b, float) / scale
