"""The one closed-loop engine: navigation -> controller -> actuator -> truth, multi-rate.

Every component declares its period: ``controller.dt`` (s), ``navigation.period_s`` and
``actuator.period_s`` (s, ``None`` = the controller's), and any number of further periodic
components (``Setup.periodic``: e.g. a guidance planner every 30 s that updates the reference
a 2 s tracking controller reads, :class:`proxops.contracts.Periodic`). The engine steps on their
common grid h (:class:`Schedule`: the greatest common divisor of the periods, commensurate to
1 us); the single-rate setup
(all periods equal) is the one-component special case, h = controller.dt, and runs exactly the
loop it always did. Each base tick k at t_k = k h:

1. x_true = plant.relative_state(state); on navigation ticks x_est = navigation.measure(t, x_true,
   rng_nav) (held in between); a controller with ``observe_truth(t, x_true)`` (a safety monitor,
   e.g. the cortex triggers of Table 1) is shown the truth before its step; a filter's ``events``
   list (if any) is drained into the run's events and its ``command(t, u, kind)`` hook (if any)
   gets each controller command after the actuator's known saturations (``actuator.limited``, if
   any; not its random execution errors). A filter with ``consistency_record()`` (NEES from the true
   state it is given at each tick, NIS of each measurement) has them stored at the end of the run as
   ``info["nav_nees"]`` / ``info["nav_nis"]`` on the samples of their ticks (NaN elsewhere), its
   dimensions and statistics in ``meta``
2. each periodic component on its ticks: events += component.update(t, x_est); then on
   controller ticks cmd = controller.step(t, x_est)   (Command: u, kind, status, ...)
3. on actuator ticks (and every controller tick) u = actuator.apply(t, cmd.u, cmd.kind, rng_act)
   (an impulse only on the controller tick that commands it; an acceleration is held)
4. impulse: state = plant.apply_impulse(...) then coast h; acceleration: ZOH over h (split into
   ``check_substeps`` pieces so constraints are checked between samples); a plant with events
   (``has_events``) returns the events it located inside the step (jump maps applied).

Idle steps (event-driven coasting): a command may carry ``next_decision_s`` and ``idle`` (see
:class:`proxops.contracts.Command`): the controller promises that each of its ticks before
``next_decision_s`` would return ``idle`` (a zero command, no events). The engine then skips
those calls and covers the gap with one propagation of the plant (``plant.coast``: one jitted
call for the truth plants), checks the constraints at the same resolution vectorised over the
coast (``constraint.violations`` screens, the scalar ``violation`` decides near zero), measures
the coast's samples at once (``navigation.measure_many``), hands the skipped estimates to the
controller (``observe_coast(t, x_est)``, before its next step) and records exactly the samples
the step-by-step path records: the SimResult is the same (tests/test_engine_coast.py). Coasting
needs a single-rate loop without periodic components, a plant without events, a controller without
``observe_truth`` and an actuator that passes a zero command through without drawing
(``actuator.zero_passthrough``); otherwise, or with ``simulate(..., coast=False)``, every tick
calls ``step``. A coast's propagation runs to its end before the stop condition is evaluated on
its samples.

Optional hooks are the capability protocols of :mod:`proxops.contracts` (``ObservesTruth``,
``ObservesCoast``, ``ReceivesCommand``, ``EmitsEvents``, ``ReportsConsistency``, ``MeasuresMany``,
``LimitsCommand``, ``PassesZero``, ``ViolationsMany``, ``Coasts``), checked once at set-up
(:class:`Hooks`). Structure: :func:`simulate` settles the :class:`Schedule` and the
:class:`Hooks`, then runs the per-tick path (``_Loop.run`` / ``tick``), which hands announced idle
ticks to the coast (``_Loop.coast``) when the run can coast; both write every sample through one
:class:`Recorder` (the same methods, a sample index or a slice), so a coast records the samples of
the ticks it replaces by construction.

Random streams: the run's ``seed`` spawns one named child stream per component
(:func:`component_streams`: navigation, actuator, plant, controller), so adding a component
never shifts another's draws. The plant and controller receive theirs as ``.rng``.

Constraint violations, mode changes, flagged solver statuses, plant events and stops become
events; ``meta["stop_reason"]`` is a :class:`proxops.status.StopReason`, ``meta["layout"]`` the
plant's state layout.
"""

from __future__ import annotations

