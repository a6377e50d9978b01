"""Re-planning of the CORTEX loop (Wijayatunga et al. §3.3-3.4): the planner of cortex (1/2) called from
the tracking loop -- the whole plan from the current state, the final approach only, or the retreat to the
safe circumnavigation orbit.

Choices the paper leaves open (documented keys of the scenario): a start inside the buffered KOS shrinks the
planning sphere to 0.95 of the current range (else CP1 is infeasible at once); a final-approach regeneration
from outside the planning cone alpha_c_bar widens it to pass 0.5 deg outside the start (never beyond alpha_c)
and, with ``regen_cone_return_s`` > 0, closes it linearly back onto alpha_c_bar within that time (per-node cone
angles of CP2: the regenerated reference returns towards the axis instead of riding the widened edge beyond the
C_cone_bar threshold, measured up to 280 of 300 s). A regeneration tries at most ``replan_candidates`` durations
per phase from tau_lb (an onboard time budget: measured, a failing CP2 regeneration over the whole [5, 60] min
grid took 90 s of CPU).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from proxops.constraints.approach_cone import ApproachCone
from proxops.constraints.plume import PlumeConstraint
from proxops.guidance.cortex.phases import solve_final_approach, solve_flyaround
from proxops.guidance.cortex.reference import duration_grid, first_converged, plan_reference


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
        return plan_reference(self.axis, self._cfg_from(x0), eclipse=self.eclipse, t0_s=self.t0_offset_s + t_now)

    def _scan(self, solve, dt):
        grid = duration_grid(self.cfg.tau_lb_s, self.cfg.tau_ub_s, dt)[: self.max_candidates]
        i, res = first_converged(solve, grid, False, [], "replan")
        return None if i is None else res[i]

    def approach(self, x0, x_f2):
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
        c = self.cfg
        r0 = float(np.linalg.norm(np.asarray(x0)[:3]))
        rho = min(c.rho_bar, 0.95 * r0)
        return self._scan(lambda tau: solve_flyaround(c.mean_motion_rad_s, tau, c.dt_cp1_s, x0, x_safe, c.a_bar, rho,
                                                      kos_max_iter=c.kos_max_iter), c.dt_cp1_s)
