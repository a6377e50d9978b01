"""Station keeping about a hold point with LQR or PD on continuous thrust.

The smallest complete system: it exercises the scenario schema, truth, navigation,
actuator model and engine; the Python API examples and the campaign tests use it.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from proxops.core.cw import mean_motion
from proxops.scenarios.registry import register_system
from proxops.systems.base import SystemBase
from proxops.scenarios.schema import InitialSection, OrbitSection, ScenarioBase, Section, TruthSection, Vector3
from proxops.sim.engine import Setup
from proxops.systems.common import actuator_model, initial_hill_state, navigation_model, translational_plant


class StationKeepingController(Section):
    """Control law and its gains (Q = diag(q_pos I, q_vel I), R = r I for LQR)."""

    type: Literal["lqr", "pd"] = Field("lqr", description="control law: discrete LQR on CW, or PD with the CW acceleration cancelled")
    dt_s: float = Field(10.0, gt=0.0, description="controller sample time (zero-order hold)")
    hold_position_m: Vector3 = Field([0.0, -100.0, 0.0], description="station to hold, Hill frame")
    q_pos: float = Field(1.0, gt=0.0, description="LQR state weight on position (Q = diag(q_pos I, q_vel I), SI)")
    q_vel: float = Field(100.0, gt=0.0, description="LQR state weight on velocity (SI)")
    r: float = Field(1e8, gt=0.0, description="LQR input weight R = r I on the acceleration (SI)")
    kp: float = Field(1e-3, gt=0.0, description="PD position gain (1/s^2)")
    kd: float = Field(6e-2, gt=0.0, description="PD velocity gain (1/s)")


class StationKeepingScenario(ScenarioBase):
    orbit: OrbitSection = Field(description="target orbit")
    truth: TruthSection = Field(TruthSection(), description="truth model")
    initial: InitialSection = Field(description="initial chaser state")
    controller: StationKeepingController = Field(StationKeepingController(), description="station-keeping law")


@register_system("station-keeping")
class StationKeepingSystem(SystemBase):
    Scenario = StationKeepingScenario

    def build(self, sc: StationKeepingScenario) -> Setup:
        from proxops.control.station_keeping import LqrStationKeeping, PdStationKeeping

        n = mean_motion(sc.orbit.sma_m)
        c = sc.controller
        if c.type == "lqr":
            ctrl = LqrStationKeeping(n, c.dt_s, c.hold_position_m, c.q_pos, c.q_vel, c.r)
        else:
            ctrl = PdStationKeeping(n, c.dt_s, c.hold_position_m, c.kp, c.kd)
        plant = translational_plant(sc.orbit, sc.truth, initial_hill_state(sc.initial))
        actuator = actuator_model(sc.actuator)
        return Setup(plant=plant, controller=ctrl, duration_s=sc.sim.duration_s,
                     navigation=navigation_model(sc.navigation, orbit=sc.orbit, control_dt_s=ctrl.dt,
                                                 system="station-keeping", actuator=actuator),
                     actuator=actuator,
                     check_substeps=sc.sim.check_substeps)

    def summarize(self, sc: StationKeepingScenario, result) -> dict:
        err = result.position[-1] - np.asarray(sc.controller.hold_position_m)
        return {"hold_error_m": float(np.linalg.norm(err))}