import math
import sys
import time
import zlib
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from proxops.actuators import IdealActuator
from proxops.dynamics.plant import PlantBase, translational_delta_v  # noqa: F401  (re-exported)
from proxops.errors import PlantEnded
from proxops.navigation import PerfectNavigation
from proxops.contracts import (
    Actuator,
    Coasts,
    Command,
    Controller,
    EmitsEvents,
    LimitsCommand,
    MeasuresMany,
    Navigation,
    ObservesCoast,
    ObservesTruth,
    PassesZero,
    Periodic,
    Plant,
    ReceivesCommand,
    ReportsConsistency,
    ViolationsMany,
)
from proxops.sim.result import SimResult
from proxops.sim.steps import schedule, step_count
from proxops.status import NOT_FLAGGED, Status, StopReason

STREAMS = ("navigation", "actuator", "plant", "controller")
COAST_SCREEN = 1e-6  # a coast's vectorised violation below -this is < 0 (rounding ~1e-12); else checked exactly


def component_streams(seed: int, names: Sequence[str] = STREAMS) -> dict[str, np.random.Generator]:
    """One independent Generator per named component, a child of ``SeedSequence(seed)`` whose
    spawn key is the CRC-32 of the name: the streams do not depend on which other components
    exist or in which order they are asked for."""
    return {name: np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(zlib.crc32(name.encode()),)))
            for name in names}


@dataclass
class Setup:
    """Everything one closed-loop run needs (built from a scenario by its system)."""

    plant: Plant
    controller: Controller
    duration_s: float
    navigation: Navigation = field(default_factory=PerfectNavigation)
    actuator: Actuator = field(default_factory=IdealActuator)
    constraints: Sequence = ()
    stop_condition: Callable[[float, np.ndarray], str | None] | None = None
    check_substeps: int = 1
    meta: dict = field(default_factory=dict)
    periodic: Sequence[Periodic] = ()  # further components on their own period (run before the controller)


def run_steps(setup: Setup) -> tuple[float, int]:
    """Base step h (s) and number of steps of a run of ``setup`` (:func:`proxops.sim.steps.step_count`:
    a one-line input error unless the run has 1 to :data:`proxops.sim.steps.MAX_STEPS` steps)."""
    return step_count(float(setup.controller.dt), setup.navigation.period_s, setup.actuator.period_s,
                      [float(c.period_s) for c in setup.periodic], setup.duration_s)


@dataclass(frozen=True)
class Schedule:
    """The multi-rate grid of one run (:func:`schedule`): base step ``h`` (s), ticks per controller,
    navigation and actuator period, the periodic components with their ticks, ``n_steps`` base steps
    and ``n_sub`` constraint-check pieces of ``sub_dt = h / n_sub`` (s) per step."""

    h: float
    k_ctrl: int
    k_nav: int
    k_act: int
    periodic: tuple  # ((component, ticks per period), ...)
    n_steps: int
    n_sub: int
    sub_dt: float
    single_rate: bool  # k_ctrl == k_nav == k_act == 1

    @classmethod
    def of(cls, setup: Setup) -> "Schedule":
        h, k_ctrl, k_nav, k_act, k_extra = schedule(float(setup.controller.dt), setup.navigation.period_s,
                                                    setup.actuator.period_s, [float(c.period_s) for c in setup.periodic])
        n_sub = int(setup.check_substeps)
        return cls(h, k_ctrl, k_nav, k_act, tuple(zip(setup.periodic, k_extra)), run_steps(setup)[1], n_sub,
                   h / n_sub, k_ctrl == k_nav == k_act == 1)


