"""Scenario schema of the ``hybrid`` system (:mod:`proxops.systems.hybrid`). Its physics checks
(:func:`model_objects`) construct the model objects of proxops.dynamics.two_rigid_bodies and
proxops.propagation.hybrid_plant (numba), imported only when a hybrid scenario is validated."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, model_validator

from proxops.core.constants import MU_EARTH, R_EARTH
from proxops.errors import ProxopsInputError
from proxops.scenarios.registry import register_scenario
from proxops.scenarios.schema import ActuatorSection, ScenarioBase, Section


Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Quaternion = Annotated[list[float], Field(min_length=4, max_length=4)]
Matrix3 = Annotated[list[Vector3], Field(min_length=3, max_length=3)]
Positive = Annotated[float, Field(gt=0.0)]
NonNegative = Annotated[float, Field(ge=0.0)]


class BodySection(Section):
    """One rigid body (§VII): constant-density cuboid; inertia and docking port default to
    the cuboid's (port at the centre of the docking face: chief +y, deputy -y)."""

    mass_kg: Positive = Field(description="mass")
    dims_m: Vector3 = Field(description="cuboid edges along the body x, y, z axes")
    inertia_kgm2: Matrix3 | None = Field(None, description="inertia matrix about the CoM in body axes, symmetric "
                                         "positive definite, moments obeying the triangle inequality "
                                         "(none: the constant-density cuboid's)")
    port_m: Vector3 | None = Field(None, description="docking port from the CoM in body axes, on or inside the "
                                   "cuboid (none: centre of the docking face, chief +y / deputy -y)")


class InitialRelativeSection(Section):
    """Initial relative state, eq. (78) of §VII (the paper's variables)."""

    rho0_m: Vector3 = Field([2.0, 0.0, 0.0], description="rho_0: deputy CoM minus chief CoM, in T (Hill)")
    rho0_dot_mps: Vector3 = Field([-0.081, 0.011, 0.0133], description="T-frame derivative of rho_0, in T")
    omega_rad_s: Vector3 = Field([0.09, 0.06, 0.009], description="omega = omega_{D/C} in D")
    q: Quaternion = Field([0.5773502691896258, 0.5773502691896258, 0.5773502691896258, 0.0],
                          description="attitude of D relative to C, [qx, qy, qz, qw] scalar last, unit norm "
                          "(eq. 78 prints 0.57 [1, 1, 1, 0], norm 0.987: normalised here)")
    p: Quaternion = Field([-0.5, 0.5, 0.5, 0.5], description="attitude of C relative to T, scalar last, unit norm")
    omega_c_rad_s: Vector3 = Field([-0.0024, 0.0024, -0.0024], description="chief tumble omega_c = omega_{C/T} in C")


class ContactSection(Section):
    """Cuboid contacts in the capture phase (eqs. 33-39)."""

    restitution: float = Field(0.5, description="Newton coefficient of restitution e in [0, 1] (the paper gives "
                               "none; 0.5: a partly plastic metal contact)")
    max_substep_s: Positive = Field(0.05, description="plant integration substep; the contact guard is checked at "
                                    "each substep end and located by bisection")
    collision_gap_s: NonNegative = Field(1.0, description="contacts closer in time than this to the previous one "
                                         "belong to the same collision (collision count c of eq. 80)")


class LatchSection(Section):
    """Spring-damper latch (eq. 81) and the scripted latch snap (§VII)."""

    # Defaults: the built-ins' latch, not eq. 81's 5/2/5/2, which cannot hold the pair against the
    # +-5 N / +-5 N m post-capture bounds (static deflection 0.75 m and 0.9 rad; the §VII run with it
    # ends failed, tests/test_hybrid_system.py). Ours: <= 5 mm and <= 0.5 deg under the bounds.
    stiffness_N_per_m: Positive = Field(750.0, description="K_T, translational stiffness (eq. 81 prints 5)")
    damping_Ns_per_m: Positive = Field(520.0, description="D_T, translational damping (eq. 81 prints 2)")
    rot_stiffness_Nm_per_rad: Positive = Field(550.0, description="K_R, torsional stiffness (eq. 81 prints 5)")
    rot_damping_Nms_per_rad: Positive = Field(150.0, description="D_R, torsional damping (eq. 81 prints 2)")
    snap: bool = Field(True, description="apply the latch-snap impulse at snap_time_s (if latched then)")
    snap_time_s: NonNegative = Field(593.0, description="time of the latch snap (§VII: about 593 s)")
    snap_impulse_Ns: NonNegative = Field(0.05, description="snap impulse along rho_0 (§VII: 0.05 N s)")
    rearm_delay_s: NonNegative = Field(10.0, description="after a snap the latch can engage again only this much "
                                       "later (re-docking)")


