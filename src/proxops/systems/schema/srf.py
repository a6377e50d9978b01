"""Scenario schema of the ``srf`` system (:mod:`proxops.systems.srf`: the defaults the paper does
not give are documented there)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from proxops.constraints.keep_out import KeepOutSphere
from proxops.core.cw import mean_motion
from proxops.errors import input_error
from proxops.frames.lvlh import lvlh_vector_to_hill
from proxops.guidance.hop_times import check_trim_delay, hop_engine_steps, plan_hops
from proxops.scenarios.registry import register_check, register_scenario
from proxops.scenarios.schema import InitialSection, OrbitSection, ScenarioBase, Section, TruthSection, Vector3
from proxops.sim.steps import step_count
from proxops.systems.schema._build_free import actuator_model, initial_hill_state, plant_checked


class ApproachSection(Section):
    """Guidance expert inputs (Algorithm 1). ``angle_deg`` from the V-bar towards the R-bar."""

    angle_deg: Annotated[float, Field(ge=-360.0, le=360.0)] = Field(
        0.0, description="approach axis from the V-bar towards the R-bar (0 V-bar, 90 R-bar, else glideslope; "
        "180-360 or negative: the other quadrants, e.g. 250 as in Fig. 9b)")
    hops: Annotated[int, Field(ge=1, le=50)] = Field(3, description="number of hops of Algorithm 1")
    gamma: Annotated[float, Field(gt=0.0, lt=1.0)] = Field(
        0.5, description="hop-length ratio of Algorithm 1 (each hop gamma times the previous)")
    start_m: Annotated[float, Field(gt=0.0)] = Field(2000.0, description="start distance along the approach axis")
    end_m: Annotated[float, Field(gt=0.0)] = Field(
        100.0, description="reference point distance where the approach ends (Table 2: 0.1 km); < start_m")
    vbar_period_fraction: Annotated[float, Field(gt=0.0, lt=1.0)] = Field(
        0.5, description="V-bar hop time as a fraction of the orbit period, eq. (8) (0.6 in §5.4)")

    @model_validator(mode="after")
    def _end_before_start(self):
        if self.end_m >= self.start_m:
            raise ValueError(f"approach.end_m = {self.end_m} m must be < approach.start_m = {self.start_m} m")
        return self


class SrfMpcSection(Section):
    """Problem (29) settings (SI). ``None`` means the documented per-approach default."""

    steps_per_hop: Annotated[int, Field(ge=1, le=100)] | None = Field(
        None, description="MPC nodes per hop (none: 6, or horizon_steps // hops)")
    horizon_steps: Annotated[int, Field(ge=1, le=1000)] | None = Field(
        None, description="maximum MPC horizon N in nodes (none: hops x steps_per_hop)")
    q_terminal_per_m2: Annotated[float, Field(gt=0.0)] = Field(
        1e-3, description="terminal position weight Q = q I of (29a) (cost in m/s units)")
    r_fuel: Annotated[float, Field(gt=0.0)] = Field(1.0, description="weight R on the l1 norm of the impulses (29a)")
    mid_hop_fuel_weight: Annotated[float, Field(ge=1.0)] | None = Field(
        None, description="fuel weight of impulses between hop instants (none: 1 V-bar, 2 others)")
    u_max_mps: Annotated[float, Field(gt=0.0)] = Field(3.0, description="impulse limit per axis (29e-f)")
    u_budget_mps: Annotated[float, Field(gt=0.0)] | None = Field(
        None, description="cumulative l1 delta-v budget (29g) (none: unlimited)")
    terminal_pos_tol_m: Annotated[float, Field(gt=0.0)] = Field(
        2.0, description="terminal box on the position error at the reference point (29d)")
    terminal_vel_tol_mps: Annotated[float, Field(gt=0.0)] = Field(
        0.005, description="terminal box on the velocity after the braking impulse (29d)")
    r_tol_m: Annotated[float, Field(gt=0.0)] = Field(1.0, description="hop-end offset from the approach axis (29l)")
    w_tol_mps: Annotated[float, Field(gt=0.0)] = Field(
        0.002, description="hop-end along-axis velocity tolerance (29m, on the rotated velocity w)")
    h_min_m: Annotated[float, Field(ge=0.0)] = Field(0.0, description="V-bar: shortest hop length (29n)")
    h_max_m: Annotated[float, Field(gt=0.0)] | None = Field(
        None, description="V-bar: longest hop length (29n) (none: approach.start_m)")
    epsilon_m: Annotated[float, Field(ge=0.0)] = Field(
        50.0, description="V-bar: each hop shorter than the previous by at least this (29o, corrected sign)")
    hop_distance_tol_frac: Annotated[float, Field(gt=0.0)] | None = Field(
        None, description="hop ends within this fraction of the hop length of Algorithm 1's distances "
        "(none: off for V-bar, 0.1 others)")
    hop_distance_weight_per_m2: Annotated[float, Field(ge=0.0)] | None = Field(
        None, description="quadratic pull of hop ends towards Algorithm 1's distances (none: 1e-7 V-bar, 0 others)")
    drift_free: bool = Field(
        True, description="V-bar: |vy+ + 2 n x| (J2-aware energy form on J2 truth) <= drift_free_tol_mps after every "
        "hop-start impulse, so the free drift returns to the hop start (not in the paper; its indefinite hold)")
    drift_free_tol_mps: Annotated[float, Field(gt=0.0)] = Field(
        5e-5, description="V-bar drift-free row tolerance (5e-5 m/s: 1.1 m of drift per orbit at a = 8100 km)")
    drift_outward_mps: Annotated[float, Field(ge=0.0)] = Field(
        0.0, description="V-bar drift rows: ONE-SIDED band, the invariant after a hop-start or trim impulse must give a "
        "drift away from the target by at least this (m/s of c = vy + 2 n x; 3 c t_orb of along-track drift per orbit) "
        "and at most this + 2 drift_free_tol_mps (the two-sided row sat on its inward edge)")
    drift_trim: bool = Field(
        True, description="V-bar (with drift_free): a drift-free row also at a trim node after every hop start, so "
        "the MPC nulls the drift left by the hop impulse's execution errors and its single-sample estimate with a "
        "small trim impulse (raised to actuator.min_impulse if below it); the passive-abort drift starts after it")
    drift_hold_after_trim: bool = Field(
        False, description="V-bar with drift_trim: every later impulse of the hop keeps the trimmed drift invariant "
        "(within drift_free_tol_mps; relaxed with the design rows), so the free drift stays null after any of them "
        "(off: in the Monte Carlo it forces costly radial-only corrections)")
    drift_trim_delay_nodes: Annotated[int, Field(ge=1, le=99)] = Field(
        1, description="MPC nodes from a hop start to its trim (1: the next node, 1/steps_per_hop of a hop later)")
    drift_estimator_window_s: Annotated[float, Field(gt=0.0)] | None = Field(
        None, description="the drift invariant is averaged over the navigation samples of this window before a "
        "node (none: every sample since the last impulse)")
    solver: Literal["piqp", "clarabel", "daqp"] = Field("piqp", description="QP solver of problem (29)")


class KeepOutSection(Section):
    """Spherical KOZ (eq. 26) and its CBF (eqs. 27-29j). ``center_m`` in the paper's LVLH."""

    radius_m: Annotated[float, Field(gt=0.0)] = Field(50.0, description="keep-out sphere radius (eq. 26)")
    center_m: Vector3 = Field([0.0, 0.0, 0.0], description="keep-out sphere centre in the paper's LVLH")
    cbf: bool = Field(True, description="enforce the control barrier function on the free drift (27-29j)")
    alpha_per_s: Annotated[float, Field(gt=0.0)] = Field(0.01, description="CBF class-K gain alpha (29j)")
    margin_m: Annotated[float, Field(ge=0.0)] = Field(
        10.0, description="the MPC plans against radius + margin (CW, navigation and J2 mismatch)")
    free_drift_orbits: Annotated[float, Field(gt=0.0, le=5.0)] = Field(
        1.0, description="passive-abort free-drift horizon checked by the MPC, in orbits")
    free_drift_nodes_per_orbit: Annotated[int, Field(ge=4, le=1000)] = Field(
        36, description="free-drift samples per orbit (29h-i)")
    compare_without_cbf: bool = Field(False, description="run twice, with and without the CBF (§5.4)")