@dataclass(frozen=True)
class Hooks:
    """The optional capabilities (:mod:`proxops.contracts`) of one run's components, found once at
    set-up by ``isinstance``; ``None`` where a component lacks one."""

    observe_truth: Callable | None  # controller: ObservesTruth
    observe_coast: Callable | None  # controller: ObservesCoast
    nav_command: Callable | None  # navigation: ReceivesCommand
    nav_events: list | None  # navigation: EmitsEvents (the filter's own list, drained by the engine)
    measure_many: Callable | None  # navigation: MeasuresMany (used only without the two filter hooks)
    nav_record: Callable | None  # navigation: ReportsConsistency
    act_limited: Callable | None  # actuator: LimitsCommand
    zero_passthrough: bool  # actuator: PassesZero and its flag
    batches: tuple  # per constraint: ViolationsMany.violations or None
    coasts: bool  # plant: Coasts
    delta_v: Callable  # the plant's delta_v (the translational default without its method call)
    plain_mode: bool  # the plant keeps PlantBase.mode (no discrete modes to record)

    @classmethod
    def of(cls, setup: Setup) -> "Hooks":
        plant, ctrl, nav, act = setup.plant, setup.controller, setup.navigation, setup.actuator
        nav_command = nav.command if isinstance(nav, ReceivesCommand) else None
        nav_events = nav.events if isinstance(nav, EmitsEvents) else None
        plain_filter = nav_command is None and nav_events is None
        return cls(
            observe_truth=ctrl.observe_truth if isinstance(ctrl, ObservesTruth) else None,
            observe_coast=ctrl.observe_coast if isinstance(ctrl, ObservesCoast) else None,
            nav_command=nav_command, nav_events=nav_events,
            measure_many=nav.measure_many if plain_filter and isinstance(nav, MeasuresMany) else None,
            nav_record=nav.consistency_record if isinstance(nav, ReportsConsistency) else None,
            act_limited=act.limited if isinstance(act, LimitsCommand) else None,
            zero_passthrough=isinstance(act, PassesZero) and bool(act.zero_passthrough),
            batches=tuple(c.violations if isinstance(c, ViolationsMany) else None for c in setup.constraints),
            coasts=isinstance(plant, Coasts),
            delta_v=translational_delta_v if type(plant).delta_v is PlantBase.delta_v else plant.delta_v,
            plain_mode=type(plant).mode is PlantBase.mode,
        )

    def can_coast(self, setup: Setup, sched: Schedule) -> bool:
        """Idle steps may be coasted: single rate, no periodic components, no plant events, no truth
        monitor, a plant that coasts and an actuator that passes a zero command through."""
        return (sched.single_rate and not sched.periodic and not setup.plant.has_events
                and self.observe_truth is None and self.coasts and self.zero_passthrough)


