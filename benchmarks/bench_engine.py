"""Engine overhead (issue 12): the time the closed-loop engine itself adds per step, measured on a
plant and a controller that do (almost) nothing, single-rate and multi-rate; plus the wall time
of two engine-bound built-in runs (station-keeping: J2 truth + LQR; los-tumble 120 s), and the
per-step cost of the los-tumble and srf-vbar loops with and without their controller (its commands
replayed: what the engine, plant, navigation, actuator and constraint checks cost per step).

    python benchmarks/bench_engine.py [N_STEPS]

Compare against the code before a change by running the same file with PYTHONPATH pointing at
the older tree (the script only uses the stable Setup / simulate / Command API). Best of 5
repeats; the machine is shared, so the load average is printed with the numbers.
"""

from __future__ import annotations

import os
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402


def _command_class():
    try:
        from proxops.contracts import Command
    except ImportError:  # the tree before the contracts moved to the ground floor
        from proxops.sim.protocols import Command
    return Command


def _plant_class():
    try:
        from proxops.dynamics.plant import PlantBase
    except ImportError:  # the tree before the platform change
        PlantBase = object

    class Still(PlantBase):
        n_x, n_u = 6, 3

        def initial_state(self):
            return np.zeros(6)

        def relative_state(self, s):
            return s

        def propagate(self, t, s, u, dt):
            return s

        def apply_impulse(self, t, s, dv):
            return s

    return Still


class Hold:
    def __init__(self, dt):
        self.dt, self.cmd = dt, _command_class()(u=np.zeros(3))

    def reset(self, t0, x0):
        pass

    def step(self, t, x):
        return self.cmd


def per_step_us(n_steps: int, nav_period: float | None = None, repeats: int = 5) -> float:
    from proxops.navigation import PerfectNavigation
    from proxops.sim.engine import Setup, simulate

    best = float("inf")
    for _ in range(repeats):
        nav = PerfectNavigation() if nav_period is None else PerfectNavigation(period_s=nav_period)
        setup = Setup(plant=_plant_class()(), controller=Hold(1.0), duration_s=float(n_steps), navigation=nav)
        t0 = time.perf_counter()
        res = simulate(setup)
        wall = time.perf_counter() - t0
        best = min(best, wall / (len(res.t) - 1))
    return best * 1e6


def per_step_full_us(n_steps: int, repeats: int = 5) -> float:
    """Engine + navigation + actuator + constraint overhead per step (issue 18 goal < 20 us): the
    do-nothing plant and controller of :func:`per_step_us` with a Gaussian navigation model
    (noise drawn every step), a thruster model with magnitude and pointing errors (applied every
    step to a non-zero command) and a keep-out-sphere constraint checked every step."""
    from proxops.actuators import ThrusterModel
    from proxops.constraints.keep_out import KeepOutSphere
    from proxops.navigation import GaussianNavigation
    from proxops.sim.engine import Setup, simulate
    Command = _command_class()

    class Push(Hold):
        def __init__(self, dt):
            self.dt, self.cmd = dt, Command(u=np.array([1e-4, 0.0, 0.0]))

    best = float("inf")
    for _ in range(repeats):
        setup = Setup(plant=_plant_class()(), controller=Push(1.0), duration_s=float(n_steps),
                      navigation=GaussianNavigation(position_sigma_m=0.1, velocity_sigma_mps=1e-3),
                      actuator=ThrusterModel(max_per_axis=1.0, magnitude_sigma=0.01, pointing_sigma_rad=1e-3),
                      constraints=(KeepOutSphere(10.0, (0.0, -100.0, 0.0)),))
        t0 = time.perf_counter()
        res = simulate(setup)
        best = min(best, (time.perf_counter() - t0) / (len(res.t) - 1))
    return best * 1e6


def builtin_wall_s(name: str, overrides: list[str], repeats: int = 5) -> float:
    from proxops.runner import execute
    from proxops.scenarios.loader import load_scenario

    best = float("inf")
    for _ in range(repeats):
        loaded = load_scenario(name, overrides)
        t0 = time.perf_counter()
        execute(loaded)
        best = min(best, time.perf_counter() - t0)
    return best


def replay_per_step_us(name: str, repeats: int = 5) -> tuple[float, float]:
    """Per step of a built-in's closed loop (us): the whole loop, and the loop with its controller
    replaced by a replay of the commands it gave (the engine, plant, navigation, actuator and
    constraint checks: everything that is not the controller). Best of ``repeats``."""
    from proxops import api

    loaded = api.load_scenario(name, [])
    setup = loaded.system.build(loaded.scenario)
    cmds, step = [], setup.controller.step
    setup.controller.step = lambda t, x: cmds.append(step(t, x)) or cmds[-1]
    api.simulate(setup, seed=0)  # warm-up, recording the commands

    class Replay:
        def __init__(self, dt):
            self.dt, self.i = dt, 0

        def reset(self, t0, x0):
            self.i = 0

        def step(self, t, x):
            self.i += 1
            return cmds[self.i - 1]

    best_all = best_rest = float("inf")
    for _ in range(repeats):
        for replay in (False, True):
            run = loaded.system.build(loaded.scenario)
            if replay:
                run.controller = Replay(run.controller.dt)
            t0 = time.perf_counter()
            res = api.simulate(run, seed=0)
            per = (time.perf_counter() - t0) / (len(res.t) - 1) * 1e6
            best_all, best_rest = (best_all, min(best_rest, per)) if replay else (min(best_all, per), best_rest)
    return best_all, best_rest


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 20000
    print(f"load average {os.getloadavg()[0]:.2f} (2 cores)")
    print(f"engine per-step overhead, single rate:          {per_step_us(n):6.2f} us/step ({n} steps, best of 5)")
    print(f"engine + navigation + actuator + constraint:    {per_step_full_us(n):6.2f} us/step "
          "(Gaussian navigation, thruster errors, keep-out check; goal < 20 us)")
    try:
        print(f"engine per-step overhead, navigation 10x faster: {per_step_us(n, nav_period=0.1):6.2f} us/base step")
    except TypeError:
        print("engine per-step overhead, multi-rate: not supported by this tree")
    print(f"station-keeping (J2, 600 s, 60 steps) wall:       {builtin_wall_s('station-keeping', ['sim.duration_s=600']) * 1e3:7.1f} ms")
    print(f"los-tumble (120 s, 120 MPC steps) wall:           {builtin_wall_s('los-tumble', ['sim.duration_s=120']) * 1e3:7.1f} ms")
    for name in ("los-tumble", "srf-vbar"):
        try:
            whole, rest = replay_per_step_us(name)
        except (ImportError, AttributeError):
            print(f"{name}: replayed loop not supported by this tree")
            continue
        print(f"{name} per step: loop {whole:7.1f} us, without the controller (commands replayed) {rest:6.1f} us "
              f"({100 * rest / whole:.0f} %)")


if __name__ == "__main__":
    main()
