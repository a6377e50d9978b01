"""Scenario schema of the ``srf`` system (:mod:`proxops.systems.srf`: the defaults the paper does
not give are documented there)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from proxops.scenarios.registry import register_scenario
from proxops.scenarios.schema import InitialSection, OrbitSection, ScenarioBase, Section, TruthSection, Vector3


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