class Recorder:
    """The record of one run, preallocated for ``n_steps + 1`` samples. The per-tick path and the
    coast write through the same methods (an index ``idx`` is a sample number or a slice of them), so
    a coast records exactly the samples of the ticks it replaces."""

    def __init__(self, n_steps: int, n_x: int, n_u: int, constraints: Sequence, batches: Sequence, h: float):
        self.n_steps = n_steps
        self.t = np.arange(n_steps + 1) * h  # t_k = k h (s): the numbers the per-tick path and the coast use
        self.x_true = np.zeros((n_steps + 1, n_x))
        self.x_est = np.zeros((n_steps + 1, n_x))
        self.u_cmd = np.zeros((n_steps + 1, n_u))
        self.u_app = np.zeros((n_steps + 1, n_u))
        self.dv_cum = np.zeros(n_steps + 1)
        self.solve_t = np.zeros(n_steps + 1)
        self.status: list[Status] = []
        self.modes: list[str] = []
        self.plant_modes: list[str] = []
        self.info: dict[str, np.ndarray] = {}
        self.events: list[tuple[float, str, str]] = []
        self.max_violation: dict[str, float] = {}
        self.in_violation: dict[str, bool] = {}
        self.constraints, self.batches = tuple(constraints), tuple(batches)
        self.checks = tuple((con.violation, con.name) for con in self.constraints)  # per-tick check, looked up once
        self.last_mode: str | None = None
        self.kinds_seen: set[str] = set()  # command kinds of the run (the unit of a "kind" control column)

    def samples(self, idx, x_true, x_est) -> None:
        """True and estimated measured state of the samples ``idx`` (their times are preset)."""
        self.x_true[idx], self.x_est[idx] = x_true, x_est

    def commands(self, idx, n: int, cmd: Command, u_applied, status: Status) -> None:
        """The ``n`` samples ``idx`` of command ``cmd`` (applied ``u_applied``): u, solve time, status,
        mode and info columns (each value held over the samples)."""
        self.u_cmd[idx], self.u_app[idx], self.solve_t[idx] = cmd.u, u_applied, cmd.solve_time_s
        if n == 1:
            self.status.append(status)
            self.modes.append(cmd.mode)
        else:
            self.status.extend([status] * n)
            self.modes.extend([cmd.mode] * n)
        info = self.info
        for key, val in cmd.info.items():
            try:
                info[key][idx] = val
            except KeyError:  # the key's first sample: its column, NaN where it has no value
                series = info[key] = np.full(self.n_steps + 1, np.nan)
                series[idx] = val

    def mode(self, t: float, mode: str, into: list) -> None:
        """A ``mode`` event into ``into`` when the controller mode changes at ``t`` (s)."""
        if mode != self.last_mode and self.last_mode is not None:
            into.append((t, "mode", f"{self.last_mode} -> {mode}"))
        self.last_mode = mode

    def held(self, k: int, u_cmd, u_applied) -> None:
        """Sample ``k`` between controller ticks: the held command, no status."""
        self.status.append(Status.NONE)
        self.modes.append(self.last_mode or "")
        self.u_cmd[k], self.u_app[k] = u_cmd, u_applied

    def last(self) -> None:
        """The final sample (end of the run or stop before a step): no command."""
        self.status.append(Status.NONE)
        self.modes.append(self.last_mode or "")

    def delta_v(self, j: int, n: int, dv: float) -> None:
        """Cumulative delta-v after the ``n`` steps from sample ``j``, each adding ``dv`` (m/s)."""
        dv_cum = self.dv_cum
        if n == 1:
            dv_cum[j + 1] = dv_cum[j] + dv
        elif dv == 0.0:
            dv_cum[j + 1:j + n + 1] = dv_cum[j]
        else:
            for i in range(j, j + n):
                dv_cum[i + 1] = dv_cum[i] + dv

    def check(self, t: float, xr: np.ndarray) -> None:
        """Constraints at one check point: maximum violation and a ``violation`` event on entry."""
        in_violation = self.in_violation
        for violation, name in self.checks:
            v = float(violation(t, xr))
            if v > 0.0:
                if v > self.max_violation.get(name, 0.0):
                    self.max_violation[name] = v
                if not in_violation.get(name, False):
                    self.events.append((t, "violation", f"{name} violated by {v:.3g}"))
                in_violation[name] = True
            elif name in in_violation:  # (a name never violated stays absent: v <= 0 is its default)
                in_violation[name] = False

    def check_many(self, chk_t: np.ndarray, chk_x: np.ndarray, at: dict) -> None:
        """:meth:`check` on every check point in turn (times (n,) s, states (n, n_x)), vectorised
        (``violations`` screens, ``violation`` decides near zero); events into ``at`` by position."""
        for con, batch in zip(self.constraints, self.batches):
            if batch is not None:
                v = np.array(batch(chk_t, chk_x), dtype=float)
                for p in np.nonzero(v > -COAST_SCREEN)[0]:
                    v[p] = float(con.violation(float(chk_t[p]), chk_x[p]))
            else:
                v = np.array([float(con.violation(float(chk_t[p]), chk_x[p])) for p in range(len(chk_t))])
            name = con.name
            pos = v > 0.0
            if pos.any():
                prev = np.concatenate([[self.in_violation.get(name, False)], pos[:-1]])
                for p in np.nonzero(pos & ~prev)[0]:
                    at.setdefault(int(p), []).append((float(chk_t[p]), "violation", f"{name} violated by {v[p]:.3g}"))
            vmax = float(v.max())
            if vmax > self.max_violation.get(name, 0.0):
                self.max_violation[name] = vmax
            self.in_violation[name] = bool(pos[-1])

    def result(self, n: int, meta: dict, nav_series: dict, h: float, plain_mode: bool) -> SimResult:
        """The SimResult of the first ``n`` samples; a filter's consistency series ``{key: (t s, values)}``
        as info columns on the samples of their ticks (NaN elsewhere)."""
        info_out = {key: arr[:n] for key, arr in self.info.items()}
        for key, (times, values) in nav_series.items():
            col = np.full(n, np.nan)
            idx = np.rint(np.asarray(times, dtype=float) / h).astype(int)
            keep = (idx >= 0) & (idx < n)
            col[idx[keep]] = np.asarray(values, dtype=float)[keep]
            info_out[key] = col
        return SimResult(t=self.t[:n], x_true=self.x_true[:n], x_est=self.x_est[:n], u_cmd=self.u_cmd[:n],
                         u_applied=self.u_app[:n], dv_cum=self.dv_cum[:n], status=self.status[:n],
                         solve_time_s=self.solve_t[:n], mode=self.modes[:n], info=info_out, events=self.events,
                         meta=meta, plant_mode=[""] * n if plain_mode else self.plant_modes[:n])


