"""One guidance step of the CORTEX loop: CP_g (:class:`proxops.control.cortex_tracking.TrackingSOCP`,
Wijayatunga et al. §3.2.1, eq. 27) towards the reference at the end of the interval, inside the shared
relaxation ladder (:mod:`proxops.control.relaxation`) and, in the final approach, with the plume rows of
eq. 22 (:mod:`proxops.constraints.plume`) by the shared successive-convexification loop
(:func:`proxops.solvers.successive_convexification`).

Choices the paper leaves open (documented keys of the scenario, stated in the report):

* plume in CP_g (deviation from §3.2.1, which leaves the plume out of CP_g): in the final approach
  CP_g carries one SOFT half-space per impulse (slack cost ``plume_weight`` per unit of a_max delta_t_g),
  the dv-linearisation of eq. (21) (alpha_p_bar). Hard rows forbid every braking correction (measured:
  low-error runs drift to the true cone edge and abort); soft rows keep the nominal clean and leave real
  conflicts to the plume triggers (recompute / abort). Linearisation point (``plume_linearization``):
  ``"solution"`` (default) solves CP_g without the rows first and keeps that answer when every impulse
  clears alpha_p_bar (+ ``tracking_plume_margin_deg``) at its predicted position; otherwise the rows are
  linearised about the reference impulse where the reference thrusts and about the plume-free impulse
  elsewhere, and CP_g is solved again: two iterations of the successive-convexification loop, the second
  always accepted. ``"reference"`` linearises about the reference only: where the reference coasts (most
  of CP2) the row is dv . r <= 0, which forbids any impulse with a component away from the target, so CP_g
  cannot slow down a state running ahead of the reference (measured, cortex-low-mc run 25: the tracking
  error grew 0.29 -> 0.84 m over 200 s with CP_g idle, then C_cone_bar recomputes; 100-run campaigns
  reference -> solution: low 95/11/5 -> 100/4/0, high 39/61/61 -> 95/17/5 docked / runs with a recompute /
  aborted). Measured: with the printed CP_g the error-free nominal run commands a braking impulse 8.6 deg
  from the target direction and aborts on C_plume at 528 s (``plume_in_tracking = false`` reproduces it);
* tracking cone margin (``tracking_cone_margin_deg``, a design margin the paper leaves open): in the
  final approach CP_g first imposes (27g) at alpha_c minus the margin and falls back to the printed
  alpha_c only when that is infeasible. A convex solution touches an active constraint, so with (27g) at
  alpha_c alone CP_g planned intervals ending ON the true cone, and any execution error (10 % magnitude)
  put the state outside it: measured on cortex-low-mc (100 runs), 19 of 27 aborts were C_cone, the state
  carried from ~5.6 deg to 10 deg within one interval by CP_g's own plan. The scenarios set the margin to
  alpha_c - (alpha_c_bar + cone_buffer_tol) = 4 deg: CP_g keeps the predicted states inside the C_cone_bar
  recompute threshold whenever it can;
* the ladder (rungs ``(cone, plume)``): ("tight", plume) -> (printed cone, plume) -> (cone, no plume) ->
  (no cone, no plume); a rung past the printed problem is the event ``cpg_relaxed``: the triggers of
  Table 1, not the solver, decide what happens when the constraints are broken (near the cone edge with an
  outward velocity 2 s impulses of a_max delta_t_g cannot keep the next node inside).
"""

from __future__ import annotations

import math

import numpy as np

from proxops.constraints.approach_cone import ApproachCone
from proxops.constraints.plume import PlumeConstraint
from proxops.control.cortex_tracking import TrackingSOCP
from proxops.control.relaxation import climb
from proxops.core.memo import memo_get
from proxops.errors import input_error
from proxops.guidance.cortex.phases import DV_ZERO_MPS
from proxops.solvers import successive_convexification
from proxops.status import Status

_PROBLEMS: dict = {}  # CP_g structures by their data (proxops.core.memo)


