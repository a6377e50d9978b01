"""CORTEX closed loop: phases, triggers, regeneration and abort (Wijayatunga et al. §3.2-3.4,
Algorithm 2, Table 1).

Three parts, each usable alone:

* :class:`Timeline` -- the reference of the tracking loop: segments hold1 -> flyaround -> hold2 ->
  approach (or one ``retreat`` segment after an abort); the state at any time is exact under the CW
  model (node state + impulse, propagated by the STM; the paper's ``interp`` of the node states is
  replaced by this, which has no interpolation error between nodes).
* :class:`CortexTriggers` -- Table 1 as a pure function of (phase, true position, reference
  position, commanded impulse): abort conditions first (true KOS in h1/1/h2, true plume and true
  cone in 2), then recompute conditions (tracking error > eps_r of the phase, buffered KOS,
  buffered cone, buffered plume). It knows nothing about solvers or the engine, so it can move
  onto a generic supervisor unchanged. The printed plume rows of Table 1 use cos(alpha_c) (the
  cone angle); the plume is defined by alpha_p (eq. 19d, Fig. 4), so alpha_p / alpha_p_bar are used.
* :class:`CortexSupervisor` -- the engine controller (``dt`` = delta_t_g): every Delta_t_g it
  solves CP_g (:class:`proxops.control.cortex_tracking.TrackingSOCP`) towards the reference at
  the end of the interval and fires one impulse per engine step; every step it evaluates the
  triggers on the TRUE state (engine hook ``observe_truth``; the measured state when the engine
  gives none). A trigger is an engine event ``(abort|recompute, reason)``.

Choices the paper leaves open (documented keys of the scenario, stated in the report):

* the abort conditions are evaluated at every impulse time (delta_t_g), not only at the guidance
  steps, so no true-constraint crossing goes one step without an abort event; the recompute
  conditions at the guidance steps, on x_{k+1} after the whole interval, as Algorithm 2 (lines
  11-15) does (``recompute_every = "impulse"`` checks them every impulse: measured, that catches
  transient buffered crossings inside an interval that CP_g corrects by its end);
* after a regeneration that starts inside a buffered envelope (C_KOS_bar, C_cone_bar), that
  condition is suspended until the true state is back inside it (measured before: the new reference
  re-fired the same trigger at the replan instant and the recompute cap was reached at once);
* plume: evaluated on the impulse about to be fired at the true position (before it is fired, so an
  aborting impulse is not executed); impulses below ``plume_min_dv_mps`` do not count as thrust;
* buffered KOS and cone: the reference lies ON both buffered boundaries (the second hold
  station-keeps at x_f1 = rho_bar e, Table 2; CP2 nodes touch the alpha_c_bar cone), so any tracking
  error, however small, would trip them: they fire only beyond a tolerance (range below
  rho_bar - ``buffer_tol_m``; more than ``cone_buffer_tol_deg`` off the axis beyond alpha_c_bar, an
  angle so that it stays well inside the true cone near the apex). Measured: without it the error-free
  nominal run recomputes at 474 s (0.1 mm outside the buffered cone);
* plume in CP_g (deviation from §3.2.1, which leaves the plume out of CP_g): in the final approach
  CP_g carries one SOFT half-space per impulse (slack cost ``plume_weight`` per unit of a_max delta_t_g),
  the dv-linearisation of eq. (21) (alpha_p_bar). Hard rows forbid every braking correction (measured:
  low-error runs drift to the true cone edge and abort); soft rows keep the nominal clean and leave real
  conflicts to the plume triggers (recompute / abort). Linearisation point (``plume_linearization``):
  ``"solution"`` (default) solves CP_g without the rows first and keeps that answer when every impulse
  clears alpha_p_bar at its predicted position; otherwise the rows are linearised about the reference
  impulse where the reference thrusts and about the plume-free impulse elsewhere (one successive-
  convexification step, eq. 22), and CP_g is solved again. ``"reference"`` linearises about the
  reference only: where the reference coasts (most of CP2) the row is dv . r <= 0, which forbids any
  impulse with a component away from the target, so CP_g cannot slow down a state running ahead of the
  reference (measured, cortex-low-mc run 25: the tracking error grew 0.29 -> 0.84 m over 200 s with CP_g
  idle, then C_cone_bar recomputes; 100-run campaigns reference -> solution: low 95/11/5 -> 100/4/0,
  high 39/61/61 -> 95/17/5 docked / runs with a recompute / aborted).
  Measured: with the printed CP_g the error-free nominal run commands a braking impulse 8.6 deg
  from the target direction and aborts on C_plume at 528 s (``plume_in_tracking = false``
  reproduces it);
* tracking cone margin (``tracking_cone_margin_deg``, a design margin the paper leaves open): in the
  final approach CP_g first imposes (27g) at alpha_c minus the margin and falls back to the printed
  alpha_c only when that is infeasible. A convex solution touches an active constraint, so with (27g) at
  alpha_c alone CP_g planned intervals ending ON the true cone, and any execution error (10 % magnitude)
  put the state outside it: measured on cortex-low-mc (100 runs), 19 of 27 aborts were C_cone, the state
  carried from ~5.6 deg to 10 deg within one interval by CP_g's own plan. The scenarios set the margin to
  alpha_c - (alpha_c_bar + cone_buffer_tol) = 4 deg: CP_g keeps the predicted states inside the C_cone_bar
  recompute threshold whenever it can;
* nulling (recompute and abort): impulses of at most a_max delta_t_g against the measured velocity
  until |v| <= ``null_tol_mps`` (the paper nulls "immediately");
* regeneration in the final approach re-plans CP2 only (from the current state to x_f2) and, when
  that fails, the whole planner (back out to x_f1, then CP2); in the
  holds and the fly-around the whole planner runs from the current state (holds re-evaluated on
  the sunlight profile); a start inside the buffered KOS shrinks the planning sphere to 0.95 of
  the current range (else CP1 is infeasible at once); a final-approach regeneration from outside the
  planning cone alpha_c_bar widens it to pass 0.5 deg outside the start (never beyond alpha_c) and, with
  ``regen_cone_return_s`` > 0, closes it linearly back onto alpha_c_bar within that time (per-node cone angles
  of CP2: the regenerated reference returns towards the axis instead of riding the widened edge beyond the
  C_cone_bar threshold, measured up to 280 of 300 s); A regeneration tries at most
  ``replan_candidates`` durations per phase from tau_lb (an onboard time budget: measured, a failing
  CP2 regeneration over the whole [5, 60] min grid took 90 s of CPU); none converged -> abort.
  After ``max_recomputes`` the next recompute trigger aborts;
* retreat: CP1 (same planner, KOS planes) from the nulled state to the safe circumnavigation
  state x_S = [0, r_AS/2, 0, n r_AS/4, 0, 0] (x_dot = (n/2) y, y_dot = 0, y = r_AS/2, §3.4),
  tracked with CP_g; on arrival the insertion is verified: the thrusters stop only when the
  thrust-free CW prediction from the estimate stays ``passive_margin_m`` outside r_KOS for
  ``passive_orbits`` orbits, else one more guidance interval tracks the safe orbit (at most
  ``insertion_max_intervals``); the run ends ``aborted`` and the system verifies passive safety on
  the thrust-free truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from proxops.constraints.approach_cone import ApproachCone, PlumeConstraint
from proxops.control.cortex_tracking import TrackingSOCP, substeps
from proxops.core.cw import cw_stm
from proxops.errors import ProxopsInputError, input_error
from proxops.guidance.cortex.phases import DV_ZERO_MPS
from proxops.contracts import Command

TRACK_PHASES = ("hold1", "flyaround", "hold2", "approach")
PHASE_INDEX = {"hold1": 0, "flyaround": 1, "hold2": 2, "approach": 3, "null": 4, "retreat": 5, "abort_null": 6}


# --------------------------------------------------------------------------- reference timeline
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

    def impulse(self, t: float) -> np.ndarray:
        """Reference thrust direction at time t for the plume half-spaces of CP_g. CP_g targets the
        reference after each node's impulse (:meth:`state`), so the impulses fired in (t_k, t_k+1]
        deliver the impulse of node k+1 (the terminal burn in the last interval): that one, or the
        impulse of node k when node k+1 has none. Zero in holds."""
        if self.x_hold is not None:
            return np.zeros(3)
        k = min(max(0, int(np.searchsorted(self.t, t + 1e-9, side="right")) - 1), len(self.t) - 2)
        d = np.array(self.dv[k + 1], float)
        if float(np.linalg.norm(d)) < 1e-9:
            d = np.array(self.dv[k], float)
        return d

    def state(self, n: float, t: float) -> np.ndarray:
        """Reference state at t, after the impulse of the node at or before t (after the terminal
        burn at and after t_end): exact CW propagation of the plan between nodes."""
        if self.x_hold is not None:
            return self.x_hold.copy()
        if t >= self.t[-1] - 1e-9:
            xf = self.x[-1].copy()
            xf[3:] += self.dv[-1]  # after the terminal burn: the phase's target state
            return xf
        k = max(0, int(np.searchsorted(self.t, t + 1e-9, side="right")) - 1)
        xk = self.x[k].copy()
        xk[3:] += self.dv[k]
        return cw_stm(n, t - self.t[k]) @ xk


class Timeline:
    """Reference segments in time order (absolute times, s)."""

    def __init__(self, n_rad_s: float, segments: list[Segment]):
        self.n = n_rad_s
        self.segments = [s for s in segments if s.t1 > s.t0 + 1e-9]

    @property
    def t_end(self) -> float:
        return self.segments[-1].t1

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


# --------------------------------------------------------------------------- Table 1
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

    def buffered_kos(self, phase: str, r) -> bool:
        """Buffered-KOS recompute condition (holds and fly-around): range below rho_bar - buffer_tol."""
        return phase in ("hold1", "flyaround", "hold2") and float(np.linalg.norm(r)) < self.rho_bar_m - self.buffer_tol_m

    def off_axis_rad(self, r) -> float:
        r = np.asarray(r, float)
        rng = max(float(np.linalg.norm(r)), 1e-12)
        return math.acos(max(-1.0, min(1.0, float(r @ self.cone_bar.axis) / rng)))

    def buffered_cone(self, phase: str, r) -> bool:
        """Buffered-cone recompute condition (approach): more than alpha_c_bar + cone_buffer_tol off the axis."""
        return phase == "approach" and self.off_axis_rad(r) > self.cone_bar.half_angle_rad + self.cone_buffer_tol_rad

    def check(self, phase: str, r, r_ref, dv, suspended=(), recompute: bool = True) -> tuple[str, str] | None:
        """First condition that holds: ("abort" | "recompute", reason), or None. ``suspended``: names of
        buffered conditions ("C_KOS_bar", "C_cone_bar") not evaluated (see CortexSupervisor.suspended);
        ``recompute=False``: the abort conditions only."""
        r = np.asarray(r, float)
        rng = float(np.linalg.norm(r))
        thrusting = dv is not None and float(np.linalg.norm(dv)) > self.plume_min_dv_mps
        if phase in ("hold1", "flyaround", "hold2") and rng < self.r_kos_m:
            return "abort", f"C_KOS: range {rng:.3f} m < r_KOS {self.r_kos_m:g} m"
        if phase == "approach":
            if thrusting and self.plume.violation(0.0, r, dv) > 0:
                ang = math.degrees(float(self.plume.angle_rad(r, dv)))
                return "abort", f"C_plume: thrust {ang:.2f} deg from the target direction < alpha_p"
            if self.cone.violation(0.0, r) > 0:
                return "abort", f"C_cone: outside the approach cone by {self.cone.violation(0.0, r):.4f} m"
        if not recompute:
            return None
        err = float(np.linalg.norm(r - np.asarray(r_ref, float)))
        eps = self.eps_r_m.get(phase, math.inf)
        if err > eps:
            return "recompute", f"C_trk: tracking error {err:.3f} m > eps_r {eps:g} m ({phase})"
        if "C_KOS_bar" not in suspended and self.buffered_kos(phase, r):
            return "recompute", f"C_KOS_bar: range {rng:.3f} m < rho_bar {self.rho_bar_m:g} m"
        if phase == "approach":
            if "C_cone_bar" not in suspended and self.buffered_cone(phase, r):
                return "recompute", (f"C_cone_bar: {math.degrees(self.off_axis_rad(r)):.2f} deg off the axis > "
                                     f"alpha_c_bar {math.degrees(self.cone_bar.half_angle_rad):g} deg")
            if thrusting and self.plume_bar.violation(0.0, r, dv) > 0:
                ang = math.degrees(float(self.plume_bar.angle_rad(r, dv)))
                return "recompute", f"C_plume_bar: thrust {ang:.2f} deg from the target direction < alpha_p_bar"
        return None


# --------------------------------------------------------------------------- re-planning
class CortexReplanner:
    """The planner of cortex (1/2) called from the loop: full plan, approach only, retreat."""

    def __init__(self, cfg, axis, eclipse=None, t0_offset_s: float = 0.0, max_candidates: int = 30,
                 cone_return_s: float = 0.0):
        self.cfg, self.axis, self.eclipse, self.t0_offset_s = cfg, np.asarray(axis, float), eclipse, t0_offset_s
        self.max_candidates = int(max_candidates)  # durations tried per phase in a regeneration (time budget)
        self.cone_return_s = float(cone_return_s)  # approach regeneration: widened cone closes onto alpha_c_bar over this

    def _cfg_from(self, x0):
        r0 = float(np.linalg.norm(x0[:3]))
        cfg = self.cfg
        rho_end = cfg.rho_bar if cfg.flyaround_end_range_m is None else cfg.flyaround_end_range_m
        margin = cfg.kos_margin if r0 > cfg.rho_bar else max(1.0, 0.95 * r0 / cfg.r_kos_m)
        if margin * cfg.r_kos_m >= r0:
            margin = 1.0
        tau_ub = min(cfg.tau_ub_s, cfg.tau_lb_s + (self.max_candidates - 1) * max(cfg.dt_cp1_s, cfg.dt_cp2_s))
        # a regeneration searches its durations from tau_lb (eq. 12): fixed durations belong to the initial plan
        return replace(cfg, start_state=tuple(float(v) for v in x0), kos_margin=margin, flyaround_end_range_m=rho_end,
                       tau_ub_s=tau_ub, tau1_s=None, tau2_s=None)

    def full(self, x0, t_now: float):
        from proxops.guidance.cortex.reference import plan_reference

        return plan_reference(self.axis, self._cfg_from(x0), eclipse=self.eclipse, t0_s=self.t0_offset_s + t_now)

    def _scan(self, solve, dt):
        from proxops.guidance.cortex.reference import _first_converged, duration_grid

        grid = duration_grid(self.cfg.tau_lb_s, self.cfg.tau_ub_s, dt)[: self.max_candidates]
        i, res = _first_converged(solve, grid, False, [], "replan")
        return None if i is None else res[i]

    def approach(self, x0, x_f2):
        from proxops.guidance.cortex.phases import solve_final_approach

        c = self.cfg
        r0 = np.asarray(x0, float)[:3]
        off = math.acos(max(-1.0, min(1.0, float(r0 @ self.axis) / max(float(np.linalg.norm(r0)), 1e-12))))
        # planning cone: alpha_c_bar, widened to pass 0.5 deg outside a start that lies beyond it (a regeneration
        # after C_cone_bar starts there; with (20f) at node 1 = 10 s later CP2 was infeasible: measured, every such
        # regeneration failed and aborted); never wider than the true cone alpha_c
        half = min(max(c.alpha_c_bar, off + math.radians(0.5)), c.cone_half_angle_rad)
        cone = ApproachCone(self.axis, half)
        plume = PlumeConstraint(c.alpha_p_bar)
        funnel = None
        if self.cone_return_s > 0 and half > c.alpha_c_bar:
            # the widened cone closes linearly back onto alpha_c_bar over cone_return_s: the regenerated
            # reference's first leg returns towards the axis instead of riding the widened edge
            rate = (half - c.alpha_c_bar) / self.cone_return_s
            funnel = lambda tk: max(c.alpha_c_bar, half - rate * tk)  # noqa: E731
        return self._scan(lambda tau: solve_final_approach(
            c.mean_motion_rad_s, tau, c.dt_cp2_s, x0, x_f2, c.a_bar, cone, plume, scp_max_iter=c.scp_max_iter,
            scp_tol_mps=c.scp_tol_mps, plume_tol_rad=c.plume_tol_rad, cone_half_angle_at=funnel), c.dt_cp2_s)

    def retreat(self, x0, x_safe):
        from proxops.guidance.cortex.phases import solve_flyaround

        c = self.cfg
        r0 = float(np.linalg.norm(np.asarray(x0)[:3]))
        rho = min(c.rho_bar, 0.95 * r0)
        return self._scan(lambda tau: solve_flyaround(c.mean_motion_rad_s, tau, c.dt_cp1_s, x0, x_safe, c.a_bar, rho,
                                                      kos_max_iter=c.kos_max_iter), c.dt_cp1_s)


def safe_orbit_state(n_rad_s: float, r_as_m: float) -> np.ndarray:
    """§3.4 safe circumnavigation point: y = r_AS/2, y_dot = 0, x_dot = (n/2) y (x = z = 0), a closed
    2:1 CW ellipse (no drift: y_dot = -2 n x holds) with semi-axes r_AS/4 (radial) and r_AS/2."""
    y = r_as_m / 2.0
    return np.array([0.0, y, 0.0, 0.5 * n_rad_s * y, 0.0, 0.0])


# --------------------------------------------------------------------------- supervisor
@dataclass
class SupervisorSettings:
    dt_g_s: float = 30.0
    substep_s: float = 2.0
    terminal_penalty: float = 10.0
    max_recomputes: int = 3
    null_tol_mps: float = 1e-3
    abort_at_s: float | None = None  # ground abort command time
    r_as_m: float = 75.0
    plume_in_tracking: bool = True
    insertion_intervals: int = 2
    null_timeout_s: float = 120.0  # nulling longer than this (thrusters failed): recompute -> abort, abort -> retreat plan
    plume_weight: float = 1e4
    passive_orbits: float = 1.0  # safe-orbit insertion: thrust-free prediction checked over this many orbits
    passive_margin_m: float = 2.0  # ... and must stay this far outside r_KOS before the thrusters stop
    insertion_max_intervals: int = 20  # most extra guidance intervals spent trimming onto the safe orbit
    insertion_coast_s: float | None = None  # thrust-free coast of each insertion check (None: one guidance interval)
    insertion_drift_tol_m: float | None = None  # predicted |along-track drift| per orbit allowed (None: not checked)
    j2_drift_gain: float = 0.0  # J2 short-period term of the predicted drift: gain sin(2 u) y m/orbit (0: CW only)
    u0_rad: float = 0.0  # target argument of latitude at t = 0 (u = u0 + n t in that term)
    recompute_every: str = "guidance"  # "guidance": recompute conditions at the guidance steps (Alg. 2); "impulse"
    tracking_cone_margin_deg: float = 0.0  # CP_g tries (27g) at alpha_c minus this first (0: only the printed alpha_c)
    tracking_plume_margin_deg: float = 0.0  # CP_g plume rows at alpha_p_bar plus this ("solution" linearisation)
    plume_linearization: str = "solution"  # CP_g plume rows about the reference ("reference") or a plume-free solve ("solution")


class CortexSupervisor:
    """Engine controller for the whole CORTEX loop (impulses every ``substep_s``)."""

    def __init__(self, n_rad_s: float, a_max_mps2: float, timeline: Timeline, triggers: CortexTriggers,
                 replanner: CortexReplanner, settings: SupervisorSettings, approach_cone: ApproachCone,
                 plume_bar: PlumeConstraint | None = None):
        self.n = n_rad_s
        self.a_max = a_max_mps2
        self.s = settings
        self.n_sub = substeps(settings.dt_g_s, settings.substep_s)
        self.dt = settings.substep_s
        self.dv_max = a_max_mps2 * settings.substep_s
        self.timeline0 = timeline
        self.triggers = triggers
        self.replanner = replanner
        self.cone = approach_cone
        self.plume_bar = plume_bar
        # CP_g's plume rows (solution linearisation) at alpha_p_bar + tracking_plume_margin: a design margin
        # like the cone's, so that execution errors do not carry an impulse across the C_plume_bar threshold
        # (nor, at ~1 m range where a few cm move the angle by degrees, across alpha_p)
        pm = math.radians(settings.tracking_plume_margin_deg)
        self.plume_track = (PlumeConstraint(plume_bar.half_angle_rad + pm) if plume_bar is not None and pm > 0
                            else plume_bar)
        self.x_f2 = timeline.final_state
        margin = math.radians(settings.tracking_cone_margin_deg)
        if not 0.0 <= margin < approach_cone.half_angle_rad:
            raise input_error("guidance.tracking_cone_margin_deg", settings.tracking_cone_margin_deg,
                              f"must be >= 0 and below the cone half-angle {math.degrees(approach_cone.half_angle_rad):g} deg",
                              "deg")
        self.tight_cone = ApproachCone(approach_cone.axis, approach_cone.half_angle_rad - margin) if margin > 0 else None
        self._socp: dict = {}
        self.reset(0.0, timeline.state(0.0))

    # CP_g structures, built once per (N_sub, cone, plume) and updated in place
    def _problem(self, n_sub: int, coned, plume: bool) -> TrackingSOCP:
        """``coned``: False (no 27g), True (27g at alpha_c) or "tight" (27g at alpha_c - tracking_cone_margin)."""
        key = (n_sub, coned, plume)
        if key not in self._socp:
            cone = None
            if coned == "tight":
                cone = self.tight_cone
            elif coned:
                cone = self.cone
            self._socp[key] = TrackingSOCP(self.n, n_sub, self.dt, self.a_max, self.s.terminal_penalty,
                                           cone=cone, plume=plume, plume_weight=self.s.plume_weight)
        return self._socp[key]

    def reset(self, t0: float, x0: np.ndarray) -> None:
        self.timeline = self.timeline0
        self.mode = self.timeline.segment(t0).phase
        self.queue: list[np.ndarray] = []
        self.seg_start = None
        self.cycle_t0 = t0
        self.x_true = None
        self.recomputes = 0
        self.aborts = 0
        self.abort_reason = ""
        self.after_null = None  # "recompute" | "abort"
        self.null_phase = None
        self.ground_abort_done = False
        self.solve_times: list[float] = []
        self.final_target = None
        self.relaxed = None
        self.null_since = None
        self.insertion_extensions = 0
        self.drift_trims = 0
        self.predicted_passive_min_m = None
        self.predicted_drift_m = None  # m/orbit, CW prediction from the coast estimates at the stop
        self.insertion_verified = None  # after an abort: the onboard insertion check passed (False: stopped at the cap)
        self.stop_reason = ""
        self.trim_queue: list[np.ndarray] = []
        self._trim_drift = None  # predicted drift (m/orbit) that the last drift trim acted on
        self._ineffective_trims = 0  # consecutive drift trims that left > 0.9 of the drift (dead thrusters)
        self._drift_stms = None
        self.suspended: set[str] = set()  # buffered conditions a regeneration started inside (re-armed on exit)
        self.verifying = False  # coasting to verify the safe-orbit insertion
        self.verify_samples: list = []
        self.x_for_next_solve = None  # the next CP_g starts from this state (the coast's mean estimate)
        self.recompute_tag = None

    def observe_truth(self, t: float, x_true: np.ndarray) -> None:
        """Engine hook: the true relative state at this sample (triggers are evaluated on it)."""
        self.x_true = np.asarray(x_true, float)

    # ------------------------------------------------------------------
    def step(self, t: float, x_est: np.ndarray) -> Command:
        x_true = self.x_true if self.x_true is not None else x_est
        events: list[tuple[str, str]] = []
        if (self.s.abort_at_s is not None and not self.ground_abort_done and t >= self.s.abort_at_s - 1e-9
                and self.mode in TRACK_PHASES + ("null",)):
            self.ground_abort_done = True
            return self._start_abort(t, x_est, "ground abort command", events)
        if self.mode == "null":  # nulling before a re-plan: the abort conditions still apply
            trig = self.triggers.check(self.null_phase, x_true[:3], x_true[:3], None)
            if trig is not None and trig[0] == "abort":
                return self._start_abort(t, x_est, trig[1], events)
        if self.mode in ("null", "abort_null"):
            return self._null(t, x_est, events)
        if self.mode in TRACK_PHASES or self.mode == "retreat":
            if t >= self.timeline.t_end - 1e-9:
                return self._finish(t, x_est, events)
            if self.verifying:  # thrust-free coast of the insertion check (after its drift trim): collect the estimates
                if self.trim_queue:
                    return Command(u=self.trim_queue.pop(0), kind="impulse", mode=self.mode, events=events,
                                   info={"phase": PHASE_INDEX[self.mode]})
                self.verify_samples.append((t, np.asarray(x_est, float).copy()))
                return Command(u=np.zeros(3), kind="impulse", mode=self.mode, info={"phase": PHASE_INDEX[self.mode]})
            seg = self.timeline.segment(t)
            if seg.phase != self.mode:
                self.mode = seg.phase
                self.queue = []
            solve_time, status = 0.0, "ok"
            guidance_step = not self.queue
            if not self.queue:
                x_solve = x_est if self.x_for_next_solve is None else self.x_for_next_solve
                self.x_for_next_solve = None
                dv, solve_time, status = self._guidance(t, x_solve, seg)
                if self.relaxed:
                    events.append(("cpg_relaxed", self.relaxed))
                if dv is None:
                    if self.mode == "retreat":
                        return Command(u=np.zeros(3), kind="impulse", status=status, solve_time_s=solve_time,
                                       mode=self.mode)
                    return self._trigger(t, x_est, ("recompute", f"CP_g {status}"), events, solve_time, status)
                self.queue = list(dv)
            dv = self.queue[0]
            if self.mode != "retreat":
                self._rearm(x_true[:3])
                # abort conditions at every impulse; recompute conditions at the guidance steps (Algorithm 2
                # lines 11-15 test x_{k+1} after the whole interval) unless recompute_every = "impulse"
                trig = self.triggers.check(self.mode, x_true[:3], self.timeline.state(t)[:3], dv, self.suspended,
                                           recompute=guidance_step or self.s.recompute_every == "impulse")
                if trig is not None:
                    return self._trigger(t, x_est, trig, events, solve_time, status)
            self.queue.pop(0)
            err = float(np.linalg.norm(x_true[:3] - self.timeline.state(t)[:3]))
            return Command(u=np.array(dv), kind="impulse", status=status, solve_time_s=solve_time, mode=self.mode,
                           events=events, info={"track_err_m": err, "phase": PHASE_INDEX[self.mode]})
        return Command(u=np.zeros(3), kind="impulse", mode=self.mode, stop=True)

    def _guidance(self, t, x_est, seg):
        """Solve CP_g for the interval starting at t. In the approach the problem carries the cone and
        the plume half-spaces; when that is infeasible (the state near the cone edge with an outward
        velocity: 2 s impulses of a_max delta_t_g cannot keep the next node inside) it is re-solved
        without the plume rows, then without the cone (event ``cpg_relaxed``): the triggers of Table 1,
        not the solver, decide what happens when the constraints are broken."""
        t_next = min(t + self.s.dt_g_s, seg.t1)
        n_sub = max(1, int(round((t_next - t) / self.dt)))
        x_T = self.timeline.state(t + n_sub * self.dt)
        approach = self.mode == "approach"
        plume = approach and self.s.plume_in_tracking and self.plume_bar is not None
        ladder = [(approach, plume)] + ([(True, False)] if plume else []) + ([(False, False)] if approach else [])
        if approach and self.tight_cone is not None:  # the tightened cone first (design margin, see the module doc)
            ladder.insert(0, ("tight", plume))
        total = 0.0
        self.relaxed = None
        for coned, with_plume in ladder:
            prob = self._problem(n_sub, coned, with_plume)
            if with_plume:
                if self.s.plume_linearization == "solution":
                    # one successive-convexification step of eq. (22) on CP_g: solve without the plume rows; an
                    # interval whose impulses all keep alpha_p_bar at their predicted positions is the answer, else
                    # the rows are linearised about those impulses (a violating one moved to the nearest generatrix
                    # of the plume cone: the tangent plane admits braking alpha_p_bar off the target direction)
                    free = self._problem(n_sub, coned, False)
                    dv0, res0 = free.solve(x_est, x_T)
                    self.solve_times.append(res0.solve_time_s)
                    total += res0.solve_time_s
                    if dv0 is None:  # infeasible without the plume rows: infeasible with them
                        res = res0
                        continue
                    r0 = free.predicted_states(x_est, dv0)[:-1, :3]
                    margin = self.plume_track.margin_rad(r0, dv0, self.triggers.plume_min_dv_mps)
                    if float(margin.min()) >= 0.0:
                        if coned not in ("tight", approach):
                            self.relaxed = f"CP_g {(approach, plume)} infeasible -> solved with cone={coned}, plume=True"
                        return dv0, total, res0.status.value
                    _, g, _ = self.plume_track.linearization(r0, self._plume_directions(dv0, seg, t), DV_ZERO_MPS)
                else:  # "reference": about the reference's position and impulse at each impulse time
                    tj = t + self.dt * np.arange(n_sub)
                    r_ref = np.array([self.timeline.state(tt)[:3] for tt in tj])
                    dv_ref = np.array([seg.impulse(tt) for tt in tj])
                    _, g, _ = self.plume_bar.linearization(r_ref, dv_ref, DV_ZERO_MPS)
                prob.set_plume(g)
            dv, res = prob.solve(x_est, x_T)
            self.solve_times.append(res.solve_time_s)
            total += res.solve_time_s
            if dv is not None:
                if (coned, with_plume) not in (("tight", plume), (approach, plume)):  # past the printed problem
                    self.relaxed = f"CP_g {(approach, plume)} infeasible -> solved with cone={coned}, plume={with_plume}"
                return dv, total, res.status.value
        return None, total, res.status.value

    def _plume_directions(self, dv0, seg, t) -> np.ndarray:
        """Linearisation points of the plume rows: the reference impulse at each impulse time where the
        reference thrusts (the planner chose its direction plume-compatible), elsewhere the impulse of the
        plume-free CP_g solution, or for a zero impulse there the direction of that solution's total impulse.
        (A point inside the plume cone of ``plume_track`` is moved to its nearest generatrix by the
        linearisation, so the rows keep alpha_p_bar + tracking_plume_margin everywhere.)"""
        dv = np.array(dv0, float)
        ref = np.array([seg.impulse(tt) for tt in t + self.dt * np.arange(len(dv))])
        thrusting = np.linalg.norm(ref, axis=1) > DV_ZERO_MPS
        dv[thrusting] = ref[thrusting]
        zero = np.linalg.norm(dv, axis=1) <= DV_ZERO_MPS
        if zero.any():
            total = np.asarray(dv0, float).sum(axis=0)
            if float(np.linalg.norm(total)) > DV_ZERO_MPS:
                dv[zero] = total
        return dv

    def _rearm(self, r_true) -> None:
        """Re-arm a suspended buffered condition once the true state no longer violates it."""
        if "C_KOS_bar" in self.suspended and not self.triggers.buffered_kos(self.mode, r_true):
            if self.mode in ("hold1", "flyaround", "hold2"):
                self.suspended.discard("C_KOS_bar")
        if "C_cone_bar" in self.suspended and self.mode == "approach" and not self.triggers.buffered_cone(self.mode, r_true):
            self.suspended.discard("C_cone_bar")

    def _trigger(self, t, x_est, trig, events, solve_time=0.0, status="ok") -> Command:
        kind, reason = trig
        if kind == "recompute" and self.recomputes >= self.s.max_recomputes:
            kind, reason = "abort", f"recompute cap {self.s.max_recomputes} reached ({reason})"
        if kind == "abort":
            return self._start_abort(t, x_est, reason, events, solve_time, status)
        self.recomputes += 1
        events.append(("recompute", reason))
        self.recompute_tag = reason.split(":")[0]
        self.null_phase = self.mode
        self.after_null = "recompute"
        self.mode = "null"
        cmd = self._null(t, x_est, events)
        cmd.solve_time_s, cmd.status = solve_time, status
        return cmd

    def _start_abort(self, t, x_est, reason, events, solve_time=0.0, status="ok") -> Command:
        self.aborts += 1
        self.abort_reason = reason
        events.append(("abort", reason))
        self.after_null = "abort"
        self.mode = "abort_null"
        self.queue = []
        cmd = self._null(t, x_est, events)
        cmd.solve_time_s, cmd.status = solve_time, status
        return cmd

    def _null(self, t, x_est, events) -> Command:
        v = np.asarray(x_est[3:6], float)
        speed = float(np.linalg.norm(v))
        if self.null_since is None:
            self.null_since = t
        timed_out = t - self.null_since > self.s.null_timeout_s
        if timed_out and self.after_null == "recompute":
            self.null_since = None
            return self._start_abort(t, x_est, f"velocity not nulled in {self.s.null_timeout_s:g} s (thrusters?)", events)
        if speed > self.s.null_tol_mps and not timed_out:
            dv = -v if speed <= self.dv_max else -v * (self.dv_max / speed)
            return Command(u=dv, kind="impulse", mode=self.mode, events=events, info={"phase": PHASE_INDEX[self.mode]})
        # velocity nulled (or the abort's nulling timed out): plan
        self.null_since = None
        if self.after_null == "recompute":
            tl = self._replan(t, x_est)
            if tl is None:
                return self._start_abort(t, x_est, "regeneration failed (no converged plan)", events)
            events.append(("replan", f"new reference from t = {t:.0f} s to {tl.t_end:.0f} s"))
            self.timeline = tl
            self.mode = tl.segment(t).phase
            if self.recompute_tag in ("C_KOS_bar", "C_cone_bar"):
                # the new reference starts where the buffered envelope is already violated: that condition
                # would fire again at once (measured: recompute cap burnt at the replan instant, then abort);
                # it is re-armed when the true state is back inside the buffered envelope (_rearm)
                self.suspended.add(self.recompute_tag)
        else:
            x_s = safe_orbit_state(self.n, self.s.r_as_m)
            res = self.replanner.retreat(np.asarray(x_est, float), x_s)
            if res is None:
                events.append(("failed", "no retreat transfer to the safe orbit converged"))
                return Command(u=np.zeros(3), kind="impulse", mode="failed", events=events, stop=True)
            self.timeline = retreat_timeline(res, self.n, t, x_s, self.s.dt_g_s, self.s.insertion_intervals)
            events.append(("retreat", f"transfer to the safe orbit in {res.t[-1]:.0f} s"))
            self.mode = "retreat"
        self.queue = []
        return self.step(t, x_est) if not events else self._merge(self.step(t, x_est), events)

    @staticmethod
    def _merge(cmd: Command, events) -> Command:
        cmd.events = list(events) + [e for e in cmd.events if e not in events]
        return cmd

    def _replan(self, t, x_est):
        x0 = np.asarray(x_est, float)
        if self.null_phase == "approach":
            res = self.replanner.approach(x0, self.x_f2)
            if res is not None:
                return phase_timeline("approach", res, self.n, t)
            # no final approach from here (typically: outside the planning cone): the whole planner,
            # back out to x_f1 on the axis and in again
        try:
            plan = self.replanner.full(x0, t)
        except ProxopsInputError:  # e.g. a start inside the true KOS: the planner cannot start there
            return None
        if not plan.ok:
            return None
        return timeline_from_plan(plan, self.n, t, self.dt)

    def predicted_min_range(self, x) -> float:
        """Smallest range of the thrust-free CW motion from x over ``passive_orbits`` orbits (m), sampled
        200 times per orbit (the STMs are built once)."""
        if self._drift_stms is None:
            period = 2.0 * math.pi / self.n
            ts = np.linspace(0.0, self.s.passive_orbits * period, int(200 * self.s.passive_orbits) + 1)
            self._drift_stms = np.array([cw_stm(self.n, float(tt))[:3] for tt in ts])  # (k, 3, 6)
        return float(np.linalg.norm(self._drift_stms @ np.asarray(x, float), axis=1).min())

    def _mean_estimate(self, t: float) -> np.ndarray:
        """The coast's estimates mapped to time t by the CW STM and averaged (thrusters off in between):
        the white navigation noise of one sample shrinks by sqrt(samples)."""
        return np.mean([cw_stm(self.n, t - ti) @ xi for ti, xi in self.verify_samples], axis=0)

    def _start_coast(self, t, x_est, trims) -> None:
        """Start an insertion check: fire ``trims`` (one per step), then coast insertion_coast_s collecting
        the estimates (``x_est``: the first sample, already after every impulse)."""
        self.verifying = True
        self.trim_queue = list(trims)
        self.verify_samples = [] if x_est is None else [(t, np.asarray(x_est, float).copy())]
        self.timeline = extend_on_safe_orbit(self.timeline, self.n, self._coast_s() + len(trims) * self.dt)
        self.queue = []

    def predicted_drift_m_per_orbit(self, x, t: float = 0.0) -> float:
        """Along-track drift per orbit of the thrust-free motion from x at time t (m, signed, Hill y): the CW
        secular term of y(t) is -3 (y_dot0 + 2 n x0) t, so -6 pi (2 x0 + y_dot0 / n) per orbit; plus, on a J2
        (or full) truth, -``j2_drift_gain`` sin(2 u) y: an along-track offset y samples the J2 short-period
        term of the semi-major axis, a_sp = (3 J2 Re^2 / 2 a) sin^2 i cos 2u (circular orbit), at u + y / a,
        so the same osculating CW motion has a mean-a offset of (d a_sp / du) y / a and a drift of -3 pi times
        it per orbit: -(9 pi J2 (Re / a)^2 sin^2 i) sin(2u) y (0.95 m/orbit at y = 37.5 m for the CSO of §5.1).
        Measured on J2 truth (cortex-abort, no errors, centre drift dy of the 3-orbit thrust-free truth, Hill
        +y): ground abort at 150 s, CW 0.13 - 0.95 = -0.82 against -1.02 m/orbit; at 450 s -0.10 - 0.81 = -0.90
        against -0.99 m/orbit (CW alone: 0.13 / -0.10)."""
        x = np.asarray(x, float)
        cw = -6.0 * math.pi * (2.0 * x[0] + x[4] / self.n)
        j2 = -self.s.j2_drift_gain * math.sin(2.0 * (self.s.u0_rad + self.n * t)) * x[1] if self.s.j2_drift_gain else 0.0
        return float(cw + j2)

    def _coast_s(self) -> float:
        return self.s.insertion_coast_s if self.s.insertion_coast_s is not None else self.s.dt_g_s

    def _finish(self, t, x_est, events) -> Command:
        if self.mode == "retreat":
            # verified insertion (§3.4 asks for a passively safe orbit; the safe circumnavigation orbit is a CLOSED
            # CW ellipse, so its drift 2 x + y_dot / n must vanish, not only its position error). After the
            # transfer the thrusters coast insertion_coast_s while the estimates are collected; their CW-mapped
            # mean x_bar predicts the thrust-free motion. The thrusters stay off only when (1) the predicted drift
            # |6 pi (2 x + y_dot / n)| per orbit is within insertion_drift_tol_m and (2) the predicted motion stays
            # outside r_KOS + passive_margin_m for passive_orbits orbits. Otherwise: (1) fails -> a drift trim
            # (the along-track impulse -(y_dot + 2 n x) e_y that nulls the drift, in impulses of at most
            # a_max delta_t_g, then the coast check again, so its execution errors are measured and trimmed in
            # turn); (2) fails -> one CP_g interval (from x_bar) onto the safe orbit's own CW motion and the coast
            # check again; at most insertion_max_intervals of both together. Measured before: open-loop insertion
            # with 20 % magnitude errors left 1-7 mm/s, and 1 mm/s drifts ~17 m along-track per orbit against a
            # 3.75 m margin; a position-only check over one orbit passed states drifting up to 12 m/orbit
            # (12 of 21 high-error aborts re-entered r_KOS within 5 orbits).
            if not self.verifying:
                self._start_coast(t, x_est, [])
                return Command(u=np.zeros(3), kind="impulse", mode=self.mode, events=events,
                               info={"phase": PHASE_INDEX[self.mode]})
            self.verify_samples.append((t, np.asarray(x_est, float).copy()))
            x_bar = self._mean_estimate(t)
            self.verifying = False
            rmin = self.predicted_min_range(x_bar)
            drift = self.predicted_drift_m_per_orbit(x_bar, t)
            range_ok = rmin >= self.triggers.r_kos_m + self.s.passive_margin_m
            drift_ok = self.s.insertion_drift_tol_m is None or abs(drift) <= self.s.insertion_drift_tol_m
            if self._trim_drift is not None:  # the last check was after a drift trim: did it act?
                # ineffective: less than 10 % removed from a drift well above the noise of its estimate (4 tol)
                tol = self.s.insertion_drift_tol_m if self.s.insertion_drift_tol_m is not None else 0.0
                big = abs(self._trim_drift) > 4.0 * tol
                self._ineffective_trims = self._ineffective_trims + 1 if (big and abs(drift) > 0.9 * abs(self._trim_drift)) else 0
                self._trim_drift = None
            dead = self._ineffective_trims >= 2  # two drift trims in a row removed < 10 %: the thrusters do not act
            if not (range_ok and drift_ok) and self.insertion_extensions < self.s.insertion_max_intervals and not dead:
                self.insertion_extensions += 1
                if not drift_ok:
                    dvy = self.n * drift / (6.0 * math.pi)  # m/s along y: the predicted drift -> 0 (CW: -(y_dot + 2 n x))
                    k = max(1, int(math.ceil(abs(dvy) / self.dv_max - 1e-12)))
                    self.drift_trims += 1
                    self._trim_drift = drift
                    events.append(("drift_trim", f"predicted drift {drift:+.2f} m/orbit: along-track trim "
                                   f"{dvy * 1e3:+.3f} mm/s in {k} impulse(s)"))
                    self._start_coast(t, None, [np.array([0.0, dvy / k, 0.0]) for _ in range(k)])
                    dv = self.trim_queue.pop(0)
                    return Command(u=dv, kind="impulse", mode=self.mode, events=events,
                                   info={"phase": PHASE_INDEX[self.mode]})
                self.timeline = extend_on_safe_orbit(self.timeline, self.n, self.s.dt_g_s)
                self.queue = []
                self.x_for_next_solve = x_bar
                cmd = self.step(t, x_est)
                return self._merge(cmd, events) if events else cmd
            self.final_target = self.timeline.final_state
            self.predicted_passive_min_m = rmin
            self.predicted_drift_m = drift
            self.insertion_verified = bool(range_ok and drift_ok)
            tol = "" if self.s.insertion_drift_tol_m is None else f" (tol {self.s.insertion_drift_tol_m:g})"
            why = "two drift trims without effect (thrusters?)" if dead else "trim cap reached"
            self.stop_reason = (f"{'verified' if self.insertion_verified else f'NOT verified ({why})'}: "
                                f"predicted thrust-free min range {rmin:.2f} m over {self.s.passive_orbits:g} orbit(s) "
                                f"(need {self.triggers.r_kos_m + self.s.passive_margin_m:g}), drift {drift:+.2f} m/orbit{tol}")
            events.append(("safe_orbit", f"on the safe circumnavigation orbit after {self.insertion_extensions} trim "
                           f"interval(s) ({self.drift_trims} drift trim(s)), {self.stop_reason}; thrusters off"))
            return Command(u=np.zeros(3), kind="impulse", mode="aborted", events=events, stop=True)
        self.final_target = self.x_f2
        events.append(("docked", "end of the final approach"))
        return Command(u=np.zeros(3), kind="impulse", mode="docked", events=events, stop=True)