class _Loop:
    """One closed-loop run: the per-tick path (:meth:`run`) and the coast over announced idle ticks
    (:meth:`coast`), both recording through one :class:`Recorder`."""

    def __init__(self, setup: Setup, sched: Schedule, hooks: Hooks, rec: Recorder, streams: dict, coast: bool):
        self.setup, self.sched, self.hooks, self.rec = setup, sched, hooks, rec
        self.plant, self.ctrl, self.nav, self.act = setup.plant, setup.controller, setup.navigation, setup.actuator
        self.rng_nav, self.rng_act = streams["navigation"], streams["actuator"]
        self.zero_u = np.zeros(self.plant.n_u)
        self.can_coast = coast and hooks.can_coast(setup, sched)
        self.outcome, self.stop_reason = "completed", StopReason.COMPLETED
        self.u_idle = self.zero_u  # the applied idle command of the current coast
        # the per-tick path's constants and bound methods, looked up once
        self.h, self.single_rate, self.k_ctrl, self.k_act = sched.h, sched.single_rate, sched.k_ctrl, sched.k_act
        self.n_sub, self.sub_dt, self.has_events = sched.n_sub, sched.sub_dt, self.plant.has_events
        self.one_piece = self.n_sub == 1 and not self.has_events
        self.step, self.apply, self.plant_propagate = self.ctrl.step, self.act.apply, self.plant.propagate
        self.delta_v, self.observe_truth = hooks.delta_v, hooks.observe_truth
        self.nav_command, self.act_limited = hooks.nav_command, hooks.act_limited
        self.kinds_seen = rec.kinds_seen

    def stop(self, outcome: str, reason: StopReason, t: float) -> None:
        self.outcome, self.stop_reason = outcome, reason
        self.rec.events.append((t, "stop", outcome))

    def run(self, state, x0: np.ndarray, bar) -> tuple[int, object]:
        """The per-tick path from sample 0 (plant state ``state``, first estimate ``x0``): returns the
        last sample index and the final plant state; announced idle ticks go to :meth:`coast`."""
        sched, rec, plant = self.sched, self.rec, self.plant
        h, n_steps, single_rate, k_nav, k_ctrl = sched.h, sched.n_steps, sched.single_rate, sched.k_nav, sched.k_ctrl
        relative_state, measure, rng_nav = plant.relative_state, self.nav.measure, self.rng_nav
        nav_events, stop_condition, periodic = self.hooks.nav_events, self.setup.stop_condition, sched.periodic
        plant_mode = None if self.hooks.plain_mode else plant.mode
        check = rec.check if rec.constraints else None
        events, tick, x_true_rec, x_est_rec = rec.events, self.tick, rec.x_true, rec.x_est
        xe, cmd, u, k = x0, None, self.zero_u, 0
        while k <= n_steps:
            t = k * h
            xr = relative_state(state)
            if single_rate or k % k_nav == 0:
                xe = measure(t, xr, rng_nav)
                if nav_events:
                    events.extend((t, kind, msg) for kind, msg in nav_events)
                    nav_events.clear()
            x_true_rec[k], x_est_rec[k] = xr, xe  # rec.samples(k, xr, xe), inline
            if plant_mode is not None:
                rec.plant_modes.append(plant_mode(state))
            if check is not None:
                check(t, xr)
            reason = stop_condition(t, xr) if stop_condition is not None else None
            if reason:
                self.stop(reason, StopReason.STOP_CONDITION, t)
                rec.last()
                break
            if k == n_steps:
                rec.last()
                break
            for comp, k_comp in periodic:
                if k % k_comp == 0:
                    events.extend((t, kind, msg) for kind, msg in comp.update(t, xe))
            try:
                state, cmd, u, coast_to = tick(k, t, state, xr, xe, cmd, u)
            except PlantEnded as end:  # sample k (and its command) is the last one
                self.stop(end.outcome, StopReason.PLANT, t)
                break
            if cmd is None:  # the controller stopped the run
                break
            if bar is not None:
                bar.update(1)
            k += 1
            if coast_to > k:
                try:
                    state, stop_i = self.coast(k, coast_to, state, cmd.idle, bar)
                except PlantEnded:  # nothing of the coast is recorded: the ticks locate the end one by one
                    continue
                if stop_i is not None:
                    k += stop_i
                    break
                k = coast_to
        return k, state

    def tick(self, k: int, t: float, state, xr, xe, cmd: Command | None, u):
        """Steps 2-4 of tick ``k`` after the sample: the controller (on its ticks) or the held command,
        the actuator and the propagation. Returns ``(state, cmd, u, coast_to)``; cmd None: stopped."""
        rec = self.rec
        coast_to = 0
        ctrl_tick = self.single_rate or k % self.k_ctrl == 0
        if ctrl_tick:
            cmd, u, coast_to = self.control(k, t, xr, xe)
            if cmd is None:
                return state, None, u, 0
        else:  # between controller samples: the command is held (an impulse is not repeated)
            if cmd.kind == "impulse":
                u = self.zero_u
            elif k % self.k_act == 0:
                u = np.asarray(self.apply(t, cmd.u, cmd.kind, self.rng_act), dtype=float)
            rec.held(k, self.zero_u if cmd.kind == "impulse" else cmd.u, u)
        kind = cmd.kind
        if kind not in self.kinds_seen:
            self.kinds_seen.add(kind)
        dv_cum = rec.dv_cum
        dv_cum[k + 1] = dv_cum[k] + self.delta_v(u, kind, self.h)  # rec.delta_v(k, 1, ...), inline
        if kind == "impulse":
            if ctrl_tick and u.any():
                state = self.plant.apply_impulse(t, state, u)
            u_hold = self.zero_u
        else:
            u_hold = u
        if self.one_piece:
            return self.plant_propagate(t, state, u_hold, self.sub_dt), cmd, u, coast_to
        return self.propagate(t, state, u_hold), cmd, u, coast_to

    def control(self, k: int, t: float, xr, xe) -> tuple[Command | None, np.ndarray, int]:
        """A controller tick: step, actuator, record. Returns ``(cmd, u applied, coast_to)``; cmd None
        when the controller stopped the run; coast_to > k + 1 when its idle ticks may be coasted."""
        rec = self.rec
        if self.observe_truth is not None:
            self.observe_truth(t, xr)
        cmd = self.step(t, xe)
        st = cmd.status
        if st.__class__ is not Status:  # Status.parse, inline (a member passes as it is)
            st = Status.parse(st)
        if cmd.stop:
            self.stop(cmd.mode or "stopped", StopReason.CONTROLLER, t)
            rec.status.append(st)
            rec.modes.append(cmd.mode)
            return None, self.zero_u, 0
        u = np.asarray(self.apply(t, cmd.u, cmd.kind, self.rng_act), dtype=float)
        if self.nav_command is not None:
            self.nav_command(t, cmd.u if self.act_limited is None else self.act_limited(cmd.u), cmd.kind)
        rec.commands(k, 1, cmd, u, st)
        events = rec.events
        if st not in NOT_FLAGGED:  # st.flagged, inline
            events.append((t, "solver", cmd.status_detail or st.value))
        if cmd.mode != rec.last_mode:
            rec.mode(t, cmd.mode, events)
        if cmd.events:
            events.extend((t, kind, msg) for kind, msg in cmd.events)
        return cmd, u, (self.coast_end(k, t, cmd) if cmd.idle is not None and self.can_coast else 0)

    def coast_end(self, k: int, t: float, cmd: Command) -> int:
        """The sample a coast after controller tick ``k`` runs to (0: none): the command announces its
        next decision with a zero, unflagged, event-free idle command (its applied value is kept)."""
        idle = cmd.idle
        if idle is None or not self.can_coast or cmd.next_decision_s is None:
            return 0
        k_next = int(math.ceil(cmd.next_decision_s / self.sched.h - 1e-9))
        if not (k_next > k + 1 and not idle.events and not idle.stop and Status.parse(idle.status) in NOT_FLAGGED
                and not np.any(idle.u)):
            return 0
        self.u_idle = np.asarray(self.act.apply(t, idle.u, idle.kind, self.rng_act), dtype=float)
        return min(k_next, self.sched.n_steps)

    def propagate(self, t: float, state, u_hold):
        """Step 4: ZOH over one base step in ``n_sub`` pieces, constraints checked between them; a
        plant with events records the events it located."""
        plant, n_sub, sub_dt, has_events = self.plant, self.n_sub, self.sub_dt, self.has_events
        if self.one_piece:
            return plant.propagate(t, state, u_hold, sub_dt)  # = the loop below with one piece (t + 0 * sub_dt)
        for j in range(n_sub):
            if has_events:
                state, plant_events = plant.propagate_events(t + j * sub_dt, state, u_hold, sub_dt)
                self.rec.events.extend(plant_events)
            else:
                state = plant.propagate(t + j * sub_dt, state, u_hold, sub_dt)
            if j < n_sub - 1:
                self.rec.check(t + (j + 1) * sub_dt, plant.relative_state(state))
        return state

    def coast(self, j0: int, j1: int, state, idle: Command, bar) -> tuple[object, int | None]:
        """Samples j0..j1-1 of idle controller ticks in one propagation (state: the plant state at j0),
        recorded as the per-tick path records them. Returns (plant state at the next sample, index of
        the stop sample or None)."""
        sched, rec = self.sched, self.rec
        h, n_sub, m = sched.h, sched.n_sub, j1 - j0
        sample_t = np.arange(j0, j1) * h
        piece_t = (sample_t[:, None] + np.arange(n_sub) * sched.sub_dt).ravel()  # start of every propagated piece
        u_hold = self.zero_u if idle.kind == "impulse" else self.u_idle
        states, rel = self.plant.coast(piece_t, state, u_hold, sched.sub_dt)
        xs = rel[0:m * n_sub:n_sub]
        stop_i, reason = self.coast_stop(sample_t, xs)  # after navigation and constraints, as in the step path
        n_rec = m if stop_i is None else stop_i + 1
        n_idle = m if stop_i is None else stop_i  # samples where the controller would have stepped
        at: dict[int, list] = {}  # events by check point (i * n_sub + s), in the step path's order
        xe_rows = self.coast_measure(sample_t[:n_rec], xs[:n_rec], n_idle, idle, at)
        rec.samples(slice(j0, j0 + n_rec), xs[:n_rec], xe_rows)
        if not self.hooks.plain_mode:
            rec.plant_modes.extend(self.plant.mode(states[i * n_sub]) for i in range(n_rec))
        n_chk = m * n_sub if stop_i is None else stop_i * n_sub + 1  # check points up to the stop sample
        rec.check_many(piece_t[:n_chk], rel[:n_chk], at)
        if stop_i is not None:
            self.outcome, self.stop_reason = reason, StopReason.STOP_CONDITION
            at.setdefault(stop_i * n_sub, []).append((float(sample_t[stop_i]), "stop", reason))
        if n_idle:
            rec.mode(float(sample_t[0]), idle.mode, at.setdefault(0, []))
            rec.commands(slice(j0, j0 + n_idle), n_idle, idle, self.u_idle, Status.parse(idle.status))
            rec.delta_v(j0, n_idle, self.hooks.delta_v(self.u_idle, idle.kind, h))
            if self.hooks.observe_coast is not None:
                self.hooks.observe_coast(sample_t[:n_idle], xe_rows[:n_idle])
            if bar is not None:
                bar.update(n_idle)
        if stop_i is not None:
            rec.last()
        for p in sorted(at):
            rec.events.extend(at[p])
        return states[n_rec * n_sub if stop_i is None else stop_i * n_sub], stop_i

    def coast_stop(self, sample_t: np.ndarray, xs: np.ndarray) -> tuple[int | None, str | None]:
        """The first coasted sample where the stop condition holds (index, reason), or (None, None)."""
        stop_condition = self.setup.stop_condition
        if stop_condition is not None:
            for i, (t, x) in enumerate(zip(sample_t.tolist(), xs)):  # t: float(sample_t[i]), x: the row xs[i]
                reason = stop_condition(t, x)
                if reason:
                    return i, reason
        return None, None

    def coast_measure(self, sample_t: np.ndarray, xs: np.ndarray, n_idle: int, idle: Command, at: dict) -> np.ndarray:
        """Estimates of the coasted samples (n, n_x): at once (``measure_many``) or, for a filter with
        hooks, sample by sample with its events (into ``at``) and the idle commands it is given."""
        hooks, n_sub = self.hooks, self.sched.n_sub
        if hooks.measure_many is not None:
            return hooks.measure_many(sample_t, xs, self.rng_nav)
        nav_events, nav_command, act_limited = hooks.nav_events, hooks.nav_command, hooks.act_limited
        xe_rows = np.empty((len(sample_t), xs.shape[1]))
        for i in range(len(sample_t)):
            ti = float(sample_t[i])
            xe_rows[i] = self.nav.measure(ti, xs[i], self.rng_nav)
            if nav_events:
                at.setdefault(i * n_sub, []).extend((ti, kind, msg) for kind, msg in nav_events)
                nav_events.clear()
            if nav_command is not None and i < n_idle:
                nav_command(ti, idle.u if act_limited is None else act_limited(idle.u), idle.kind)
        return xe_rows


