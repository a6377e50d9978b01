"""Table 1 of Wijayatunga et al. (§3.3): the abort and recompute conditions of the CORTEX loop, as a pure
function of (phase, true position, reference position, commanded impulse): abort conditions first (true KOS
in h1/1/h2, true plume and true cone in 2), then recompute conditions (tracking error > eps_r of the phase,
buffered KOS, buffered cone, buffered plume). It knows nothing about solvers or the engine. The printed plume
rows of Table 1 use cos(alpha_c) (the cone angle); the plume is defined by alpha_p (eq. 19d, Fig. 4), so
alpha_p / alpha_p_bar are used.

Choices the paper leaves open (documented keys of the scenario):

* plume: evaluated on the impulse about to be fired at the true position (before it is fired, so an
  aborting impulse is not executed); impulses below ``plume_min_dv_mps`` do not count as thrust;
* buffered KOS and cone: the reference lies ON both buffered boundaries (the second hold station-keeps at
  x_f1 = rho_bar e, Table 2; CP2 nodes touch the alpha_c_bar cone), so any tracking error, however small,
  would trip them: they fire only beyond a tolerance (range below rho_bar - ``buffer_tol_m``; more than
  ``cone_buffer_tol_deg`` off the axis beyond alpha_c_bar, an angle so that it stays well inside the true
  cone near the apex). Measured: without it the error-free nominal run recomputes at 474 s (0.1 mm outside
  the buffered cone).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxops.constraints.approach_cone import ApproachCone
from proxops.constraints.plume import PlumeConstraint
from proxops.errors import input_error

HOLD_PHASES = ("hold1", "flyaround", "hold2")


@dataclass
class CortexTriggers:
    """Abort and recompute conditions of Table 1 (radii m, angles rad, per-phase eps_r m)."""

    r_kos_m: float
    rho_bar_m: float
    cone: ApproachCone  # true cone, alpha_c
    cone_bar: ApproachCone  # buffered cone, alpha_c_bar
    plume: PlumeConstraint  # alpha_p
    plume_bar: PlumeConstraint  # alpha_p_bar
    eps_r_m: dict  # phase -> threshold
    plume_min_dv_mps: float = 1e-4
    buffer_tol_m: float = 0.1
    cone_buffer_tol_rad: float = math.radians(1.0)

    def __post_init__(self):
        for phase, v in self.eps_r_m.items():
            if not (math.isfinite(v) and v > 0):
                raise input_error(f"guidance.recompute_{phase}_m", v, "must be a finite number > 0 (eps_r of Table 1)", "m")
        self._axis = _floats(self.cone_bar.axis)
        self._cone_axis = _floats(self.cone.axis)
        self._cos_cone = math.cos(self.cone.half_angle_rad)

    def buffered_kos(self, phase: str, r) -> bool:
        """Buffered-KOS recompute condition (holds and fly-around): range below rho_bar - buffer_tol."""
        return phase in HOLD_PHASES and _norm(_floats(r)) < self.rho_bar_m - self.buffer_tol_m

    def off_axis_rad(self, r) -> float:
        """Angle between r and the docking axis (rad)."""
        r = _floats(r)
        rng = max(_norm(r), 1e-12)
        return math.acos(max(-1.0, min(1.0, _dot(r, self._axis) / rng)))

    def buffered_cone(self, phase: str, r) -> bool:
        """Buffered-cone recompute condition (approach): more than alpha_c_bar + cone_buffer_tol off the axis."""
        return phase == "approach" and self.off_axis_rad(r) > self.cone_bar.half_angle_rad + self.cone_buffer_tol_rad

    def check(self, phase: str, r, r_ref, dv, suspended=(), recompute: bool = True) -> tuple[str, str] | None:
        """First condition that holds: ("abort" | "recompute", reason), or None. ``suspended``: names of
        buffered conditions ("C_KOS_bar", "C_cone_bar") not evaluated (see CortexSupervisor.suspended);
        ``recompute=False``: the abort conditions only. Runs at every impulse: 3-vectors in plain floats
        (the angles as :meth:`PlumeConstraint.angle_rad` and :meth:`ApproachCone.margin` define them)."""
        r = _floats(r)
        r0, r1, r2 = r
        rng = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)  # _norm(r), inline (this runs at every impulse)
        if dv is None:
            thrusting = False
        else:
            d0, d1, d2 = _floats(dv)
            nd = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            thrusting = nd > self.plume_min_dv_mps
        if phase in HOLD_PHASES and rng < self.r_kos_m:
            return "abort", f"C_KOS: range {rng:.3f} m < r_KOS {self.r_kos_m:g} m"
        if phase == "approach":
            ang = math.nan  # angle between dv and r (rad); NaN when not thrusting or either is zero
            if thrusting and rng != 0.0 and nd != 0.0:
                ang = math.acos(max(-1.0, min(1.0, (d0 * r0 + d1 * r1 + d2 * r2) / (rng * nd))))
            if ang < self.plume.half_angle_rad:
                return "abort", f"C_plume: thrust {math.degrees(ang):.2f} deg from the target direction < alpha_p"
            a0, a1, a2 = self._cone_axis
            outside = rng * self._cos_cone - (r0 * a0 + r1 * a1 + r2 * a2)
            if outside > 0:
                return "abort", f"C_cone: outside the approach cone by {outside:.4f} m"
        if not recompute:
            return None
        rr = _floats(r_ref)
        err = math.sqrt((r[0] - rr[0]) ** 2 + (r[1] - rr[1]) ** 2 + (r[2] - rr[2]) ** 2)
        eps = self.eps_r_m.get(phase, math.inf)
        if err > eps:
            return "recompute", f"C_trk: tracking error {err:.3f} m > eps_r {eps:g} m ({phase})"
        if "C_KOS_bar" not in suspended and self.buffered_kos(phase, r):
            return "recompute", f"C_KOS_bar: range {rng:.3f} m < rho_bar {self.rho_bar_m:g} m"
        if phase == "approach":
            if "C_cone_bar" not in suspended and self.buffered_cone(phase, r):
                return "recompute", (f"C_cone_bar: {math.degrees(self.off_axis_rad(r)):.2f} deg off the axis > "
                                     f"alpha_c_bar {math.degrees(self.cone_bar.half_angle_rad):g} deg")
            if ang < self.plume_bar.half_angle_rad:
                return "recompute", f"C_plume_bar: thrust {math.degrees(ang):.2f} deg from the target direction < alpha_p_bar"
        return None


def _floats(a) -> list:
    """A 3-vector as Python floats (one conversion, then scalar math at a fraction of numpy's call cost); a
    list is taken as floats already (``ndarray.tolist()``'s)."""
    if a.__class__ is list:
        return a[:3]
    return a.tolist()[:3] if isinstance(a, np.ndarray) else [float(v) for v in a[:3]]


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _norm(a) -> float:
    return math.sqrt(_dot(a, a))
