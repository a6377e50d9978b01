"""The reference of the CORTEX tracking loop (Wijayatunga et al. §3.2-3.4): a time line of segments.

Segments hold1 -> flyaround -> hold2 -> approach of a plan (:func:`timeline_from_plan`), or one
transfer after a regeneration (:func:`phase_timeline`) or an abort (:func:`retreat_timeline`, onto the
§3.4 safe circumnavigation orbit, :func:`safe_orbit_state`). The state at any time is exact under the
CW model (node state + impulse, propagated by the STM; the paper's ``interp`` of the node states is
replaced by this, which has no interpolation error between nodes). Times absolute (s), Hill frame.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass, field

import numpy as np

from proxops.core.cw import cw_stm
from proxops.errors import input_error


@dataclass
class Segment:
    """One phase of the reference: ``x_hold`` (hold) or node times/states/impulses (transfer), times absolute."""

    phase: str
    t0: float
    t1: float
    x_hold: np.ndarray | None = None
    t: np.ndarray | None = None
    x: np.ndarray | None = None
    dv: np.ndarray | None = None
    _stms: dict = field(default_factory=dict, repr=False)  # Phi(tau) by tau: the loop asks for the same offsets

    def __post_init__(self):
        if self.x_hold is None:  # node times as floats and node states after their impulses, once
            self._t = np.asarray(self.t, float).tolist()
            self._xp = np.array(self.x, float)
            self._xp[:, 3:] += np.asarray(self.dv, float)[: len(self._xp)]

    def impulse(self, t: float) -> np.ndarray:
        """Reference thrust direction at time t for the plume half-spaces of CP_g. CP_g targets the
        reference after each node's impulse (:meth:`state`), so the impulses fired in (t_k, t_k+1]
        deliver the impulse of node k+1 (the terminal burn in the last interval): that one, or the
        impulse of node k when node k+1 has none. Zero in holds."""
        if self.x_hold is not None:
            return np.zeros(3)
        k = min(max(0, bisect_right(self._t, t + 1e-9) - 1), len(self._t) - 2)  # (np.searchsorted's index)
        d = np.array(self.dv[k + 1], float)
        if float(np.linalg.norm(d)) < 1e-9:
            d = np.array(self.dv[k], float)
        return d

    def state(self, n: float, t: float) -> np.ndarray:
        """Reference state at t, after the impulse of the node at or before t (after the terminal
        burn at and after t_end): exact CW propagation of the plan between nodes."""
        if self.x_hold is not None:
            return self.x_hold.copy()
        if t >= self._t[-1] - 1e-9:
            return self._xp[-1].copy()  # after the terminal burn: the phase's target state
        k = max(0, bisect_right(self._t, t + 1e-9) - 1)
        tau = t - self._t[k]
        phi = self._stms.get(tau)
        if phi is None:
            phi = cw_stm(n, tau)
            if len(self._stms) < 4096:
                self._stms[tau] = phi
        return phi @ self._xp[k]


class Timeline:
    """Reference segments in time order (absolute times, s)."""

    def __init__(self, n_rad_s: float, segments: list[Segment]):
        self.n = n_rad_s
        self.segments = [s for s in segments if s.t1 > s.t0 + 1e-9]
        self.t_end = self.segments[-1].t1  # (s; the segments are not changed after construction)

    def segment(self, t: float) -> Segment:
        for s in self.segments:
            if t < s.t1 - 1e-9:
                return s
        return self.segments[-1]

    def state(self, t: float) -> np.ndarray:
        return self.segment(t).state(self.n, min(t, self.t_end))

    @property
    def final_state(self) -> np.ndarray:
        return self.segments[-1].state(self.n, self.t_end)


def _grid(t: float, step: float) -> float:
    """Round a duration up to the impulse grid (holds from the sunlight profile are arbitrary)."""
    return math.ceil(t / step - 1e-9) * step


def timeline_from_plan(plan, n: float, t_start: float, step: float) -> Timeline:
    """hold1 -> flyaround -> hold2 -> approach of a :class:`CortexPlan`, starting at ``t_start``."""
    h1 = _grid(plan.hold1_s, step)
    h2 = _grid(plan.hold2_s, step)
    c1, c2 = plan.cp1, plan.cp2
    t = t_start
    segs = [Segment("hold1", t, t + h1, x_hold=np.asarray(c1.x[0], float))]
    t += h1
    segs.append(Segment("flyaround", t, t + plan.tau1_s, t=t + c1.t, x=c1.x, dv=c1.dv))
    t += plan.tau1_s
    x_f1 = segs[-1].state(n, t)
    segs.append(Segment("hold2", t, t + h2, x_hold=x_f1))
    t += h2
    segs.append(Segment("approach", t, t + plan.tau2_s, t=t + c2.t, x=c2.x, dv=c2.dv))
    return Timeline(n, segs)


def phase_timeline(phase: str, res, n: float, t_start: float) -> Timeline:
    """One transfer segment (a regenerated approach or the retreat) from a PhaseResult."""
    return Timeline(n, [Segment(phase, t_start, t_start + float(res.t[-1]), t=t_start + res.t, x=res.x, dv=res.dv)])


def retreat_timeline(res, n: float, t_start: float, x_safe, dt_g_s: float, insertion_intervals: int) -> Timeline:
    """The retreat transfer, then ``insertion_intervals`` guidance intervals tracking the safe orbit's
    own CW motion: the transfer ends with a terminal burn of up to a_bar dt_CP1 (one impulse of the
    plan), which CP_g spreads over 2 s impulses; the extra intervals let it settle on the orbit
    (measured: without them the insertion misses the safe orbit by ~2.5 cm/s)."""
    segs = phase_timeline("retreat", res, n, t_start).segments
    if insertion_intervals > 0:
        t1 = segs[-1].t1
        tt = dt_g_s * np.arange(insertion_intervals + 1)
        xs = np.array([cw_stm(n, float(s)) @ np.asarray(x_safe, float) for s in tt])
        segs.append(Segment("retreat", t1, t1 + tt[-1], t=t1 + tt, x=xs, dv=np.zeros((len(tt), 3))))
    return Timeline(n, segs)


def extend_on_safe_orbit(tl: Timeline, n: float, dt_g_s: float) -> Timeline:
    """The timeline plus one guidance interval that follows the thrust-free CW motion of its final
    state (on the safe orbit: the orbit itself)."""
    x_end = tl.final_state
    t1 = tl.t_end
    tt = np.array([0.0, dt_g_s])
    xs = np.array([cw_stm(n, float(s)) @ x_end for s in tt])
    return Timeline(n, tl.segments + [Segment("retreat", t1, t1 + dt_g_s, t=t1 + tt, x=xs, dv=np.zeros((2, 3)))])


def safe_orbit_state(n_rad_s: float, r_as_m: float) -> np.ndarray:
    """§3.4 safe circumnavigation point: y = r_AS/2, y_dot = 0, x_dot = (n/2) y (x = z = 0), a closed
    2:1 CW ellipse (no drift: y_dot = -2 n x holds) with semi-axes r_AS/4 (radial) and r_AS/2."""
    y = r_as_m / 2.0
    return np.array([0.0, y, 0.0, 0.5 * n_rad_s * y, 0.0, 0.0])


def substeps(dt_g_s: float, substep_s: float) -> int:
    """N_sub = dt_g / delta_t_g; raises a clear error unless delta_t_g divides dt_g."""
    for name, v in (("guidance.dt_g_s", dt_g_s), ("guidance.substep_s", substep_s)):
        if not (math.isfinite(v) and v > 0):
            raise input_error(name, v, "must be a finite number > 0", "s")
    ratio = dt_g_s / substep_s
    n = int(round(ratio))
    if n < 1 or abs(ratio - n) > 1e-9 * max(1.0, ratio):
        raise input_error("guidance.substep_s", substep_s,
                          f"must divide guidance.dt_g_s = {dt_g_s:g} s into a whole number of impulses", "s")
    return n