def simulate(setup: Setup, seed: int = 0, progress: bool = False, coast: bool = True) -> SimResult:
    """Run one closed loop to ``setup.duration_s`` (or an earlier stop) and return its SimResult.

    The schedule and the components' capabilities are settled once here; the per-tick path runs
    every tick, or hands announced idle ticks to the coast when the run can coast. ``coast=False``:
    every controller tick calls ``step`` even when the controller announced its next decision (the
    reference path of the idle-step coasting; the result is the same)."""
    plant, ctrl, nav = setup.plant, setup.controller, setup.navigation
    streams = component_streams(seed)
    plant.rng, ctrl.rng = streams["plant"], streams["controller"]
    for comp in setup.periodic:
        comp.reset(0.0)
    sched, hooks = Schedule.of(setup), Hooks.of(setup)
    rec = Recorder(sched.n_steps, plant.n_x, plant.n_u, setup.constraints, hooks.batches, sched.h)
    loop = _Loop(setup, sched, hooks, rec, streams, coast)
    state = plant.initial_state()
    bar = _progress_bar(sched.n_steps, progress)
    bar_close = bar.close
    if isinstance(bar, _NoBar):
        bar = None
    wall0 = time.perf_counter()
    x0 = plant.relative_state(state)
    ctrl.reset(0.0, x0)
    try:  # the bar is cleared even when the run is interrupted (Ctrl-C)
        k, state = loop.run(state, x0, bar)
    finally:
        bar_close()
    wall_s = time.perf_counter() - wall0
    nav_series, nav_meta = hooks.nav_record() if hooks.nav_record is not None else ({}, {})
    meta = _run_meta(setup, sched, rec, loop, seed, state, wall_s, nav_meta)
    return rec.result(k + 1, meta, nav_series, sched.h, hooks.plain_mode)


