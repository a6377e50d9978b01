"""The multi-rate step grid of a closed loop from its periods alone (plain Python: no numpy, no
plant): :func:`schedule` and :func:`step_count`. The engine (:func:`proxops.sim.engine.run_steps`)
and the build-free scenario checks (``proxops validate``, :mod:`proxops.systems.schema`) use the
same functions, so both give the same one-line errors."""

from __future__ import annotations

import math
from typing import Sequence

from proxops.errors import input_error

PERIOD_QUANTUM_S = 1e-6  # periods are commensurate on this grid
MAX_STEPS = 2_000_000  # base steps of one run: its records take ~0.2-0.5 kB per step (~1 GB at the limit)


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


def step_count(ctrl_dt: float, nav_period: float | None, act_period: float | None,
               extra_periods: Sequence[float], duration_s: float) -> tuple[float, int]:
    """Base step h (s, :func:`schedule`) and number of steps of a run of ``duration_s``; a one-line
    input error unless the run has 1 to :data:`MAX_STEPS` steps: a control period longer than the run
    gave 0 steps, status "completed" and exit code 0; a duration of 1e12 s a MemoryError (745 GiB)."""
    h = schedule(float(ctrl_dt), nav_period, act_period, [float(p) for p in extra_periods])[0]
    duration = float(duration_s)
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
