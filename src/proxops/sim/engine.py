"""The one closed-loop engine: navigation -> controller -> actuator -> truth, multi-rate.

Every component declares its period: ``controller.dt`` (s), ``navigation.period_s`` and
``actuator.period_s`` (s, ``None`` = the controller's), and any number of further periodic
components (``Setup.periodic``: e.g. a guidance planner every 30 s that updates the reference
a 2 s tracking controller reads, :class:`proxops.sim.protocols.Periodic`). The engine steps on their common grid
h (the greatest common divisor of the periods, commensurate to 1 us); the single-rate setup
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
:class:`proxops.sim.protocols.Command`): the controller promises that each of its ticks before
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
from proxops.errors import input_error
from proxops.navigation import PerfectNavigation
from proxops.sim.protocols import Actuator, Command, Controller, Navigation, Periodic, Plant
from proxops.sim.result import SimResult
from proxops.status import NOT_FLAGGED, Status, StopReason

STREAMS = ("navigation", "actuator", "plant", "controller")
PERIOD_QUANTUM_S = 1e-6  # periods are commensurate on this grid
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


def schedule(ctrl_dt: float, nav_period: float | None, act_period: float | None,
             extra_periods: Sequence[float] = ()) -> tuple[float, int, int, int, tuple[int, ...]]:
    """Base step h (s) and the ticks per controller, navigation, actuator and extra period.

    All periods equal (or None): ``(ctrl_dt, 1, 1, 1, (1, ...))`` exactly. Otherwise h is the
    greatest common divisor of the periods on a 1 us grid and h = ctrl_dt / K_ctrl."""
    periods = {"controller.dt": ctrl_dt, "navigation.period_s": nav_period or ctrl_dt,
               "actuator.period_s": act_period or ctrl_dt}
    periods.update({f"periodic[{i}].period_s": p for i, p in enumerate(extra_periods)})
    for name, p in periods.items():
        if not (math.isfinite(p) and p > 0):
            raise input_error(name, p, "must be finite and > 0", "s")
    if len(set(periods.values())) == 1:
        return ctrl_dt, 1, 1, 1, (1,) * len(extra_periods)
    ints = {}
    for name, p in periods.items():
        n = round(p / PERIOD_QUANTUM_S)
        if n < 1 or abs(n * PERIOD_QUANTUM_S - p) > 1e-9 * max(1.0, p):
            raise input_error(name, p, f"must be a multiple of {PERIOD_QUANTUM_S:g} s (multi-rate grid)", "s")
        ints[name] = n
    g = math.gcd(*ints.values())
    k_ctrl, k_nav, k_act, *k_extra = (ints[n] // g for n in periods)
    return ctrl_dt / k_ctrl, k_ctrl, k_nav, k_act, tuple(k_extra)


MAX_STEPS = 2_000_000  # base steps of one run: its records take ~0.2-0.5 kB per step (~1 GB at the limit)


def run_steps(setup: Setup) -> tuple[float, int]:
    """Base step h (s, :func:`schedule`) and number of steps of a run of ``setup``; a one-line input
    error unless the run has 1 to :data:`MAX_STEPS` steps: a control period longer than the run gave
    0 steps, status "completed" and exit code 0; a duration of 1e12 s a MemoryError (745 GiB)."""
    h = schedule(float(setup.controller.dt), setup.navigation.period_s, setup.actuator.period_s,
                 [float(c.period_s) for c in setup.periodic])[0]
    duration = float(setup.duration_s)
    if not (math.isfinite(duration) and duration > 0):
        raise input_error("sim.duration_s", duration, "must be finite and > 0", "s")
    if duration < h * (1.0 - 1e-9):
        raise input_error("sim.duration_s", duration, f"is shorter than the step of the closed loop ({h:g} s: its "
                          "control period, e.g. controller.dt_s or sim.dt_s): the run would have no step; give a "
                          "duration >= the step or a shorter step", "s")
    n_steps = int(round(duration / h))
    if n_steps > MAX_STEPS:
        raise input_error("sim.duration_s", duration, f"gives {n_steps:,} steps of {h:g} s; at most {MAX_STEPS:,} "
                          f"steps in one run (duration <= {MAX_STEPS * h:g} s at this step)", "s")
    return h, n_steps


def simulate(setup: Setup, seed: int = 0, progress: bool = False, coast: bool = True) -> SimResult:
    """Run one closed loop to ``setup.duration_s`` (or an earlier stop) and return its SimResult.

    ``coast=False``: every controller tick calls ``step`` even when the controller announced its
    next decision (the reference path of the idle-step coasting; the result is the same)."""
    plant, ctrl, nav, act = setup.plant, setup.controller, setup.navigation, setup.actuator
    streams = component_streams(seed)
    rng_nav, rng_act = streams["navigation"], streams["actuator"]
    plant.rng, ctrl.rng = streams["plant"], streams["controller"]
    for comp in setup.periodic:
        comp.reset(0.0)
    dt_ctrl = float(ctrl.dt)
    h, k_ctrl, k_nav, k_act, k_extra = schedule(dt_ctrl, nav.period_s, act.period_s,
                                                [float(c.period_s) for c in setup.periodic])
    periodic = list(zip(setup.periodic, k_extra))
    single_rate = k_ctrl == k_nav == k_act == 1
    n_steps = run_steps(setup)[1]
    layout = plant.layout
    kinds_seen: set[str] = set()  # command kinds of the run (the unit of a "kind" control column)

    state = plant.initial_state()
    # the translational default without its method call (the same function)
    delta_v = translational_delta_v if getattr(type(plant), "delta_v", None) is PlantBase.delta_v else plant.delta_v
    has_events, plant_mode = plant.has_events, plant.mode
    n_x, n_u = plant.n_x, plant.n_u
    t_rec = np.zeros(n_steps + 1)
    x_true = np.zeros((n_steps + 1, n_x))
    x_est = np.zeros((n_steps + 1, n_x))
    u_cmd = np.zeros((n_steps + 1, n_u))
    u_app = np.zeros((n_steps + 1, n_u))
    dv_cum = np.zeros(n_steps + 1)
    solve_t = np.zeros(n_steps + 1)
    status: list[Status] = []
    modes: list[str] = []
    plant_modes: list[str] = []
    info: dict[str, np.ndarray] = {}
    events: list[tuple[float, str, str]] = []
    max_violation: dict[str, float] = {}
    in_violation: dict[str, bool] = {}
    zero_u = np.zeros(n_u)

    constraints = tuple(setup.constraints)
    stop_condition = setup.stop_condition
    n_sub = int(setup.check_substeps)
    sub_dt = h / n_sub
    propagate, relative_state, measure, step_ctrl, apply_act = (plant.propagate, plant.relative_state, nav.measure,
                                                                 ctrl.step, act.apply)

    def check_constraints(t: float, xr: np.ndarray) -> None:
        for con in constraints:
            v = float(con.violation(t, xr))
            name = con.name
            if v > max_violation.get(name, 0.0):
                max_violation[name] = v
            if v > 0.0 and not in_violation.get(name, False):
                events.append((t, "violation", f"{name} violated by {v:.3g}"))
            in_violation[name] = v > 0.0

    bar = _progress_bar(n_steps, progress)
    bar_close = bar.close
    if isinstance(bar, _NoBar):
        bar = None
    wall0 = time.perf_counter()
    x0 = plant.relative_state(state)
    ctrl.reset(0.0, x0)
    outcome, stop_reason = "completed", StopReason.COMPLETED
    observe = getattr(ctrl, "observe_truth", None)  # supervisors that monitor the true state (cortex triggers)
    last_mode = None
    cmd = None
    u = zero_u
    xe = x0
    k = 0
    nav_command = getattr(nav, "command", None)  # optional hooks of a filter: the commanded control,
    nav_events = getattr(nav, "events", None)  # and its events (e.g. rejected measurements), drained
    act_limited = getattr(act, "limited", None)  # the filter gets the command after the known saturations
    can_coast = (coast and single_rate and not periodic and not has_events and observe is None
                 and bool(getattr(act, "zero_passthrough", False)))
    coast_to = 0  # sample index the current coast runs to (0: none)
    plain_mode = getattr(type(plant), "mode", None) is PlantBase.mode
    observe_coast = getattr(ctrl, "observe_coast", None)
    measure_many = getattr(nav, "measure_many", None) if (nav_command is None and nav_events is None) else None

    def run_coast(j0: int, j1: int, state, idle: Command):
        """Samples j0..j1-1 of idle controller ticks (state: the plant state at j0). Returns
        (plant state at the next sample, index of the stop sample or None, stop reason)."""
        nonlocal last_mode
        m = j1 - j0
        sample_t = np.arange(j0, j1) * h
        piece_t = (sample_t[:, None] + np.arange(n_sub) * sub_dt).ravel()  # start of every propagated piece
        u_hold = zero_u if idle.kind == "impulse" else u_idle_applied
        states, rel = plant.coast(piece_t, state, u_hold, sub_dt)
        xs = rel[0:m * n_sub:n_sub]
        # stop condition on the samples (after navigation and constraints, as in the step path)
        stop_i, reason = None, None
        if stop_condition is not None:
            for i in range(m):
                reason = stop_condition(float(sample_t[i]), xs[i])
                if reason:
                    stop_i = i
                    break
        n_rec = m if stop_i is None else stop_i + 1
        n_idle = m if stop_i is None else stop_i  # samples where the controller would have stepped
        at: dict[int, list] = {}  # events by check point (i * n_sub + s), in the step path's order
        # navigation
        if measure_many is not None:
            xe_rows = measure_many(sample_t[:n_rec], xs[:n_rec], rng_nav)
        else:
            xe_rows = np.empty((n_rec, xs.shape[1]))
            for i in range(n_rec):
                ti = float(sample_t[i])
                xe_rows[i] = nav.measure(ti, xs[i], rng_nav)
                if nav_events:
                    at.setdefault(i * n_sub, []).extend((ti, kind, msg) for kind, msg in nav_events)
                    nav_events.clear()
                if nav_command is not None and i < n_idle:
                    nav_command(ti, idle.u if act_limited is None else act_limited(idle.u), idle.kind)
        sl = slice(j0, j0 + n_rec)
        t_rec[sl], x_true[sl], x_est[sl] = sample_t[:n_rec], xs[:n_rec], xe_rows
        if not plain_mode:
            plant_modes.extend(plant_mode(states[i * n_sub]) for i in range(n_rec))
        # constraints at every check point up to the stop sample (vectorised screen, exact near zero)
        n_chk = m * n_sub if stop_i is None else stop_i * n_sub + 1
        chk_t, chk_x = piece_t[:n_chk], rel[:n_chk]
        for con in constraints:
            batch = getattr(con, "violations", None)
            if batch is not None:
                v = np.array(batch(chk_t, chk_x), dtype=float)
                for p in np.nonzero(v > -COAST_SCREEN)[0]:
                    v[p] = float(con.violation(float(chk_t[p]), chk_x[p]))
            else:
                v = np.array([float(con.violation(float(chk_t[p]), chk_x[p])) for p in range(n_chk)])
            name = con.name
            pos = v > 0.0
            if pos.any():
                prev = np.concatenate([[in_violation.get(name, False)], pos[:-1]])
                for p in np.nonzero(pos & ~prev)[0]:
                    at.setdefault(int(p), []).append((float(chk_t[p]), "violation", f"{name} violated by {v[p]:.3g}"))
            vmax = float(v.max())
            if vmax > max_violation.get(name, 0.0):
                max_violation[name] = vmax
            in_violation[name] = bool(pos[-1])
        if stop_i is not None:
            at.setdefault(stop_i * n_sub, []).append((float(sample_t[stop_i]), "stop", reason))
        # the idle commands
        if n_idle:
            if idle.mode != last_mode and last_mode is not None:
                at.setdefault(0, []).append((float(sample_t[0]), "mode", f"{last_mode} -> {idle.mode}"))
            last_mode = idle.mode
            isl = slice(j0, j0 + n_idle)
            u_cmd[isl], u_app[isl], solve_t[isl] = idle.u, u_idle_applied, idle.solve_time_s
            status.extend([Status.parse(idle.status)] * n_idle)
            modes.extend([idle.mode] * n_idle)
            for key, val in idle.info.items():
                series = info.get(key)
                if series is None:
                    series = info[key] = np.full(n_steps + 1, np.nan)
                series[isl] = val
            dv0 = delta_v(u_idle_applied, idle.kind, h)
            if dv0 == 0.0:
                dv_cum[j0 + 1:j0 + n_idle + 1] = dv_cum[j0]
            else:
                for j in range(j0, j0 + n_idle):
                    dv_cum[j + 1] = dv_cum[j] + dv0
            if observe_coast is not None:
                observe_coast(sample_t[:n_idle], xe_rows[:n_idle])
            if bar is not None:
                bar.update(n_idle)
        if stop_i is not None:
            status.append(Status.NONE)
            modes.append(last_mode or "")
        for p in sorted(at):
            events.extend(at[p])
        return states[n_rec * n_sub if stop_i is None else stop_i * n_sub], stop_i, reason

    u_idle_applied = zero_u
    try:  # the bar is cleared even when the run is interrupted (Ctrl-C)
        k = 0
        while k <= n_steps:
            t = k * h
            xr = relative_state(state)
            if single_rate or k % k_nav == 0:
                xe = measure(t, xr, rng_nav)
                if nav_events:
                    events.extend((t, kind, msg) for kind, msg in nav_events)
                    nav_events.clear()
            t_rec[k], x_true[k], x_est[k] = t, xr, xe
            if not plain_mode:
                plant_modes.append(plant_mode(state))
            if constraints:
                check_constraints(t, xr)
            reason = stop_condition(t, xr) if stop_condition is not None else None
            if reason:
                outcome, stop_reason = reason, StopReason.STOP_CONDITION
                events.append((t, "stop", reason))
                status.append(Status.NONE)
                modes.append(last_mode or "")
                break
            if k == n_steps:
                status.append(Status.NONE)
                modes.append(last_mode or "")
                break
            for comp, k_comp in periodic:
                if k % k_comp == 0:
                    events.extend((t, kind, msg) for kind, msg in comp.update(t, xe))
            ctrl_tick = single_rate or k % k_ctrl == 0
            if ctrl_tick:
                if observe is not None:
                    observe(t, xr)
                cmd = step_ctrl(t, xe)
                st = Status.parse(cmd.status)
                if cmd.stop:
                    outcome, stop_reason = cmd.mode or "stopped", StopReason.CONTROLLER
                    events.append((t, "stop", outcome))
                    status.append(st)
                    modes.append(cmd.mode)
                    break
                u = np.asarray(apply_act(t, cmd.u, cmd.kind, rng_act), dtype=float)
                if nav_command is not None:
                    nav_command(t, cmd.u if act_limited is None else act_limited(cmd.u), cmd.kind)
                u_cmd[k], u_app[k], solve_t[k] = cmd.u, u, cmd.solve_time_s
                status.append(st)
                modes.append(cmd.mode)
                if st not in NOT_FLAGGED:  # st.flagged, inline
                    events.append((t, "solver", cmd.status_detail or st.value))
                if cmd.mode != last_mode and last_mode is not None:
                    events.append((t, "mode", f"{last_mode} -> {cmd.mode}"))
                last_mode = cmd.mode
                if cmd.events:
                    events.extend((t, kind, msg) for kind, msg in cmd.events)
                for key, val in cmd.info.items():
                    series = info.get(key)
                    if series is None:
                        series = info[key] = np.full(n_steps + 1, np.nan)
                    series[k] = val
                idle = cmd.idle
                if idle is not None and can_coast and cmd.next_decision_s is not None:
                    k_next = int(math.ceil(cmd.next_decision_s / h - 1e-9))
                    if (k_next > k + 1 and not idle.events and not idle.stop and Status.parse(idle.status) in NOT_FLAGGED
                            and not np.any(idle.u)):
                        coast_to = min(k_next, n_steps)
                        u_idle_applied = np.asarray(act.apply(t, idle.u, idle.kind, rng_act), dtype=float)
            else:  # between controller samples: the command is held (an impulse is not repeated)
                status.append(Status.NONE)
                modes.append(last_mode or "")
                if cmd.kind == "impulse":
                    u = zero_u
                elif k % k_act == 0:
                    u = np.asarray(act.apply(t, cmd.u, cmd.kind, rng_act), dtype=float)
                u_cmd[k], u_app[k] = (zero_u if cmd.kind == "impulse" else cmd.u), u
            kind = cmd.kind
            kinds_seen.add(kind)
            dv_cum[k + 1] = dv_cum[k] + delta_v(u, kind, h)
            if kind == "impulse":
                if ctrl_tick and u.any():
                    state = plant.apply_impulse(t, state, u)
                u_hold = zero_u
            else:
                u_hold = u
            if n_sub == 1 and not has_events:
                state = propagate(t, state, u_hold, sub_dt)  # = the loop below with one piece (t + 0 * sub_dt)
            else:
                for j in range(n_sub):
                    if has_events:
                        state, plant_events = plant.propagate_events(t + j * sub_dt, state, u_hold, sub_dt)
                        events.extend(plant_events)
                    else:
                        state = propagate(t + j * sub_dt, state, u_hold, sub_dt)
                    if j < n_sub - 1:
                        check_constraints(t + (j + 1) * sub_dt, relative_state(state))
            if bar is not None:
                bar.update(1)
            k += 1
            if coast_to > k:
                state, stop_i, reason = run_coast(k, coast_to, state, cmd.idle)
                if stop_i is not None:
                    outcome, stop_reason = reason, StopReason.STOP_CONDITION
                    k += stop_i
                    break
                k = coast_to
            coast_to = 0
    finally:
        bar_close()
    n = k + 1
    meta = dict(setup.meta)
    meta.update(
        outcome=outcome,
        stop_reason=stop_reason.value,
        seed=seed,
        dt_s=dt_ctrl,
        wall_time_s=time.perf_counter() - wall0,
        position_slice=list(layout.span("position") or (0, 3)),
        velocity_slice=list(layout.span("velocity") or (3, 6)),
        layout=layout.to_dict(),
        control_layout=plant.control_layout.to_dict(),
        control_kind="/".join(sorted(kinds_seen)) or "acceleration",
        max_violation=max_violation,
        final_plant_state=np.asarray(state, dtype=float).tolist(),
    )
    if nav_events is not None:
        meta.update(navigation_filter=True)
    nav_record = getattr(nav, "consistency_record", None)  # optional: a filter's NEES / NIS per tick
    info_out = {key: arr[:n] for key, arr in info.items()}
    if nav_record is not None:
        series, nav_meta = nav_record()
        for key, (times, values) in series.items():
            col = np.full(n, np.nan)
            idx = np.rint(np.asarray(times, dtype=float) / h).astype(int)
            keep = (idx >= 0) & (idx < n)
            col[idx[keep]] = np.asarray(values, dtype=float)[keep]
            info_out[key] = col
        meta.update(nav_meta)
    if not single_rate:
        meta.update(base_step_s=h, navigation_period_s=h * k_nav, actuator_period_s=h * k_act)
    if periodic:
        meta.update(periodic_periods_s=[h * kp for _, kp in periodic])
    return SimResult(
        t=t_rec[:n],
        x_true=x_true[:n],
        x_est=x_est[:n],
        u_cmd=u_cmd[:n],
        u_applied=u_app[:n],
        dv_cum=dv_cum[:n],
        status=status[:n],
        solve_time_s=solve_t[:n],
        mode=modes[:n],
        info=info_out,
        events=events,
        meta=meta,
        plant_mode=[""] * n if plain_mode else plant_modes[:n],
    )


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