def _run_meta(setup: Setup, sched: Schedule, rec: Recorder, loop: _Loop, seed: int, state, wall_s: float,
              nav_meta: dict) -> dict:
    """``meta`` of a run: the setup's, outcome and stop reason, seed, layouts, violations, final
    state, a filter's consistency statistics (``nav_meta``) and the multi-rate periods."""
    plant, layout = setup.plant, setup.plant.layout
    meta = dict(setup.meta)
    meta.update(
        outcome=loop.outcome,
        stop_reason=loop.stop_reason.value,
        seed=seed,
        dt_s=float(setup.controller.dt),
        wall_time_s=wall_s,
        position_slice=list(layout.span("position") or (0, 3)),
        velocity_slice=list(layout.span("velocity") or (3, 6)),
        layout=layout.to_dict(),
        control_layout=plant.control_layout.to_dict(),
        control_kind="/".join(sorted(rec.kinds_seen)) or "acceleration",
        max_violation=rec.max_violation,
        final_plant_state=np.asarray(state, dtype=float).tolist(),
    )
    if loop.hooks.nav_events is not None:
        meta.update(navigation_filter=True)
    meta.update(nav_meta)
    if not sched.single_rate:
        meta.update(base_step_s=sched.h, navigation_period_s=sched.h * sched.k_nav,
                    actuator_period_s=sched.h * sched.k_act)
    if sched.periodic:
        meta.update(periodic_periods_s=[sched.h * kp for _, kp in sched.periodic])
    return meta