class CpgGuidance:
    """CP_g with its ladder and plume step; the problems are built once per (N_sub, cone, plume) and
    updated in place. ``settings``: the supervisor's (dt_g_s, substep_s, terminal_penalty, plume_weight,
    plume_in_tracking, plume_linearization, tracking_cone_margin_deg, tracking_plume_margin_deg)."""

    def __init__(self, n_rad_s: float, a_max_mps2: float, settings, approach_cone: ApproachCone,
                 plume_bar: PlumeConstraint | None, plume_min_dv_mps: float):
        self.n, self.a_max, self.s = n_rad_s, a_max_mps2, settings
        self.dt = settings.substep_s
        self.cone = approach_cone
        self.plume_bar = plume_bar
        self.plume_min_dv_mps = plume_min_dv_mps
        # plume rows (solution linearisation) at alpha_p_bar + tracking_plume_margin: a design margin like the
        # cone's, so that execution errors do not carry an impulse across the C_plume_bar threshold (nor, at
        # ~1 m range where a few cm move the angle by degrees, across alpha_p)
        pm = math.radians(settings.tracking_plume_margin_deg)
        self.plume_track = (PlumeConstraint(plume_bar.half_angle_rad + pm) if plume_bar is not None and pm > 0
                            else plume_bar)
        margin = math.radians(settings.tracking_cone_margin_deg)
        if not 0.0 <= margin < approach_cone.half_angle_rad:
            raise input_error("guidance.tracking_cone_margin_deg", settings.tracking_cone_margin_deg,
                              f"must be >= 0 and below the cone half-angle {math.degrees(approach_cone.half_angle_rad):g} deg",
                              "deg")
        self.tight_cone = ApproachCone(approach_cone.axis, approach_cone.half_angle_rad - margin) if margin > 0 else None
        self._socp: dict = {}
        self.solve_times: list[float] = []
        self.relaxed: str | None = None

    def problem(self, n_sub: int, coned, plume: bool) -> TrackingSOCP:
        """``coned``: False (no 27g), True (27g at alpha_c) or "tight" (27g at alpha_c - tracking_cone_margin).
        Shared by every run of the process with the same data (a campaign's runs): each solve writes its
        state, target and plume rows first, and Clarabel keeps nothing from one solve to the next."""
        key = (n_sub, coned, plume)
        if key not in self._socp:
            cone = self.tight_cone if coned == "tight" else (self.cone if coned else None)
            data = (self.n, n_sub, self.dt, self.a_max, self.s.terminal_penalty, plume, self.s.plume_weight,
                    None if cone is None else (*cone.axis.tolist(), cone.half_angle_rad))
            self._socp[key] = memo_get(_PROBLEMS, data, lambda: TrackingSOCP(
                self.n, n_sub, self.dt, self.a_max, self.s.terminal_penalty, cone=cone, plume=plume,
                plume_weight=self.s.plume_weight))
        return self._socp[key]

    def solve(self, t: float, x_est, seg, timeline, approach: bool):
        """Impulses of the interval starting at t (None when no rung solves), solver seconds, status."""
        t_next = min(t + self.s.dt_g_s, seg.t1)
        n_sub = max(1, int(round((t_next - t) / self.dt)))
        x_T = timeline.state(t + n_sub * self.dt)
        plume = approach and self.s.plume_in_tracking and self.plume_bar is not None
        rungs = [(approach, plume)] + ([(True, False)] if plume else []) + ([(False, False)] if approach else [])
        if approach and self.tight_cone is not None:  # the tightened cone first (design margin, see the module doc)
            rungs.insert(0, ("tight", plume))
        clock = [0.0]
        self.relaxed = None

        def run(prob):
            dv, res = prob.solve(x_est, x_T)
            self.solve_times.append(res.solve_time_s)
            clock[0] += res.solve_time_s
            return dv, res.status

        def attempt(rung):
            coned, with_plume = rung
            if not with_plume:
                return run(self.problem(n_sub, coned, False))
            if self.s.plume_linearization == "solution":
                return self._plume_scp(t, x_est, seg, n_sub, coned, run)
            # "reference": about the reference's position and impulse at each impulse time
            tj = t + self.dt * np.arange(n_sub)
            r_ref = np.array([timeline.state(tt)[:3] for tt in tj])
            dv_ref = np.array([seg.impulse(tt) for tt in tj])
            prob = self.problem(n_sub, coned, True)
            prob.set_plume(self.plume_bar.rows(r_ref, dv_ref, DV_ZERO_MPS, None)[1])
            return run(prob)

        out = climb(rungs, attempt)
        if out.solved and out.level > 0 and out.rung not in (("tight", plume), (approach, plume)):
            self.relaxed = (f"CP_g {(approach, plume)} infeasible -> solved with cone={out.rung[0]}, "
                            f"plume={out.rung[1]}")
        return out.result, clock[0], Status.parse(out.status)

    def _plume_scp(self, t, x_est, seg, n_sub, coned, run):
        """Eq. (22) on CP_g by the shared loop: iterate 1 without the plume rows, accepted when every impulse
        keeps alpha_p_bar (+ margin) at its predicted position; else the rows are linearised about those
        impulses (:meth:`_plume_directions`; a violating one moved to the nearest generatrix of the plume cone:
        the tangent plane admits braking alpha_p_bar off the target direction) and iterate 2 is the answer."""
        free = self.problem(n_sub, coned, False)
        current = [free]
        status = [Status.INFEASIBLE]

        def solve():
            dv, status[0] = run(current[0])
            return dv, (None if dv is not None else status[0])

        last = [None, None]  # (iterate, its predicted positions): the plume-free iterate is checked, then linearised about

        def positions(dv):
            if last[0] is not dv:
                last[:] = [dv, free.predicted_states(x_est, dv)[:-1, :3]]
            return last[1]

        def converged(dv, prev):
            if prev is not None:
                return True
            r0 = positions(dv)
            return float(self.plume_track.margin_rad(r0, dv, self.plume_min_dv_mps).min()) >= 0.0

        def relinearize(dv0, _radius):
            r0 = positions(dv0)
            prob = self.problem(n_sub, coned, True)
            prob.set_plume(self.plume_track.rows(r0, self._plume_directions(dv0, seg, t), DV_ZERO_MPS, None)[1])
            current[0] = prob

        out = successive_convexification(solve, converged, relinearize, max_iter=2)
        return (out.iterate if out.converged else None), status[0]

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
