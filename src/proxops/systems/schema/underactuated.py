"""Scenario schema of the ``underactuated`` system (:mod:`proxops.systems.underactuated`)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from proxops.dynamics.planar_cubesat import DockingSet, Interval, PlanarCubeSatParams, PlanarCubeSatPlant, PlanarLimits
from proxops.scenarios.loader import unit_of
from proxops.scenarios.registry import register_check, register_scenario
from proxops.scenarios.schema import ActuatorSection, ScenarioBase, Section
from proxops.sim.steps import step_count


Bounds = Annotated[list[float], Field(min_length=2, max_length=2)]
Horizon = Annotated[int, Field(ge=1, le=1000)]  # NMPC steps: the NLP grows with it


def _ordered(value: list[float]) -> list[float]:
    if not all(math.isfinite(v) for v in value):
        raise ValueError("both bounds must be finite numbers")
    if value[0] >= value[1]:
        raise ValueError(f"must be [min, max] with min < max (got min {value[0]} >= max {value[1]})")
    return value


class DeputySection(Section):
    """Deputy parameters (Table 1) and damping c of eq. 5 (0 = undamped eq. 4)."""

    mass_kg: Annotated[float, Field(gt=0.0)] = Field(12.0, description="deputy mass m (Table 1)")
    wheel_inertia_kgm2: Annotated[float, Field(gt=0.0)] = Field(4.1e-5, description="reaction wheel inertia (Table 1)")
    body_inertia_kgm2: Annotated[float, Field(gt=0.0)] = Field(5.6e-2, description="body inertia about z (Table 1)")
    mean_motion_rad_s: Annotated[float, Field(ge=0.0)] = Field(
        1.027e-3, description="mean motion n of the chief's circular orbit (Table 1)")
    damping_Nms: Annotated[float, Field(ge=0.0)] = Field(
        0.0, description="wheel-body damping c of eq. 5 (0: undamped eq. 4)")


class LimitsSection(Section):
    """State and input limits as [min, max] (Table 2 defaults; Table 3 in case 2)."""

    thrust_N: Bounds = Field([-2.0, 2.0], description="[min, max] thrust along the body axis")
    wheel_acc_deg_s2: Bounds = Field([-1604.0, 1604.0], description="[min, max] reaction wheel acceleration")
    position_m: Bounds = Field([-2000.0, 2000.0], description="[min, max] of x and y")
    velocity_mps: Bounds = Field([-10.0, 10.0], description="[min, max] of vx and vy")
    angle_deg: Bounds = Field([-180.0, 180.0], description="[min, max] of theta, within [-180, 180]")
    rate_deg_s: Bounds = Field([-2.0, 2.0], description="[min, max] of the body rate omega")
    angular_acc_deg_s2: Bounds = Field([-1.0, 1.0], description="[min, max] of the body angular acceleration")

    @field_validator("*")
    @classmethod
    def _min_below_max(cls, value):
        return _ordered(value)

    @field_validator("angle_deg")
    @classmethod
    def _within_half_turn(cls, value):
        if value[0] < -180.0 or value[1] > 180.0:
            raise ValueError("must lie within [-180, 180] deg")
        return value


class DockingSection(Section):
    """Admissible docking set (Table 1): |x|,|y| <= position_m, |vx|,|vy| <= velocity_mps,
    |theta| <= angle_deg, |omega| <= rate_deg_s."""

    position_m: Annotated[float, Field(gt=0.0)] = Field(0.1, description="docked when |x|, |y| <= this")
    velocity_mps: Annotated[float, Field(gt=0.0)] = Field(0.2, description="docked when |vx|, |vy| <= this")
    angle_deg: Annotated[float, Field(gt=0.0)] = Field(2.0, description="docked when |theta| <= this")
    rate_deg_s: Annotated[float, Field(gt=0.0)] = Field(1.0, description="docked when |omega| <= this")


class InitialStateSection(Section):
    """Initial planar state s0 = [x, y, theta, vx, vy, omega] (Hill x radial, y along-track;
    theta counter-clockwise from the Hill x axis)."""

    x_m: float = Field(description="initial radial position (within limits.position_m)")
    y_m: float = Field(description="initial along-track position (within limits.position_m)")
    theta_deg: float = Field(0.0, description="initial attitude, counter-clockwise from Hill x, within [-180, 180]")
    vx_mps: float = Field(0.0, description="initial radial velocity")
    vy_mps: float = Field(0.0, description="initial along-track velocity")
    omega_deg_s: float = Field(0.0, description="initial body rate")

    @field_validator("theta_deg")
    @classmethod
    def _angle_range(cls, value):
        if not -180.0 <= value <= 180.0:
            raise ValueError("initial angle must lie within [-180, 180] deg")
        return value


class ControllerSection(Section):
    """NMPC settings. ``horizon`` H in steps of ``dt_s`` (Table 1: 2 s); ``average_window`` N of
    eq. 14; weights ``q`` on [x, y, theta, vx, vy, omega] (SI, rad) and ``r`` on
    [thrust N, wheel_acc rad/s^2] (the paper gives none: documented choice);
    ``terminal_weight`` P = terminal_weight * Q and ``terminal_box_fraction`` (general variant:
    s_H = 0 of eq. 9 is enforced as |s_H| <= fraction * docking set; 0 gives the exact
    equality, which is degenerate at the origin, see proxops.control.nmpc_underactuated)."""

    variant: Literal["averaged", "general"] = Field(
        "averaged", description="averaged-value NMPC (eq. 14) or the general NMPC with terminal constraint (eq. 9)")
    horizon: Horizon = Field(30, description="prediction horizon H in steps of dt_s")
    dt_s: Annotated[float, Field(gt=0.0)] = Field(2.0, description="NMPC and engine sample time (Table 1: 2 s)")
    average_window: Annotated[int, Field(ge=1, le=1000)] = Field(10, description="averaging window N of eq. 14, in steps")
    q: Annotated[list[Annotated[float, Field(ge=0.0)]], Field(min_length=6, max_length=6)] = Field(
        [1.0, 1.0, 10.0, 10.0, 10.0, 1000.0], description="state weights on [x, y, theta, vx, vy, omega] (SI, rad)")
    r: Annotated[list[Annotated[float, Field(gt=0.0)]], Field(min_length=2, max_length=2)] = Field(
        [1.0e-2, 1.0e-6], description="input weights on [thrust N, wheel acceleration rad/s^2]")
    terminal_weight: Annotated[float, Field(ge=0.0)] = Field(
        10.0, description="terminal weight P = terminal_weight * Q")
    terminal_box_fraction: Annotated[float, Field(ge=0.0, le=1.0)] = Field(
        0.1, description="general variant: |s_H| <= fraction x docking set (0: the exact s_H = 0)")
    solver: Literal["fatrop", "ipopt"] = Field("fatrop", description="NLP solver (through CasADi)")
    model_substeps: Annotated[int, Field(ge=1, le=100)] = Field(1, description="RK4 substeps per sample in the prediction model")
    max_iter: Annotated[int, Field(ge=1, le=100_000)] = Field(200, description="NLP iteration limit per warm-started solve (5x when cold)")


class RunSection(Section):
    """One closed loop of a multi-run scenario; unset keys come from [controller]/[deputy]."""

    label: Annotated[str, Field(min_length=1, pattern=r"^[A-Za-z0-9_.-]+$")] = Field(
        description="name of this run (output subfolder, summary key)")
    variant: Literal["averaged", "general"] | None = Field(None, description="NMPC variant (none: controller.variant)")
    horizon: Horizon | None = Field(None, description="horizon H (none: controller.horizon)")
    damping_Nms: Annotated[float, Field(ge=0.0)] | None = Field(
        None, description="damping c (none: deputy.damping_Nms)")


@register_scenario("underactuated")
class UnderactuatedScenario(ScenarioBase):
    actuator: ActuatorSection = Field(ActuatorSection(), description="not used by this system (its input limits are "
                                      "in [limits]): leave it out")
    deputy: DeputySection = Field(DeputySection(), description="deputy parameters")
    limits: LimitsSection = Field(LimitsSection(), description="state and input limits")
    docking: DockingSection = Field(DockingSection(), description="admissible docking set")
    initial_state: InitialStateSection = Field(description="initial planar state")
    controller: ControllerSection = Field(ControllerSection(), description="NMPC settings")
    runs: Annotated[list[RunSection], Field(max_length=20)] = Field([], description="closed loops to run, as [[runs]] tables (none: one run "
                                   "with [controller]); the first is the main one")

    @model_validator(mode="after")
    def _consistent(self):
        s0 = self.initial_state
        lim = self.limits
        for key, value, bounds in (
            ("x_m", s0.x_m, lim.position_m),
            ("y_m", s0.y_m, lim.position_m),
            ("theta_deg", s0.theta_deg, lim.angle_deg),
            ("vx_mps", s0.vx_mps, lim.velocity_mps),
            ("vy_mps", s0.vy_mps, lim.velocity_mps),
            ("omega_deg_s", s0.omega_deg_s, lim.rate_deg_s),
        ):
            if not bounds[0] <= value <= bounds[1]:
                unit = unit_of(key)
                raise ValueError(f"initial_state.{key} = {value} {unit} is outside the limits {bounds} {unit} "
                                 "([limits] section)")
        if self.actuator != ActuatorSection():
            raise ValueError("[actuator] is not used by the underactuated system: its limits are in [limits]")
        labels = [r.label for r in self.runs]
        if len(set(labels)) != len(labels):
            raise ValueError(f"runs: labels must be unique, got {labels}")
        return self


# --------------------------------------------------------------------------- model objects and the build-free check
# (used by the build, proxops.systems.underactuated, and by the check below: one definition)
DEG = math.pi / 180.0


def initial_vector(s0: InitialStateSection) -> np.ndarray:
    """The plant's initial state [x, y, theta, vx, vy, omega] (SI, rad) of [initial_state]."""
    return np.array([s0.x_m, s0.y_m, s0.theta_deg * DEG, s0.vx_mps, s0.vy_mps, s0.omega_deg_s * DEG])