class _NoBar:
    def update(self, n: int) -> None: ...

    def close(self) -> None: ...


class StepBar:
    """Progress of one run (steps) on stderr that shows real progress or nothing.

    The first step carries one-off costs (numba JIT compilation, solver set-up) that say nothing
    about the rest: a bar timed from the start shows a frozen ``1/1082 [ETA 1:05:08]`` while the
    other 1081 steps take 0.08 s. So the first step is not timed: the bar appears only once the
    run has lasted ``delay_s``, the rate has been measured over at least ``measure_s`` after the
    first step, and the remaining steps at that rate still need ``min_remaining_s`` or more; its
    rate and ETA count from the end of the first step (elapsed time is the whole run).
    ``clock`` and ``make_bar(total, n, n_first, t_start, t_first)`` are replaceable for tests."""

    def __init__(self, total: int, clock: Callable[[], float] = time.perf_counter, make_bar=None,
                 delay_s: float = 1.0, measure_s: float = 0.5, min_remaining_s: float = 1.0):
        self.total, self.n = int(total), 0
        self.clock, self.make_bar = clock, make_bar or _tqdm_bar
        self.delay_s, self.measure_s, self.min_remaining_s = delay_s, measure_s, min_remaining_s
        self.t_start = clock()
        self.t_first: float | None = None  # end of the first step
        self.n_first = 0
        self.bar = None

    def update(self, n: int = 1) -> None:
        self.n += n
        if self.bar is not None:
            self.bar.update(n)
            return
        now = self.clock()
        if self.t_first is None:
            self.t_first, self.n_first = now, self.n
            return
        measured = now - self.t_first
        if now - self.t_start < self.delay_s or measured < self.measure_s or self.n >= self.total:
            return
        rate = (self.n - self.n_first) / measured
        if rate > 0 and (self.total - self.n) / rate < self.min_remaining_s:
            return
        self.bar = self.make_bar(self.total, self.n, self.n_first, now - self.t_start, measured)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _tqdm_bar(total: int, n: int, n_first: int, elapsed_s: float, since_first_s: float):
    """A tqdm bar at step ``n`` whose rate is that of the steps after the first (see StepBar)."""
    from tqdm import tqdm

    bar = tqdm(total=total, initial=n_first, unit="step", desc="simulating", leave=False, mininterval=0.5,
               file=sys.stderr, dynamic_ncols=True)
    now = getattr(bar, "_time", time.time)()  # tqdm's clock (time.time)
    bar.start_t = now - elapsed_s  # elapsed: the whole run
    bar.last_print_t, bar.last_print_n = now - since_first_s, n_first  # rate/ETA: from the first step's end
    bar.update(n - n_first)
    return bar


def _progress_bar(total: int, enabled: bool):
    """StepBar on a terminal; nothing when disabled or when stderr is not a terminal (logs, pipes)."""
    if not enabled or not getattr(sys.stderr, "isatty", lambda: False)():
        return _NoBar()
    return StepBar(total)