class DockingSection(Section):
    """Transition sets of the supervisor: T_{0->1} (capture envelope, where the latch also
    engages) and T_{1->0}; the paper gives no numbers (our choice)."""

    position_m: Positive = Field(0.02, description="T_{0->1}: |rho| at most this")
    velocity_mps: Positive = Field(0.01, description="T_{0->1}: |rho_dot| at most this")
    angle_deg: Positive = Field(2.0, description="T_{0->1}: attitude error of q from q_I at most this")
    rate_deg_s: Positive = Field(0.5, description="T_{0->1}: |omega| at most this")
    release_distance_m: Positive = Field(0.5, description="T_{1->0}: latch open or |rho| at least this "
                                         "(> position_m: the hysteresis)")
    min_dwell_s: Positive = Field(10.0, description="T_1: minimum dwell in a mode and period of the dwell timer tau")


class ControlSection(Section):
    """Actuation bounds and horizon (§VII)."""

    force_max_capture_N: Positive = Field(1.0, description="capture-phase thrust bound per axis (§VII: 1 N)")
    torque_max_capture_Nm: Positive = Field(1.0, description="capture-phase torque bound per axis (§VII: 1 N m)")
    force_max_post_N: Positive = Field(5.0, description="post-capture thrust bound per axis (§VII: 5 N)")
    torque_max_post_Nm: Positive = Field(5.0, description="post-capture torque bound per axis (§VII: 5 N m)")
    horizon_capture_s: Positive = Field(10.0, description="capture MPC horizon T^0 (§VII: 10 s)")


class CaptureMPCSection(Section):
    """Capture MPC (Problem 2) settings the scenario may change; the rest are the paper's
    (proxops.control.hybrid_mpc.CaptureMPCConfig). Weights are diagonal entries in SI."""

    period_s: Positive = Field(1.0, description="control period (not in the paper); must divide the horizon")
    R_force: Positive = Field(1e4, description="input weight on F_d while no collision (eq. 79: 1e4, per N^2)")
    R_torque: Positive = Field(1e4, description="input weight on M_d while no collision (eq. 79: 1e4, per (N m)^2)")
    approach_guidance: bool = Field(True, description="waypoints round the chief to the port axis (not in the "
                                    "paper: the eq. 78 deputy starts behind the docking face)")
    solver: Literal["daqp", "piqp", "clarabel"] = Field(
        "daqp", description="QP solver of both MPCs by name (proxops.solvers.make_solver); only DAQP keeps the rate "
        "bounds soft (on the others a measured rate beyond them makes the step fall back to the steady input)")


class ReferenceSection(Section):
    """Desired orbit x_ref of the pair's CoM (natural CW motion from this state, in T)."""

    position_m: Vector3 = Field([0.0, 0.0, 0.0], description="r_des at t = 0 (default: the chief's initial orbit)")
    velocity_mps: Vector3 = Field([0.0, 0.0, 0.0], description="r_des_dot at t = 0")


class TruthSection(Section):
    """Translational truth of both bodies and the desired orbit (the MPCs keep their CW models)."""

    gravity: str = Field("j2", description="cw: the linear model itself (eq. 21, corrected G2); twobody / j2: exact "
                         "inertial point-mass (+ J2) gravity of each CoM seen from T (proxops.core.twobody kernels)")
    inclination_deg: float = Field(51.6, ge=0.0, le=180.0, description="inclination of the chief's circular orbit "
                                   "(the paper gives none; J2 depends on it; our choice: ISS-like)")

    @model_validator(mode="after")
    def _known(self):
        from proxops.propagation.hybrid_plant import GRAVITY_MODELS

        if self.gravity not in GRAVITY_MODELS:
            raise ValueError(f"truth.gravity = {self.gravity!r}: allowed {', '.join(GRAVITY_MODELS)}")
        return self