def run_configs(sc: UnderactuatedScenario) -> list[dict]:
    """The closed loops of a scenario: label, variant, horizon, damping (SI)."""
    c, d = sc.controller, sc.deputy
    if not sc.runs:
        return [{"label": c.variant, "variant": c.variant, "horizon": c.horizon, "damping_Nms": d.damping_Nms}]
    return [
        {
            "label": r.label,
            "variant": r.variant or c.variant,
            "horizon": r.horizon or c.horizon,
            "damping_Nms": d.damping_Nms if r.damping_Nms is None else r.damping_Nms,
        }
        for r in sc.runs
    ]


def model_objects(sc: UnderactuatedScenario, damping_Nms: float | None = None):
    """(params, limits, docking set) in SI units from the scenario."""
    d, lim, dock = sc.deputy, sc.limits, sc.docking
    params = PlanarCubeSatParams(
        mass_kg=d.mass_kg,
        wheel_inertia_kgm2=d.wheel_inertia_kgm2,
        body_inertia_kgm2=d.body_inertia_kgm2,
        mean_motion_rad_s=d.mean_motion_rad_s,
        damping_Nms=d.damping_Nms if damping_Nms is None else damping_Nms,
    )

    def interval(b, scale=1.0):
        return Interval(b[0] * scale, b[1] * scale)

    limits = PlanarLimits(
        thrust=interval(lim.thrust_N),
        wheel_acc=interval(lim.wheel_acc_deg_s2, DEG),
        position=interval(lim.position_m),
        velocity=interval(lim.velocity_mps),
        angle=interval(lim.angle_deg, DEG),
        rate=interval(lim.rate_deg_s, DEG),
        angular_acc=interval(lim.angular_acc_deg_s2, DEG),
    )
    docking = DockingSet(dock.position_m, dock.velocity_mps, dock.angle_deg * DEG, dock.rate_deg_s * DEG)
    return params, limits, docking


@register_check("underactuated")
def check(sc: UnderactuatedScenario) -> bool:
    """The build's checks (:func:`proxops.systems.underactuated.build_setup`, first run) without
    building: the model objects and the plant (:mod:`proxops.dynamics.planar_cubesat`: their own
    checks) and the run's step count on ``controller.dt_s``. The NMPC settings check nothing the
    schema has not. False (build) with the ekf (the planar pose filter)."""
    if sc.navigation.model == "ekf":
        return False
    params, _, _ = model_objects(sc, run_configs(sc)[0]["damping_Nms"])
    PlanarCubeSatPlant(params, initial_vector(sc.initial_state))
    step_count(sc.controller.dt_s, None, None, (), sc.sim.duration_s)  # no actuator model: every sample
    return True
