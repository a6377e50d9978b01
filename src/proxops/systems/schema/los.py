"""Scenario schema of the ``los`` system (:mod:`proxops.systems.los`)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field

from proxops.errors import input_error
from proxops.scenarios.registry import register_check, register_scenario
from proxops.scenarios.schema import OrbitSection, ScenarioBase, Section, TruthSection, Vector3
from proxops.sim.steps import step_count
from proxops.systems.schema._build_free import actuator_model, plant_checked


class TargetSection(Section):
    """Tumbling target and its docking corridor (Table 1)."""

    tumble_rate_deg_s: Annotated[float, Field(ge=0.0, le=30.0)] = Field(
        2.0, description="target tumble rate w_t about the orbit normal")
    initial_angle_deg: float = Field(0.0, description="angle of the body frame F_B about the orbit normal from F_L at t = 0")
    corridor_half_angle_deg: Annotated[float, Field(gt=0.0, lt=90.0)] = Field(
        30.0, description="LOS corridor half-angle alpha_c about the docking axis +y_B")
    corridor_faces: Annotated[int, Field(ge=3, le=64)] = Field(
        8, description="half-spaces approximating the corridor cone (eq. 9)")
    corridor_floor_m: Annotated[float, Field(ge=0.0)] = Field(
        1.0, description="corridor floor y_B >= y_min (eq. 9)")


class ChaserSection(Section):
    """Thrust authority and initial state. ``initial_velocity_frame``: "body" means the
    velocity is given in F_B (zero = co-rotating with the target, §9 IC sampling);
    "lvlh" means it is the Hill-frame relative velocity (zero = LVLH-stationary)."""

    a_max_mps2: Annotated[float, Field(gt=0.0, le=10.0)] = Field(
        0.1, description="chaser acceleration limit per body axis (input box)")
    initial_body_position_m: Vector3 = Field(
        [0.0, 150.0, 0.0], description="initial chaser position in the target body frame F_B")
    initial_velocity_mps: Vector3 = Field([0.0, 0.0, 0.0], description="initial chaser velocity, in initial_velocity_frame")
    initial_velocity_frame: Literal["body", "lvlh"] = Field(
        "body", description="body: velocity in F_B (zero = co-rotating); lvlh: Hill relative velocity")


class MpcSection(Section):
    """Eq. (11). ``config``: "single" (N_p = 40, R_du = 1e4 I) or "monte-carlo"
    (N_p = 20, R_du = diag(1e5, 1e4, 1e5)), §6; ``horizon`` overrides N_p."""

    config: Literal["single", "monte-carlo"] = Field(
        "single", description="single: N_p = 40, R_du = 1e4 I; monte-carlo: N_p = 20, R_du = diag(1e5, 1e4, 1e5) (§6)")
    horizon: Annotated[int, Field(ge=1, le=200)] | None = Field(
        None, description="prediction horizon N_p in steps (none: from config)")
    constraint_mode: Literal["hard", "soft"] = Field(
        "hard", description="corridor as hard constraints or soft with a penalised slack")
    slack_penalty: Annotated[float, Field(gt=0.0)] = Field(1e7, description="soft mode: weight on the corridor slack")


class GuidanceSection(Section):
    """§7 regimes (documented defaults; the paper gives no values)."""

    hold_range_m: Annotated[float, Field(gt=0.0)] | None = Field(
        None, description="hold point range r_h on the docking axis (none: min(10, max(2, a_max / (2 w_t^2))))")
    hold_band_m: Annotated[float, Field(gt=0.0)] = Field(1.0, description="hold is reached within this of r_h (eps_h)")
    v_switch_mps: Annotated[float, Field(gt=0.0)] = Field(
        0.05, description="hold is reached below this body-frame speed")
    v_max_mps: Annotated[float, Field(gt=0.0)] = Field(1.0, description="largest reference approach speed")
    pd_period_s: Annotated[float, Field(gt=0.0)] = Field(
        2 * math.pi / 0.05, description="natural period of the PD loops (2 pi / 0.05 rad/s)")
    use_mpc: bool = Field(True, description="filter the PD command through the eq.-(11) MPC (false: PD only)")
    stop_on_infeasible: bool = Field(True, description="end the run when the hard-constrained QP is infeasible (§9.3)")
    stop_at_hold: bool = Field(False, description="end the run when hold is reached (faster campaigns)")


@register_scenario("los")
class LosScenario(ScenarioBase):
    orbit: OrbitSection = Field(description="target orbit (Table 1: 500 km circular)")
    truth: TruthSection = Field(TruthSection(), description="truth model")
    target: TargetSection = Field(TargetSection(), description="tumbling target and corridor")
    chaser: ChaserSection = Field(ChaserSection(), description="chaser authority and initial state")
    mpc: MpcSection = Field(MpcSection(), description="eq.-(11) MPC")
    guidance: GuidanceSection = Field(GuidanceSection(), description="§7 guidance regimes")


def check_settings(sc: LosScenario) -> None:
    """What the build needs beyond the schema's ranges: an ECI truth for the target's attitude (not the
    linear CW one) and PD gains kp = (2 pi / pd_period_s)^2 that are numbers (a period below ~1e-153 s
    overflowed into an internal error)."""
    if sc.truth.model == "cw":
        raise input_error("truth.model", "cw", "the los system needs an ECI truth for the target attitude: "
                          "allowed: j2, two-body")
    frequency = 2 * math.pi / sc.guidance.pd_period_s
    if not math.isfinite(frequency * frequency):
        raise input_error("guidance.pd_period_s", sc.guidance.pd_period_s,
                          "too short: the PD gain kp = (2 pi / pd_period_s)^2 overflows", "s")


@register_check("los")
def check(sc: LosScenario) -> bool:
    """The build's checks (:func:`proxops.systems.los.build_setup`) without building: its
    :func:`check_settings`, the target orbit (:func:`plant_checked`), the actuator and the run's step
    count on ``sim.dt_s`` (default 1 s). The corridor, MPC and guidance settings check nothing the
    schema has not. False (build) with the ekf (the attitude filter) or the full truth (its integrator)."""
    if sc.navigation.model == "ekf" or sc.truth.model == "full":
        return False
    check_settings(sc)
    plant_checked(sc.orbit, sc.truth)
    step_count(sc.sim.dt_s or 1.0, None, actuator_model(sc.actuator).period_s, (), sc.sim.duration_s)
    return True
