"""Scenario schema of the ``station-keeping`` system (:mod:`proxops.systems.station_keeping`)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from proxops.scenarios.registry import register_check, register_scenario
from proxops.scenarios.schema import InitialSection, OrbitSection, ScenarioBase, Section, TruthSection, Vector3
from proxops.sim.steps import step_count
from proxops.systems.schema._build_free import actuator_model, plant_checked


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


@register_scenario("station-keeping")
class StationKeepingScenario(ScenarioBase):
    orbit: OrbitSection = Field(description="target orbit")
    truth: TruthSection = Field(TruthSection(), description="truth model")
    initial: InitialSection = Field(description="initial chaser state")
    controller: StationKeepingController = Field(StationKeepingController(), description="station-keeping law")


@register_check("station-keeping")
def check(sc: StationKeepingScenario) -> bool:
    """The build's checks (:class:`proxops.systems.station_keeping.StationKeepingSystem`) without
    building: the plant's (:func:`plant_checked`), the actuator's and the run's step count
    (:func:`proxops.sim.steps.step_count` on ``controller.dt_s``). The control laws check nothing
    the schema has not (their gains > 0). False (build) with the ekf or the full truth."""
    if sc.navigation.model == "ekf" or not plant_checked(sc.orbit, sc.truth):
        return False
    actuator = actuator_model(sc.actuator)
    step_count(sc.controller.dt_s, None, actuator.period_s, (), sc.sim.duration_s)  # noise navigation: every sample
    return True