class SafetySection(Section):
    """Per-run safety and success evaluation."""

    reference_tolerance_m: Annotated[float, Field(gt=0.0)] = Field(
        5.0, description="success: final distance to the reference point at most this")
    abort_orbits: Annotated[float, Field(ge=1.0, le=50.0)] = Field(
        5.0, description="passive-abort check on the truth: free drift from every hop state over this many orbits "
        "(the window of the passive-safety certificate)")
    abort_samples_per_orbit: Annotated[int, Field(ge=10, le=100000)] = Field(
        720, description="samples per orbit of each passive-abort drift")
    abort_required_orbits: Annotated[float, Field(gt=0.0, le=10.0)] | None = Field(
        None, description="window that counts for success (none: all of abort_orbits for V-bar, the indefinite "
        "hold of §2; 1 orbit for R-bar and glideslopes, which the paper says lack indefinite safety, §5.2)")


@register_scenario("srf")
class SrfScenario(ScenarioBase):
    orbit: OrbitSection = Field(description="target orbit")
    truth: TruthSection = Field(TruthSection(), description="truth model")
    initial: InitialSection | None = Field(
        None, description="initial chaser state (none: at rest on the approach axis at approach.start_m)")
    approach: ApproachSection = Field(ApproachSection(), description="hop guidance (Algorithm 1)")
    mpc: SrfMpcSection = Field(SrfMpcSection(), description="hopping MPC, problem (29)")
    keep_out: KeepOutSection = Field(KeepOutSection(), description="keep-out zone and CBF")
    safety: SafetySection = Field(SafetySection(), description="success and passive-abort evaluation")