class EstimationSection(Section):
    """What the MPCs see (proxops.navigation.hybrid.HybridNavigation). Sigmas are our choices
    (the paper assumes the chief state 'can be accurately estimated'), 1-sigma per axis."""

    model: str = Field("mekf", description="mekf: noisy relative pose + MEKF of the chief attitude and rate (both "
                       "MPCs use it); exact: the true state ([navigation] noise only, default none)")
    position_sigma_m: NonNegative = Field(2e-3, description="relative port position rho")
    velocity_sigma_mps: NonNegative = Field(5e-4, description="relative port velocity rho_dot")
    attitude_sigma_deg: NonNegative = Field(0.2, description="relative attitude q (small rotation)")
    rate_sigma_deg_s: NonNegative = Field(0.02, description="relative rate omega")
    chief_attitude_sigma_deg: Positive = Field(0.5, description="pose measurement of the chief attitude p (MEKF input)")
    com_position_sigma_m: NonNegative = Field(1e-3, description="composite CoM rho_n")
    com_velocity_sigma_mps: NonNegative = Field(1e-4, description="composite CoM velocity rho_n_dot")

    @model_validator(mode="after")
    def _known(self):
        if self.model not in ("mekf", "exact"):
            raise ValueError(f"estimation.model = {self.model!r}: allowed mekf, exact")
        return self


class SuccessSection(Section):
    """What a successful run is (judged at the END of the run) and when a run is stopped as
    diverging (checked at every sample on the true state). Our thresholds (not the paper's)."""

    chief_rate_max_deg_s: Positive = Field(0.05, description="success: chief tumble |omega_c| at the end below this "
                                           "(about 1/5 of the eq. 78 tumble, 0.238 deg/s)")
    tracking_error_max_m: Positive = Field(0.01, description="success: |rho_n - r_des| at the end below this (the "
                                           "paper claims millimetre tracking; 1 cm allows for navigation noise)")
    divergence_range_m: Positive | None = Field(None, description="stop as diverged when the port range |rho| "
                                                "exceeds this (none: 2 x the initial range + 2 m)")
    divergence_rate_deg_s: Positive = Field(30.0, description="stop as diverged when the deputy's rate relative to "
                                            "the chief |omega| exceeds this (3 x the MPC rate bound)")
    divergence_chief_rate_deg_s: Positive | None = Field(None, description="stop as diverged when the chief tumble "
                                                         "|omega_c| exceeds this (none: 2 x the initial + 2 deg/s; the post-capture MPC bound is 0.5 deg/s per axis)")


@register_scenario("hybrid")
class HybridScenario(ScenarioBase):
    actuator: ActuatorSection = Field(ActuatorSection(), description="not used by this system (bounds are in "
                                      "[control]): leave it out")
    altitude_km: Positive = Field(500.0, description="circular orbit altitude of the chief (the paper: 'low Earth "
                                  "orbit'; sets n0)")
    chief: BodySection = Field(BodySection(mass_kg=360.0, dims_m=[1.04, 1.15, 1.57]), description="chief (§VII)")
    deputy: BodySection = Field(BodySection(mass_kg=120.0, dims_m=[0.6, 0.7, 0.8]), description="deputy (§VII)")
    initial: InitialRelativeSection = Field(InitialRelativeSection(), description="initial relative state (eq. 78)")
    contact: ContactSection = Field(ContactSection(), description="contacts")
    latch: LatchSection = Field(LatchSection(), description="latch and latch snap")
    docking: DockingSection = Field(DockingSection(), description="supervisor transition sets")
    control: ControlSection = Field(ControlSection(), description="bounds and horizon")
    reference: ReferenceSection = Field(ReferenceSection(), description="desired orbit of the pair's CoM")
    capture_mpc: CaptureMPCSection = Field(CaptureMPCSection(), description="capture MPC settings")
    truth: TruthSection = Field(TruthSection(), description="translational truth model")
    estimation: EstimationSection = Field(EstimationSection(), description="navigation seen by both MPCs")
    success: SuccessSection = Field(SuccessSection(), description="success thresholds and divergence stop")

    @model_validator(mode="after")
    def _physical(self):
        """The physics checks of proxops.dynamics.two_rigid_bodies, named by scenario key."""
        if self.actuator != ActuatorSection():
            raise ValueError("[actuator] is not used by the hybrid system: its bounds are in [control]")
        model_objects(self)
        return self


