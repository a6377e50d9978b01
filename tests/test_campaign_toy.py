"""A tiny, fast system used by the campaign tests (no tests in this module).

CW truth integrated exactly with the closed-form STM (so runs take milliseconds), the
shared LQR station-keeping controller, navigation and actuator models from the common
builders, a keep-out sphere, and switches that make a run raise, kill its worker process
or sleep. Registered as system ``campaign-toy``; worker processes import this module
by name (the campaign sends ``system_module``).
"""

from __future__ import annotations

import os
import time

import numpy as np
from pydantic import Field

from proxops.core.cw import cw_input_matrix_zoh, cw_stm, mean_motion
from proxops.scenarios.registry import register_system
from proxops.systems.base import SystemBase
from proxops.scenarios.schema import InitialSection, OrbitSection, ScenarioBase, Section, Vector3
from proxops.sim.engine import Setup
from proxops.systems.common import navigation_model
from proxops.systems.schema._build_free import actuator_model, initial_hill_state
from proxops.dynamics.plant import PlantBase

TOY_SCENARIO = {
    "name": "toy",
    "description": "campaign test system",
    "system": "campaign-toy",
    "sim": {"duration_s": 600.0, "seed": 3},
    "orbit": {"altitude_km": 500.0},
    "initial": {"position_m": [20.0, -120.0, 10.0], "velocity_mps": [0.0, 0.02, 0.0]},
    "navigation": {"position_sigma_m": 0.1, "velocity_sigma_mps": 0.001},
    "actuator": {"max_per_axis": 0.01, "magnitude_sigma": 0.02, "pointing_sigma_deg": 1.0, "missed_probability": 0.05},
    "toy": {"dt_s": 10.0, "hold_position_m": [0.0, -100.0, 0.0]},
    "dispersions": {
        "initial.position_m": {"percent": 10, "min_abs": 1.0},
        "initial.velocity_mps": {"percent": 10, "min_abs": 0.01},
    },
}


class ToySection(Section):
    dt_s: float = Field(10.0, gt=0.0)
    hold_position_m: Vector3 = [0.0, -100.0, 0.0]
    gain_scale: float = Field(1.0, gt=0.0)
    keep_out_m: float = Field(0.0, ge=0.0)
    success_tolerance_m: float = Field(5.0, gt=0.0)
    raise_if_x_above_m: float | None = None  # build() raises when initial x exceeds this
    exit_if_x_above_m: float | None = None  # the worker process exits (simulates a killed worker)
    sleep_s: float = Field(0.0, ge=0.0)  # extra wall time per run (or env PROXOPS_TOY_SLEEP_S)


class ToyScenario(ScenarioBase):
    orbit: OrbitSection
    initial: InitialSection
    toy: ToySection = ToySection()


class ExactCWPlant(PlantBase):
    """CW truth propagated with the exact ZOH discretisation (closed form)."""

    n_x, n_u = 6, 3

    def __init__(self, n, x0):
        self.n, self.x0 = n, np.asarray(x0, float)
        self._cache = {}

    def initial_state(self):
        return self.x0.copy()

    def relative_state(self, s):
        return s

    def propagate(self, t, s, u, dt):
        key = round(dt, 12)
        if key not in self._cache:
            self._cache[key] = (cw_stm(self.n, dt), cw_input_matrix_zoh(self.n, dt))
        A, B = self._cache[key]
        return A @ s + B @ u

    def apply_impulse(self, t, s, dv):
        return np.concatenate([s[:3], s[3:] + dv])


class KeepOut:
    name = "keep_out"

    def __init__(self, radius):
        self.radius = radius

    def violation(self, t, x):
        return max(0.0, self.radius - float(np.linalg.norm(x[:3])))


class ScaledLqr:
    def __init__(self, n, dt, hold, scale):
        from proxops.control.station_keeping import LqrStationKeeping

        self.inner = LqrStationKeeping(n, dt, hold)
        self.inner.K = self.inner.K * scale
        self.dt = dt

    def reset(self, t0, x0):
        self.inner.reset(t0, x0)

    def step(self, t, x):
        return self.inner.step(t, x)


def _pass_gate() -> None:
    """With env PROXOPS_TOY_GATE=DIR and PROXOPS_TOY_GATE_OPEN=K: the first K builds (in any
    process) pass, later ones wait until the file DIR/release exists. Lets a test stop a
    campaign in a known state (K runs done, the rest in flight or queued) without timing."""
    gate = os.environ.get("PROXOPS_TOY_GATE")
    if not gate:
        return
    os.makedirs(gate, exist_ok=True)
    ordinal = 1  # this build's place in line: the first free number, claimed atomically (O_EXCL)
    while True:
        try:
            os.close(os.open(os.path.join(gate, f"build-{ordinal:06d}"), os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            break
        except FileExistsError:
            ordinal += 1
    if ordinal <= int(os.environ.get("PROXOPS_TOY_GATE_OPEN", "0")):
        return
    while not os.path.exists(os.path.join(gate, "release")):
        time.sleep(0.01)


@register_system("campaign-toy")
class ToySystem(SystemBase):
    Scenario = ToyScenario

    def build(self, sc):
        x0 = initial_hill_state(sc.initial)
        toy = sc.toy
        if toy.raise_if_x_above_m is not None and x0[0] > toy.raise_if_x_above_m:
            raise RuntimeError(f"toy failure: x0 = {x0[0]:.3f} m above {toy.raise_if_x_above_m} m")
        if toy.exit_if_x_above_m is not None and x0[0] > toy.exit_if_x_above_m:
            os._exit(17)
        sleep_s = toy.sleep_s or float(os.environ.get("PROXOPS_TOY_SLEEP_S", "0"))
        if sleep_s:
            time.sleep(sleep_s)
        _pass_gate()
        n = mean_motion(sc.orbit.sma_m)
        cons = (KeepOut(toy.keep_out_m),) if toy.keep_out_m > 0 else ()
        return Setup(plant=ExactCWPlant(n, x0), controller=ScaledLqr(n, toy.dt_s, toy.hold_position_m, toy.gain_scale),
                     duration_s=sc.sim.duration_s, navigation=navigation_model(sc.navigation),
                     actuator=actuator_model(sc.actuator), constraints=cons)

    def summarize(self, sc, result):
        err = result.position[-1] - np.asarray(sc.toy.hold_position_m)
        return {"hold_error_m": float(np.linalg.norm(err))}

    def success(self, sc, summary):
        return summary["hold_error_m"] < sc.toy.success_tolerance_m




# picklable helpers for the map_runs tests (a light module for spawned workers to import)
def square(x):
    return x * x


def cube(x):
    return x ** 3


def scaled(scale, x):
    return scale * x


def fail_on_three(x):
    if x == 3:
        raise ValueError("three is not allowed")
    return x
