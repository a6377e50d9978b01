"""Scenario schema of the ``cortex`` system (:mod:`proxops.systems.cortex`, the closed loop
:mod:`proxops.systems.cortex_loop`)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, model_validator

from proxops.scenarios.registry import register_scenario
from proxops.scenarios.schema import (ActuatorSection, OrbitSection, Probability, ScenarioBase, Section, TruthSection,
                                      Vector3)


class ServicerSection(Section):
    """Table 2 / §5.1: m_Serv = 500 kg, a_max = 1.2 N / 500 kg = 2.4 mm/s^2."""

    mass_kg: Annotated[float, Field(gt=0.0)] = Field(500.0, description="servicer mass m_Serv (Table 2)")
    a_max_mps2: Annotated[float, Field(gt=0.0)] = Field(2.4e-3, description="thrust acceleration limit a_max (1.2 N / 500 kg, §5.1)")


class GeometrySection(Section):
    """Table 2 radii and angles; ``start_*`` is x_i1 (default [0, -r_AS/2, 0] at rest)."""

    r_rs_m: Annotated[float, Field(gt=0.0)] = Field(10_000.0, description="rendezvous-sphere radius r_RS (Table 2)")
    r_as_m: Annotated[float, Field(gt=0.0)] = Field(75.0, description="approach-sphere radius r_AS (Table 2); the fly-around starts on it")
    r_kos_m: Annotated[float, Field(gt=0.0)] = Field(15.0, description="keep-out sphere radius r_KOS (Table 2); must be < r_as_m")
    plume_half_angle_deg: Annotated[float, Field(gt=0.0, lt=90.0)] = Field(20.0, description="plume half-angle alpha_p: no thrust towards the target inside it (19d)")
    cone_half_angle_deg: Annotated[float, Field(gt=0.0, lt=90.0)] = Field(10.0, description="approach-cone half-angle alpha_c about the docking axis (20f)")
    start_position_m: Vector3 | None = Field(None, description="fly-around start x_i1 in Hill (none: [0, -r_as_m/2, 0])")
    start_velocity_mps: Vector3 = Field([0.0, 0.0, 0.0], description="fly-around start velocity in Hill (at rest by default)")
    flyaround_end_range_m: Annotated[float, Field(gt=0.0)] | None = Field(None, description="fly-around end range on the docking axis (none: the inflated KOS radius rho_bar)")
    approach_end_range_m: Annotated[float, Field(gt=0.0)] = Field(1.0, description="final-approach end range on the docking axis (x_f2 = [1 m e, 0])")
    approach_end_position_m: Vector3 | None = Field(None, description="explicit final-approach end position in Hill (overrides approach_end_range_m)")

    @model_validator(mode="after")
    def _kos_inside_approach_sphere(self):
        if self.r_kos_m >= self.r_as_m:
            raise ValueError(f"geometry.r_kos_m = {self.r_kos_m} m must be smaller than r_as_m = {self.r_as_m} m")
        return self


class MarginsSection(Section):
    """§3.1.1-3.1.2: a_bar = 0.8 a_max, rho_bar = 1.2 r_KOS, alpha_p_bar = 1.2 alpha_p, alpha_c_bar = 0.5 alpha_c."""

    thrust: float = Field(0.8, description="thrust margin: planned limit a_bar = thrust x a_max (§3.1.1: 0.8)")
    kos: float = Field(1.2, description="keep-out margin: planned radius rho_bar = kos x r_KOS (§3.1.1: 1.2)")
    plume: float = Field(1.2, description="plume margin: planned half-angle = plume x alpha_p (§3.1.2: 1.2)")
    cone: float = Field(0.5, description="cone margin: planned half-angle = cone x alpha_c (§3.1.2: 0.5)")


class PlannerSection(Section):
    """Outer search and the convex phases. Table 2: tau in [5, 60] min, eps_C = 100 (read in
    minutes, the unit of tau in Table 2; see proxops.guidance.cortex.reference), dt_CP1 = 30 s,
    dt_CP2 = 10 s."""

    tau_lb_s: Annotated[float, Field(gt=0.0)] = Field(300.0, description="shortest phase duration tau_lb searched (Table 2: 5 min)")
    tau_ub_s: Annotated[float, Field(gt=0.0)] = Field(3600.0, description="longest phase duration tau_ub searched (Table 2: 60 min)")
    tau1_s: Annotated[float, Field(gt=0.0)] | None = Field(None, description="fixed fly-around duration tau_1 of the initial plan (none: the eq. 12 search over [tau_lb_s, tau_ub_s]; regenerations always search)")
    tau2_s: Annotated[float, Field(gt=0.0)] | None = Field(None, description="fixed final-approach duration tau_2 of the initial plan (none: the eq. 12 search over [tau_lb_s, tau_ub_s]; regenerations always search)")
    convergence_penalty_s: Annotated[float, Field(ge=0.0)] = Field(6000.0, description="penalty eps_C added to J when a phase does not converge (eq. 12; 100, read in minutes)")
    dt_cp1_s: Annotated[float, Field(gt=0.0)] = Field(30.0, description="node spacing of the fly-around problem CP1 (Table 2: 30 s)")
    dt_cp2_s: Annotated[float, Field(gt=0.0)] = Field(10.0, description="node spacing of the final-approach problem CP2 (Table 2: 10 s)")
    kos_max_iter: Annotated[int, Field(ge=1, le=1000)] = Field(50, description="CP1: most re-solves adding KOS supporting planes (eq. 18) before the status 'not converged'")
    kos_arc_planes: bool = Field(False, description="CP1: also add planes at the deepest coast point between nodes (not in the paper)")
    scp_max_iter: Annotated[int, Field(ge=1, le=1000)] = Field(30, description="CP2: most successive-convexification iterations of the plume constraint (eqs. 21-22)")
    scp_tol_mps: Annotated[float, Field(gt=0.0)] = Field(1e-5, description="CP2: convergence test on the change of the impulses between iterations")
    plume_tol_deg: Annotated[float, Field(gt=0.0)] = Field(0.00573, description="CP2: plume constraint tolerance in the acceptance check")
    search: Literal["auto", "scan"] = Field("auto", description="outer search over tau: auto (doubling then halving for CP1, scan for CP2) or scan (linear scans)")
    start_delay_s: Annotated[float, Field(ge=0.0)] = Field(0.0, description="plan start t0 after orbit.epoch_utc (moves the plan within the eclipse cycle)")

    @model_validator(mode="after")
    def _bounds_ordered(self):
        if self.tau_lb_s > self.tau_ub_s:
            raise ValueError(f"planner.tau_lb_s = {self.tau_lb_s} s must not exceed tau_ub_s = {self.tau_ub_s} s")
        return self


class GuidanceSection(Section):
    """Table 2 keys of the tracking guidance (not used by the planner):
    eps_P = 10, dt_g = 30 s, delta t_g = 2 s, recompute thresholds [30, 30, 15, 5] m."""

    terminal_penalty: float = Field(10.0, description="tracking (cortex 2/2): terminal-error weight eps_P (Table 2: 10)")
    dt_g_s: Annotated[float, Field(gt=0.0)] = Field(30.0, description="tracking (cortex 2/2): guidance interval Delta t_g (Table 2: 30 s)")
    substep_s: Annotated[float, Field(gt=0.0)] = Field(2.0, description="tracking (cortex 2/2): impulse spacing delta t_g (Table 2: 2 s)")
    recompute_hold1_m: float = Field(30.0, description="tracking (cortex 2/2): recompute threshold in the first hold (Table 1)")
    recompute_flyaround_m: float = Field(30.0, description="tracking (cortex 2/2): recompute threshold in the fly-around (Table 1)")
    recompute_hold2_m: float = Field(15.0, description="tracking (cortex 2/2): recompute threshold in the second hold (Table 1)")
    recompute_approach_m: float = Field(5.0, description="tracking (cortex 2/2): recompute threshold in the final approach (Table 1)")
    closed_loop: bool = Field(False, description="run the tracking loop (cortex 2/2) against the truth; false: plan only")
    max_recomputes: Annotated[int, Field(ge=0, le=1000)] = Field(3, description="reference regenerations per run before the next recompute trigger aborts (not in the paper)")
    abort_at_s: Annotated[float, Field(ge=0.0)] | None = Field(None, description="ground abort command at this time (s from the start; none: no command)")
    buffer_tol_m: Annotated[float, Field(ge=0.0)] = Field(0.1, description="buffered-KOS recompute only below rho_bar minus this (the second hold sits on rho_bar)")
    tracking_cone_margin_deg: Annotated[float, Field(ge=0.0)] = Field(0.0, description="final approach: CP_g imposes the cone row (27g) at alpha_c minus this first and falls back to alpha_c when that is infeasible (0: the printed alpha_c only)")
    cone_buffer_tol_deg: Annotated[float, Field(ge=0.0)] = Field(1.0, description="buffered-cone recompute only beyond alpha_c_bar plus this (CP2 nodes touch the buffered cone)")
    plume_weight: Annotated[float, Field(gt=0.0)] = Field(1e4, description="cost of the plume-row slacks in CP_g per unit of a_max delta_t_g (against 1 per unit of delta-v)")
    plume_in_tracking: bool = Field(True, description="final approach: CP_g keeps each impulse in a soft plume half-space (not in the paper; linearisation point: plume_linearization; false: the printed CP_g)")
    plume_linearization: Literal["reference", "solution"] = Field("solution", description="final approach: CP_g plume rows linearised about the reference impulse (reference; a coasting reference gives dv . r <= 0, no braking) or about a plume-free CP_g solve, re-solved only when that breaks alpha_p_bar (solution)")
    tracking_plume_margin_deg: Annotated[float, Field(ge=0.0, lt=45.0)] = Field(0.0, description="final approach: CP_g's plume rows (plume_linearization = solution) keep each impulse this far beyond alpha_p_bar (a design margin against execution errors; 0: at alpha_p_bar)")
    plume_min_dv_mps: Annotated[float, Field(ge=0.0)] = Field(1e-4, description="impulses below this are not thrust for the plume triggers (minimum impulse bit)")
    regen_cone_return_s: Annotated[float, Field(ge=0.0)] = Field(0.0, description="final-approach regeneration from outside alpha_c_bar: the planning cone, widened to pass the start, closes linearly back onto alpha_c_bar within this time (0: the widened cone throughout)")
    replan_candidates: Annotated[int, Field(ge=1, le=1000)] = Field(30, description="regeneration: most phase durations tried from tau_lb (onboard time budget; none converged -> abort)")
    null_tol_mps: Annotated[float, Field(gt=0.0)] = Field(1e-3, description="velocity nulling before a re-plan / retreat ends below this speed")
    passive_orbits: Annotated[float, Field(ge=1.0, le=50.0)] = Field(5.0, description="after an abort: window of the passive-safety certificate (orbits of thrust-free truth from the final state) and of the onboard insertion check's CW prediction")
    passive_margin_m: Annotated[float, Field(ge=0.0)] = Field(2.0, description="safe-orbit insertion: the thrusters stop only when the thrust-free CW prediction from the estimate stays this far outside r_KOS for passive_orbits orbits")
    recompute_every: Literal["guidance", "impulse"] = Field("guidance", description="closed loop: evaluate the recompute conditions of Table 1 at every guidance step (Algorithm 2 lines 11-15, x_{k+1}) or at every impulse; the abort conditions are evaluated at every impulse either way")
    trace_step_s: Annotated[float, Field(ge=0.0)] = Field(10.0, description="closed loop: the run summary keeps the trajectory every this many seconds (campaign Figs. 13-14 without saved series; 0: none)")
    insertion_max_intervals: Annotated[int, Field(ge=0, le=10000)] = Field(20, description="safe-orbit insertion: most extra guidance intervals spent trimming onto the safe orbit before the thrusters stop anyway")
    insertion_coast_s: Annotated[float, Field(gt=0.0)] | None = Field(None, description="safe-orbit insertion: thrust-free coast of each insertion check, its estimates averaged (none: one guidance interval dt_g_s)")
    insertion_drift_tol_m: Annotated[float, Field(gt=0.0)] | None = Field(0.5, description="safe-orbit insertion: the thrusters stop only when the predicted along-track drift |6 pi (2 x + y_dot / n)| per orbit is at most this, else an along-track drift trim (none: drift not checked, the position-only check before issue 26)")


class ErrorsSection(Section):
    """Execution errors of Algorithm 3 at the levels of Table 3 (0 = none). sigma_r of §5.1.2:
    (delta_r_m / 3) (0.02 + 0.98 ||r|| / r_AS), split equally over the three axes (the printed
    Delta r delta / sqrt(3)); sigma_v = 0.001 sigma_r. The injection errors enter as navigation
    errors (what the guidance sees); thrust errors through the thruster model."""

    delta_r_m: Annotated[float, Field(ge=0.0)] = Field(0.0, description="position error level Delta r of Table 3 (low 0.1 m, high 1.0 m)")
    sigma_dv: Annotated[float, Field(ge=0.0)] = Field(0.0, description="relative 1-sigma impulse magnitude error (Table 3 prints m/s; eq. 29 makes it relative: low 0.1, high 0.2)")
    sigma_beta_deg: Annotated[float, Field(ge=0.0)] = Field(0.0, description="1-sigma out-of-plane direction error beta (Table 3: 0.5 / 1.0 deg)")
    sigma_alpha_deg: Annotated[float, Field(ge=0.0)] = Field(0.0, description="1-sigma in-plane direction error alpha (Table 3: 0.5 / 1.0 deg)")
    p_misthrust: Probability = Field(0.0, description="probability that all impulses of a guidance interval are missed (Table 3: 0.05 / 0.10)")
    velocity_ratio_per_s: Annotated[float, Field(ge=0.0)] = Field(0.001, description="sigma_v / sigma_r (§5.1.2: 0.001 1/s)")


class CortexActuatorSection(ActuatorSection):
    """The closed loop's actuator slot (cortex 2/2, §4.1.3-4.1.4). ``impulsive``: the CP_g impulses are
    applied as commanded (after the [errors] of Algorithm 3). ``thrusters``: each impulse goes through
    the thruster chain (proxops.actuators.thrusters.ThrusterChainActuator): rocket-equation force
    (eq. 32, mass depletion), Algorithm 4 allocation over six thrusters (HiGHS LP) and the PWM law
    (eq. 33) over the impulse spacing delta t_g. The generic limit/error keys above are not used by
    the cortex loop (its errors are [errors])."""

    model: Literal["impulsive", "thrusters"] = Field("impulsive", description="cortex loop: impulsive (commanded impulses applied) or thrusters (eq. 32 + Algorithm 4 + eq. 33 chain)")
    thruster_force_n: Annotated[float, Field(gt=0.0)] = Field(1.2, description="thrusters: maximum thrust of each of the six thrusters (+-x, +-y, +-z through the centre of mass); 1.2 N = m a_max, so every command |a| <= a_max is producible in any direction (documented choice)")
    isp_s: Annotated[float, Field(gt=0.0)] = Field(220.0, description="thrusters: specific impulse (not in the paper; 220 s, a hydrazine monopropellant RCS: documented choice)")
    min_on_time_s: Annotated[float, Field(ge=0.0)] = Field(0.0, description="thrusters: duty cycles shorter than this on-time fire nothing (minimum on-time; must not exceed guidance.substep_s)")


MAX_FIBONACCI_N = 1_000_000  # points of the Fibonacci sphere (`cortex references --n`): a bound, not a use


class AxisSection(Section):
    """Docking axis e in Hill (x radial, y along-track, z normal; the paper's frame, see
    proxops.guidance.cortex.reference). With ``fibonacci_index`` set, the axis is point i of
    an N-point Fibonacci sphere instead."""

    docking_axis: Vector3 = Field([-math.sin(math.pi / 4), -math.sin(math.pi / 4), 0.0], description="docking axis e in Hill (x radial, y along-track, z normal); §5.1.2: [-sin 45, -sin 45, 0]")
    fibonacci_n: Annotated[int, Field(ge=1, le=MAX_FIBONACCI_N)] = Field(100, description="points N of the Fibonacci sphere of docking axes (ref. 11)")
    fibonacci_index: Annotated[int, Field(ge=0)] | None = Field(None, description="use point i of the N-point Fibonacci sphere as the axis (none: docking_axis)")

    @model_validator(mode="after")
    def _index_in_range(self):
        if self.fibonacci_index is not None and self.fibonacci_index >= self.fibonacci_n:
            raise ValueError(f"axis.fibonacci_index must be < fibonacci_n = {self.fibonacci_n}")
        return self


class EclipseSection(Section):
    """Sunlight profile for the holds (eqs. 13-15). model "none" switches the holds off."""

    model: Literal["conical", "cylindrical", "none"] = Field("conical", description="Earth shadow model of the sunlight profile for the holds; none switches the holds off")
    samples_per_orbit: Annotated[int, Field(ge=10, le=100_000)] = Field(1000, description="sunlight samples per orbit (§3.1: 1000)")
    orbits: Annotated[float, Field(gt=0.0, le=100.0)] = Field(4.0, description="length of the sunlight profile in orbits (two holds of up to an orbit plus two phases)")
    sunlit_threshold: Annotated[float, Field(gt=0.0, le=1.0)] = Field(1.0, description="illumination fraction counted as sunlit (eta = 1); 1: full sun only")


@register_scenario("cortex")
class CortexScenario(ScenarioBase):
    orbit: OrbitSection = Field(description="target (client) orbit; §5.1 CSO elements and epoch")
    servicer: ServicerSection = Field(ServicerSection(), description="servicer mass and thrust (Table 2)")
    geometry: GeometrySection = Field(GeometrySection(), description="spheres, cone and plume angles, start and end states")
    margins: MarginsSection = Field(MarginsSection(), description="planning margins on thrust, KOS, plume and cone (§3.1)")
    planner: PlannerSection = Field(PlannerSection(), description="outer search and the convex phases CP1, CP2")
    guidance: GuidanceSection = Field(GuidanceSection(), description="tracking guidance keys (cortex 2/2; unused by the planner)")
    axis: AxisSection = Field(AxisSection(), description="docking axis, fixed or from a Fibonacci sphere")
    eclipse: EclipseSection = Field(EclipseSection(), description="sunlight profile for the holds (eqs. 13-15)")
    truth: TruthSection = Field(TruthSection(), description="truth dynamics of the closed loop (guidance.closed_loop)")
    errors: ErrorsSection = Field(ErrorsSection(), description="Algorithm 3 execution errors (Table 3)")
    actuator: CortexActuatorSection = Field(CortexActuatorSection(), description="closed loop: impulsive or the thruster chain of §4.1.3-4.1.4")