# --------------------------------------------------------------------------- geometry and feasibility
# (used by the build, proxops.systems.srf, and by the build-free check below: one definition)
ENGINE_STEPS_PER_ORBIT = 720


def _is_vbar(theta: float) -> bool:
    return abs(math.sin(theta)) < 1e-9


def approach_axes_hill(theta: float) -> tuple[np.ndarray, np.ndarray]:
    """Approach direction e_A and perpendicular e_perp2 of eq. (20), as Hill unit vectors."""
    a = lvlh_vector_to_hill(np.array([math.cos(theta), 0.0, math.sin(theta)]))
    b = lvlh_vector_to_hill(np.array([-math.sin(theta), 0.0, math.cos(theta)]))
    return a, b


def initial_state_hill(sc: SrfScenario) -> np.ndarray:
    if sc.initial is not None:
        return initial_hill_state(sc.initial)
    a, _ = approach_axes_hill(math.radians(sc.approach.angle_deg))
    return np.concatenate([sc.approach.start_m * a, np.zeros(3)])


def engine_dt(sc: SrfScenario) -> float:
    period = 2 * math.pi / mean_motion(sc.orbit.sma_m)
    return sc.sim.dt_s if sc.sim.dt_s is not None else period / ENGINE_STEPS_PER_ORBIT


def keep_out_hill(sc: SrfScenario):
    return KeepOutSphere(sc.keep_out.radius_m, lvlh_vector_to_hill(np.array(sc.keep_out.center_m)), name="keep_out")




def _check_vbar_hop_lengths(ap, m) -> None:
    """Rows (29n)-(29o) admit hop lengths L_1..L_N with h_min <= L_j <= h_max, L_{j+1} <= L_j - epsilon and
    sum L_j = start - end only if N h_min + epsilon N(N-1)/2 <= start - end <= N h_max - epsilon N(N-1)/2
    (the shortest and longest such sequences); otherwise every MPC step would need relaxed rows."""
    n, total = ap.hops, ap.start_m - ap.end_m
    h_max = m.h_max_m if m.h_max_m is not None else ap.start_m
    ladder = m.epsilon_m * n * (n - 1) / 2.0
    if n * m.h_min_m + ladder > total:
        most = (total - n * m.h_min_m) / (n * (n - 1) / 2.0) if n > 1 else math.inf
        raise input_error("mpc.epsilon_m", m.epsilon_m,
                          f"{n} V-bar hops over {total:g} m cannot each shrink by {m.epsilon_m:g} m (29o) with "
                          f"h_min_m = {m.h_min_m:g} m: give epsilon_m <= {most:.4g}, fewer hops or a lower h_min_m", "m")
    if n * h_max - ladder < total:
        raise input_error("mpc.h_max_m", h_max,
                          f"{n} V-bar hops of at most {h_max:g} m shrinking by {m.epsilon_m:g} m cannot cover "
                          f"{total:g} m: raise h_max_m, add hops or lower epsilon_m", "m")