_PARAM_KEYS = {  # HybridParams / HybridInitialState field -> scenario key (for error messages)
    "mass_chief_kg": "chief.mass_kg", "mass_deputy_kg": "deputy.mass_kg", "dims_chief_m": "chief.dims_m",
    "dims_deputy_m": "deputy.dims_m", "inertia_chief_kgm2": "chief.inertia_kgm2",
    "inertia_deputy_kgm2": "deputy.inertia_kgm2", "port_chief_m": "chief.port_m", "port_deputy_m": "deputy.port_m",
    "restitution": "contact.restitution", "q": "initial.q", "p": "initial.p", "rho0_m": "initial.rho0_m",
}


def _renamed(exc: Exception) -> ValueError:
    msg = str(exc)
    field_name = msg.split(" = ", 1)[0]
    key = _PARAM_KEYS.get(field_name)
    return ValueError(f"{key}{msg[len(field_name):]}" if key else msg)


def model_objects(sc: HybridScenario):
    """(HybridParams, HybridInitialState, truth x0 (26), CaptureEnvelope) of a scenario; the
    physics checks raise ValueError naming the scenario key."""
    from proxops.dynamics.two_rigid_bodies import HybridInitialState, HybridParams, truth_state_from_initial
    from proxops.propagation.hybrid_plant import CaptureEnvelope

    c, d, lt, ct = sc.chief, sc.deputy, sc.latch, sc.control
    try:
        params = HybridParams(
            mass_chief_kg=c.mass_kg, mass_deputy_kg=d.mass_kg, dims_chief_m=tuple(c.dims_m),
            dims_deputy_m=tuple(d.dims_m), inertia_chief_kgm2=c.inertia_kgm2, inertia_deputy_kgm2=d.inertia_kgm2,
            port_chief_m=c.port_m, port_deputy_m=d.port_m,
            mean_motion_rad_s=math.sqrt(MU_EARTH / (R_EARTH + sc.altitude_km * 1e3) ** 3),
            restitution=sc.contact.restitution, latch_KT=lt.stiffness_N_per_m, latch_DT=lt.damping_Ns_per_m,
            latch_KR=lt.rot_stiffness_Nm_per_rad, latch_DR=lt.rot_damping_Nms_per_rad,
            force_max_capture_N=ct.force_max_capture_N, torque_max_capture_Nm=ct.torque_max_capture_Nm,
            force_max_post_N=ct.force_max_post_N, torque_max_post_Nm=ct.torque_max_post_Nm,
            horizon_capture_s=ct.horizon_capture_s, snap_impulse_Ns=lt.snap_impulse_Ns, snap_time_s=lt.snap_time_s,
        )
        i = sc.initial
        ic = HybridInitialState(rho0_m=tuple(i.rho0_m), rho0_dot_m_s=tuple(i.rho0_dot_mps),
                                omega_rad_s=tuple(i.omega_rad_s), q=tuple(i.q), omega_c_rad_s=tuple(i.omega_c_rad_s),
                                p=tuple(i.p))
        x0 = truth_state_from_initial(params, ic)
        dk = sc.docking
        envelope = CaptureEnvelope(dk.position_m, dk.velocity_mps, math.radians(dk.angle_deg),
                                   math.radians(dk.rate_deg_s))
    except ProxopsInputError as exc:
        if str(exc).startswith("initial_state = "):
            raise ValueError(f"initial.rho0_m = {list(sc.initial.rho0_m)} m: {str(exc).split(': ', 1)[1]}") from None
        raise _renamed(exc) from None
    if not dk.release_distance_m > dk.position_m:
        raise ValueError(f"docking.release_distance_m = {dk.release_distance_m} m must be > docking.position_m = "
                         f"{dk.position_m} m (hysteresis between T_0->1 and T_1->0)")
    return params, ic, x0, envelope
