"""CORTEX closed loop: phases, triggers, regeneration and abort (Wijayatunga et al. §3.2-3.4,
Algorithm 2, Table 1).

:class:`CortexSupervisor` is the engine controller (``dt`` = delta_t_g): every Delta_t_g it solves CP_g
towards the reference at the end of the interval (:class:`proxops.control.cortex_cpg.CpgGuidance`: the
shared relaxation ladder, the plume rows by the shared SCP loop) and fires one impulse per engine step;
every step it evaluates Table 1 (:class:`proxops.control.cortex_triggers.CortexTriggers`) on the TRUE
state (engine hook ``observe_truth``; the measured state when the engine gives none). A trigger is an
engine event ``(abort|recompute, reason)``. The reference is a :class:`proxops.guidance.cortex.timeline.
Timeline`; regenerations and the retreat come from :class:`proxops.guidance.cortex.replanner.
CortexReplanner`; the safe-orbit insertion after an abort is :mod:`proxops.control.cortex_insertion`.

Choices the paper leaves open (documented keys of the scenario, stated in the report):

* the abort conditions are evaluated at every impulse time (delta_t_g), not only at the guidance
  steps, so no true-constraint crossing goes one step without an abort event; the recompute
  conditions at the guidance steps, on x_{k+1} after the whole interval, as Algorithm 2 (lines
  11-15) does (``recompute_every = "impulse"`` checks them every impulse: measured, that catches
  transient buffered crossings inside an interval that CP_g corrects by its end);
* after a regeneration that starts inside a buffered envelope (C_KOS_bar, C_cone_bar), that
  condition is suspended until the true state is back inside it (measured before: the new reference
  re-fired the same trigger at the replan instant and the recompute cap was reached at once);
* nulling (recompute and abort): impulses of at most a_max delta_t_g against the measured velocity
  until |v| <= ``null_tol_mps`` (the paper nulls "immediately");
* regeneration in the final approach re-plans CP2 only and, when that fails, the whole planner (back
  out to x_f1, then CP2); elsewhere the whole planner (holds re-evaluated on the sunlight profile); none
  converged -> abort. After ``max_recomputes`` the next recompute trigger aborts;
* retreat: CP1 from the nulled state to the safe circumnavigation state x_S (§3.4), tracked with CP_g,
  the insertion verified (:mod:`proxops.control.cortex_insertion`); the run ends ``aborted`` and the
  system verifies passive safety on the thrust-free truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxops.constraints.approach_cone import ApproachCone
from proxops.constraints.plume import PlumeConstraint
from proxops.control.cortex_cpg import CpgGuidance
from proxops.control.cortex_insertion import SafeOrbitInsertion
from proxops.control.cortex_triggers import HOLD_PHASES, CortexTriggers
from proxops.errors import ProxopsInputError
from proxops.guidance.cortex.replanner import CortexReplanner
from proxops.guidance.cortex.timeline import (Timeline, phase_timeline, retreat_timeline, safe_orbit_state,
                                              substeps, timeline_from_plan)
from proxops.contracts import Command
from proxops.status import Status

TRACK_PHASES = ("hold1", "flyaround", "hold2", "approach")
PHASE_INDEX = {"hold1": 0, "flyaround": 1, "hold2": 2, "approach": 3, "null": 4, "retreat": 5, "abort_null": 6}


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
        self.x_f2 = timeline.final_state
        self.cpg = CpgGuidance(n_rad_s, a_max_mps2, settings, approach_cone, plume_bar, triggers.plume_min_dv_mps)
        self.insertion = SafeOrbitInsertion(n_rad_s, settings, triggers.r_kos_m, self.dt, self.dv_max)
        self.reset(0.0, timeline.state(0.0))

    def reset(self, t0: float, x0: np.ndarray) -> None:
        self.timeline = self.timeline0
        self.mode = self.timeline.segment(t0).phase
        self.queue: list[np.ndarray] = []
        self.x_true = None
        self.recomputes = 0
        self.aborts = 0
        self.abort_reason = ""
        self.after_null = None  # "recompute" | "abort"
        self.null_phase = None
        self.ground_abort_done = False
        self.cpg.solve_times = []
        self.final_target = None
        self.null_since = None
        self.insertion.reset()
        self.suspended: set[str] = set()  # buffered conditions a regeneration started inside (re-armed on exit)
        self.x_for_next_solve = None  # the next CP_g starts from this state (the coast's mean estimate)
        self.recompute_tag = None

    def observe_truth(self, t: float, x_true: np.ndarray) -> None:
        """Engine hook: the true relative state at this sample (triggers are evaluated on it)."""
        self.x_true = np.asarray(x_true, float)

    def _cmd(self, u, events=(), **kw) -> Command:
        return Command(u=u, kind="impulse", mode=kw.pop("mode", self.mode), events=list(events),
                       info=kw.pop("info", {"phase": PHASE_INDEX.get(self.mode, math.nan)}), **kw)

    def step(self, t: float, x_est: np.ndarray) -> Command:
        x_true = self.x_true if self.x_true is not None else x_est
        events: list[tuple[str, str]] = []
        if (self.s.abort_at_s is not None and not self.ground_abort_done and t >= self.s.abort_at_s - 1e-9
                and self.mode in TRACK_PHASES + ("null",)):
            self.ground_abort_done = True
            return self._start_abort(t, x_est, "ground abort command", events)
        if self.mode == "null" and (trig := self.triggers.check(self.null_phase, x_true[:3], x_true[:3], None,
                                                                 recompute=False)):
            return self._start_abort(t, x_est, trig[1], events)  # nulling before a re-plan: aborts still apply
        if self.mode in ("null", "abort_null"):
            return self._null(t, x_est, events)
        if self.mode not in TRACK_PHASES and self.mode != "retreat":
            return self._cmd(np.zeros(3), stop=True, info={})
        if t >= self.timeline.t_end - 1e-9:
            return self._finish(t, x_est, events)
        ins = self.insertion
        if ins.verifying:  # thrust-free coast of the insertion check (after its drift trim): collect the estimates
            if ins.trim_queue:
                return self._cmd(ins.trim_queue.pop(0), events)
            ins.verify_samples.append((t, np.array(x_est, float)))
            return self._cmd(np.zeros(3))
        seg = self.timeline.segment(t)
        if seg.phase != self.mode:
            self.mode = seg.phase
            self.queue = []
        solve_time, status = 0.0, Status.OK
        guidance_step = not self.queue
        if guidance_step:
            x_solve = x_est if self.x_for_next_solve is None else self.x_for_next_solve
            self.x_for_next_solve = None
            dv, solve_time, status = self.cpg.solve(t, x_solve, seg, self.timeline, self.mode == "approach")
            if self.cpg.relaxed:
                events.append(("cpg_relaxed", self.cpg.relaxed))
            if dv is None:
                if self.mode == "retreat":
                    return self._cmd(np.zeros(3), status=status, solve_time_s=solve_time, info={})
                return self._trigger(t, x_est, ("recompute", f"CP_g {status}"), events, solve_time, status)
            self.queue = list(dv)
        dv = self.queue[0]
        r_true = x_true[:3].tolist()  # 3-vectors as floats once (the triggers and the error use them)
        tl = self.timeline  # the reference at t: seg is tl.segment(t) (= tl.state(t), one segment search)
        r_ref = seg.state(tl.n, min(t, tl.t_end))[:3].tolist()
        if self.mode != "retreat":
            if self.suspended:
                self._rearm(r_true)
            # abort conditions at every impulse; recompute conditions at the guidance steps (Algorithm 2
            # lines 11-15 test x_{k+1} after the whole interval) unless recompute_every = "impulse"
            trig = self.triggers.check(self.mode, r_true, r_ref, dv, self.suspended,
                                       recompute=guidance_step or self.s.recompute_every == "impulse")
            if trig is not None:
                return self._trigger(t, x_est, trig, events, solve_time, status)
        self.queue.pop(0)
        (ax, ay, az), (bx, by, bz) = r_true, r_ref
        err = math.sqrt((ax - bx) ** 2 + (ay - by) ** 2 + (az - bz) ** 2)
        return Command(u=np.array(dv), kind="impulse", status=status, solve_time_s=solve_time, mode=self.mode,
                       events=events, info={"track_err_m": err, "phase": PHASE_INDEX[self.mode]})

    def _rearm(self, r_true) -> None:
        """Re-arm a suspended buffered condition once the true state no longer violates it."""
        if "C_KOS_bar" in self.suspended and self.mode in HOLD_PHASES and not self.triggers.buffered_kos(self.mode, r_true):
            self.suspended.discard("C_KOS_bar")
        if "C_cone_bar" in self.suspended and self.mode == "approach" and not self.triggers.buffered_cone(self.mode, r_true):
            self.suspended.discard("C_cone_bar")

    def _trigger(self, t, x_est, trig, events, solve_time=0.0, status=Status.OK) -> Command:
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

    def _start_abort(self, t, x_est, reason, events, solve_time=0.0, status=Status.OK) -> Command:
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
            return self._cmd(dv, events)
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
                return self._cmd(np.zeros(3), events, mode="failed", stop=True, info={})
            self.timeline = retreat_timeline(res, self.n, t, x_s, self.s.dt_g_s, self.s.insertion_intervals)
            events.append(("retreat", f"transfer to the safe orbit in {res.t[-1]:.0f} s"))
            self.mode = "retreat"
        self.queue = []
        return self._merge(self.step(t, x_est), events) if events else self.step(t, x_est)

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

    def _finish(self, t, x_est, events) -> Command:
        if self.mode != "retreat":
            self.final_target = self.x_f2
            events.append(("docked", "end of the final approach"))
            return self._cmd(np.zeros(3), events, mode="docked", stop=True, info={})
        action = self.insertion.decide(self.timeline, t, x_est, events)
        if action[0] == "stop":
            self.final_target = self.timeline.final_state
            return self._cmd(np.zeros(3), events, mode="aborted", stop=True, info={})
        self.timeline = action[1]
        self.queue = []
        if action[0] == "coast":
            return self._cmd(np.zeros(3), events)
        if action[0] == "trim":
            return self._cmd(action[2], events)
        self.x_for_next_solve = action[2]  # "extend": one more CP_g interval from the coast's mean estimate
        return self._merge(self.step(t, x_est), events) if events else self.step(t, x_est)
