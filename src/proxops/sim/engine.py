"""The one closed-loop engine: navigation -> controller -> actuator -> truth.

Each sample k at t_k = k * controller.dt:

1. x_true = plant.relative_state(state); x_est = navigation.measure(t, x_true, rng)
   (a controller with ``observe_truth(t, x_true)`` -- a safety monitor -- is shown the truth)
2. cmd = controller.step(t, x_est)                  (Command: u, kind, status, ...)
3. u = actuator.apply(t, cmd.u, cmd.kind, rng)     (limits, min impulse, errors)
4. impulse: state = plant.apply_impulse(...) then coast dt; acceleration: ZOH over dt
   (split into ``check_substeps`` pieces so constraints are checked between samples)

Constraint violations, mode changes, solver failures and stops become events.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from proxops.actuators import IdealActuator
from proxops.navigation import PerfectNavigation
from proxops.sim.protocols import Controller, Plant
from proxops.sim.result import SimResult


@dataclass
class Setup:
    """Everything one closed-loop run needs (built from a scenario by its system)."""

    plant: Plant
    controller: Controller
    duration_s: float
    navigation: object = field(default_factory=PerfectNavigation)
    actuator: object = field(default_factory=IdealActuator)
    constraints: Sequence = ()
    stop_condition: Callable[[float, np.ndarray], str | None] | None = None
    check_substeps: int = 1
    meta: dict = field(default_factory=dict)


def simulate(setup: Setup, seed: int = 0, progress: bool = False) -> SimResult:
    """Run one closed loop to ``setup.duration_s`` (or an earlier stop) and return its SimResult."""
    plant, ctrl = setup.plant, setup.controller
    rng = np.random.default_rng(seed)
    dt = float(ctrl.dt)
    n_steps = int(round(setup.duration_s / dt))
    position_slice = getattr(plant, "position_slice", (0, 3))

    state = plant.initial_state()
    delta_v = getattr(plant, "delta_v", translational_delta_v)
    n_x, n_u = plant.n_x, plant.n_u
    t_rec = np.zeros(n_steps + 1)
    x_true = np.zeros((n_steps + 1, n_x))
    x_est = np.zeros((n_steps + 1, n_x))
    u_cmd = np.zeros((n_steps + 1, n_u))
    u_app = np.zeros((n_steps + 1, n_u))
    dv_cum = np.zeros(n_steps + 1)
    solve_t = np.zeros(n_steps + 1)
    status: list[str] = []
    modes: list[str] = []
    info: dict[str, np.ndarray] = {}
    events: list[tuple[float, str, str]] = []
    max_violation: dict[str, float] = {}
    in_violation: dict[str, bool] = {}

    def check_constraints(t: float, xr: np.ndarray) -> None:
        for con in setup.constraints:
            v = float(con.violation(t, xr))
            name = con.name
            if v > max_violation.get(name, 0.0):
                max_violation[name] = v
            if v > 0.0 and not in_violation.get(name, False):
                events.append((t, "violation", f"{name} violated by {v:.3g}"))
            in_violation[name] = v > 0.0

    bar = _progress_bar(n_steps, progress)
    wall0 = time.perf_counter()
    x0 = plant.relative_state(state)
    ctrl.reset(0.0, x0)
    observe = getattr(ctrl, "observe_truth", None)  # supervisors that monitor the true state (cortex triggers)
    outcome = "completed"
    last_mode = None
    k = 0
    try:  # the bar is cleared even when the run is interrupted (Ctrl-C)
        for k in range(n_steps + 1):
            t = k * dt
            xr = plant.relative_state(state)
            xe = setup.navigation.measure(t, xr, rng)
            t_rec[k], x_true[k], x_est[k] = t, xr, xe
            check_constraints(t, xr)
            reason = setup.stop_condition(t, xr) if setup.stop_condition else None
            if reason:
                outcome = reason
                events.append((t, "stop", reason))
                status.append("")
                modes.append(last_mode or "")
                break
            if k == n_steps:
                status.append("")
                modes.append(last_mode or "")
                break
            if observe is not None:
                observe(t, xr)
            cmd = ctrl.step(t, xe)
            if cmd.stop:
                outcome = cmd.mode or "stopped"
                events.append((t, "stop", outcome))
                status.append(cmd.status)
                modes.append(cmd.mode)
                break
            u = np.asarray(setup.actuator.apply(t, cmd.u, cmd.kind, rng), dtype=float)
            u_cmd[k], u_app[k], solve_t[k] = cmd.u, u, cmd.solve_time_s
            status.append(cmd.status)
            modes.append(cmd.mode)
            if cmd.status not in ("ok", "optimal"):
                events.append((t, "solver", cmd.status))
            if cmd.mode != last_mode and last_mode is not None:
                events.append((t, "mode", f"{last_mode} -> {cmd.mode}"))
            last_mode = cmd.mode
            for kind, msg in cmd.events:
                events.append((t, kind, msg))
            for key, val in cmd.info.items():
                series = info.get(key)
                if series is None:
                    series = info[key] = np.full(n_steps + 1, np.nan)
                series[k] = val
            dv_cum[k + 1] = dv_cum[k] + delta_v(u, cmd.kind, dt)
            if cmd.kind == "impulse":
                if u.any():
                    state = plant.apply_impulse(t, state, u)
                u_hold = np.zeros(n_u)
            else:
                u_hold = u
            sub_dt = dt / setup.check_substeps
            for j in range(setup.check_substeps):
                state = plant.propagate(t + j * sub_dt, state, u_hold, sub_dt)
                if j < setup.check_substeps - 1:
                    check_constraints(t + (j + 1) * sub_dt, plant.relative_state(state))
            bar.update(1)
    finally:
        bar.close()
    n = k + 1
    meta = dict(setup.meta)
    meta.update(
        outcome=outcome,
        seed=seed,
        dt_s=dt,
        wall_time_s=time.perf_counter() - wall0,
        position_slice=list(position_slice),
        velocity_slice=list(getattr(plant, "velocity_slice", (3, 6))),
        max_violation=max_violation,
        final_plant_state=np.asarray(state, dtype=float).tolist(),
    )
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
        info={key: arr[:n] for key, arr in info.items()},
        events=events,
        meta=meta,
    )


def translational_delta_v(u: np.ndarray, kind: str, dt: float) -> float:
    """Delta-v (m/s) of one applied command: |dv| for an impulse, |a| dt for a held
    acceleration. Plants whose control is not a translational acceleration (e.g. thrust
    in N plus a wheel command) define ``delta_v(u, kind, dt)`` themselves."""
    norm_u = math.sqrt(u @ u)  # = np.linalg.norm(u), without its overhead
    return norm_u if kind == "impulse" else norm_u * dt


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