def mpc_steps_per_hop(sc: SrfScenario) -> int:
    """MPC nodes per hop (``mpc.steps_per_hop`` or its documented default); every hop needs one node
    and the shrinking horizon must cover the approach."""
    ap, m = sc.approach, sc.mpc
    if m.horizon_steps is not None and ap.hops > m.horizon_steps:
        raise input_error("approach.hops", ap.hops,
                          f"more hops than the MPC horizon holds (mpc.horizon_steps = {m.horizon_steps}); every hop "
                          "needs at least one MPC step: lower hops or raise horizon_steps")
    steps = m.steps_per_hop
    if steps is None:
        steps = 6 if m.horizon_steps is None else max(1, min(6, m.horizon_steps // ap.hops))
    if m.horizon_steps is not None and steps * ap.hops > m.horizon_steps:
        raise input_error("mpc.steps_per_hop", steps,
                          f"hops x steps_per_hop = {steps * ap.hops} exceeds mpc.horizon_steps = {m.horizon_steps} "
                          "(the shrinking horizon must cover the whole approach)")
    return steps


def check_mission(sc: SrfScenario, mission_s: float, dt: float) -> None:
    """The approach fits the run (``sim.duration_s`` >= the ``mission_s`` of the node schedule) and the
    keep-out zone: start, start point and reference point outside it, the V-bar hop ladder (29n-o)
    feasible, the reference point outside the planning radius (KOZ + margin)."""
    ap, m, ko = sc.approach, sc.mpc, sc.keep_out
    theta = math.radians(ap.angle_deg)
    if sc.sim.duration_s < mission_s:
        raise input_error("sim.duration_s", sc.sim.duration_s,
                          f"shorter than the {ap.hops}-hop approach ({mission_s:.1f} s): use >= {mission_s + 2 * dt:.0f}", "s")
    a, _ = approach_axes_hill(theta)
    koz = keep_out_hill(sc)
    x0 = initial_state_hill(sc)
    if koz.contains(x0[:3]):
        raise input_error("initial position", np.round(x0[:3], 3).tolist(),
                          f"starts inside the keep-out zone (radius {koz.radius_m:g} m): move the start or shrink keep_out.radius_m", "m")
    if koz.contains(ap.start_m * a):
        raise input_error("approach.start_m", ap.start_m,
                          f"the start point lies inside the keep-out zone (radius {koz.radius_m:g} m)", "m")
    target = ap.end_m * a
    if koz.contains(target):
        raise input_error("approach.end_m", ap.end_m,
                          f"the reference point lies inside the keep-out zone (radius {koz.radius_m:g} m): "
                          "raise end_m or shrink keep_out.radius_m", "m")
    if _is_vbar(theta):
        _check_vbar_hop_lengths(ap, m)
    if ko.margin_m > 0 and np.linalg.norm(target - koz.center_m) <= koz.radius_m + ko.margin_m:
        raise input_error("keep_out.margin_m", ko.margin_m,
                          f"the reference point ({ap.end_m:g} m out) must lie outside the KOZ radius + margin "
                          f"({koz.radius_m + ko.margin_m:g} m)", "m")


def _schedule_end_s(durations_s, steps_per_hop: int, dt: float) -> float:
    """The last node time of :func:`proxops.control.srf_mpc.build_schedule` (s), and its check."""
    return float(sum(hop_engine_steps(durations_s, steps_per_hop, dt)) * dt)


@register_check("srf")
def check(sc: SrfScenario) -> bool:
    """The build's checks (:func:`proxops.systems.srf.build_setup`) without building: Algorithm 1's
    plan (:func:`proxops.guidance.hop_times.plan_hops`: its infeasible band), the node schedule, the
    mission and keep-out geometry (:func:`check_mission`), the drift-trim node, the plant, actuator and
    the run's step count. False (build) with the ekf or the full truth."""
    if sc.navigation.model == "ekf" or sc.truth.model == "full":
        return False
    ap, m = sc.approach, sc.mpc
    plan = plan_hops(math.radians(ap.angle_deg), ap.hops, ap.gamma, ap.start_m, ap.end_m, mean_motion(sc.orbit.sma_m),
                     vbar_period_fraction=ap.vbar_period_fraction)
    steps = mpc_steps_per_hop(sc)
    dt = engine_dt(sc)
    mission_s = _schedule_end_s(plan.durations_s, steps, dt)
    check_mission(sc, mission_s, dt)
    if _is_vbar(math.radians(ap.angle_deg)) and m.drift_free and m.drift_trim:
        check_trim_delay(m.drift_trim_delay_nodes, 0, steps)  # SrfMpc: the first hop (nodes 0..steps) fails first
    plant_checked(sc.orbit, sc.truth)
    actuator = actuator_model(sc.actuator)
    step_count(dt, None, actuator.period_s, (), mission_s + dt)  # the controller's period: the engine step
    return True
