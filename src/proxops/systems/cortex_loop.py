"""CORTEX closed loop (cortex 2/2): the ``cortex`` system with ``guidance.closed_loop = true``
(Wijayatunga et al. §3.2-3.4, §5.1.2, Tables 1, 3, 4).

Scenarios ``cortex-nominal`` (fixed axis of §5.1.2, no errors), ``cortex-low-mc`` /
``cortex-high-mc`` (Table 3 levels, full truth) and ``cortex-abort`` (ground abort command
mid fly-around)::

    proxops run cortex-nominal --json
    proxops mc cortex-high-mc --runs 100 --workers 2 --report

The engine runs at delta_t_g (one impulse per step, :class:`proxops.control.cortex_supervisor.
CortexSupervisor`); thrust errors go through the engine's actuator slot
(:class:`proxops.actuators.ThrusterModel`), injection errors through its navigation slot
(:class:`proxops.navigation.GaussianNavigation` with the §5.1.2 range law) or, with
``[navigation] model = "ekf"`` (``cortex-nominal-ekf``, ``cortex-low-mc-ekf``), the relative-
navigation filter's estimate (:class:`proxops.navigation.ekf.RelativeEKF`) in that same slot.
"""

from __future__ import annotations

import math

import numpy as np

from proxops.actuators import IdealActuator, ThrusterModel, propellant_mass_kg
from proxops.actuators.thrusters import ThrusterChainActuator, six_thruster_layout
from proxops.constraints.approach_cone import ApproachCone
from proxops.constraints.keep_out import KeepOutSphere
from proxops.constraints.plume import PlumeConstraint
from proxops.control.cortex_supervisor import CortexSupervisor, SupervisorSettings
from proxops.control.cortex_triggers import CortexTriggers
from proxops.core.constants import J2_EARTH, R_EARTH
from proxops.errors import ProxopsError
from proxops.guidance.cortex.replanner import CortexReplanner
from proxops.guidance.cortex.timeline import timeline_from_plan
from proxops.navigation import GaussianNavigation, PerfectNavigation
from proxops.sim.engine import Setup, simulate
from proxops.systems.common import ekf_navigation, passive_safety_certificate, translational_plant
from proxops.systems.cortex_setup import (eps_r, check_loop, check_navigation, config_from_scenario, eclipse_profile,
                                          plan_scenario, scenario_axis)


PAPER_TABLE4 = {  # Wijayatunga et al. Table 4: mean, std, Q1, Q2, Q3, P99
    "low": {"tof_s": (1179.82, 0.00, 1179.82, 1179.82, 1179.82, 1179.82),
            "total_dv_mps": (0.11, 0.01, 0.10, 0.10, 0.11, 0.13),
            "terminal_position_error_mm": (3.67, 3.32, 2.23, 2.88, 3.96, 21.05),
            "terminal_velocity_error_mmps": (0.0335, 0.0388, 0.0079, 0.0181, 0.0426, 0.18),
            "recomputes": 0, "aborts": 0},
    "high": {"tof_s": (1271.93, 363.21, 1179.82, 1179.82, 1179.82, 3296.50),
             "total_dv_mps": (1.23, 0.14, 1.14, 1.21, 1.30, 1.67),
             "terminal_position_error_mm": (31.26, 24.17, 19.18, 25.53, 38.64, 119.85),
             "terminal_velocity_error_mmps": (0.5243, 0.8034, 0.1195, 0.2747, 0.4869, 4.27),
             "recomputes": 12, "aborts": 8},
}
PAPER_CPG_SOLVE_MS = (38.43, 12.8)  # §5.1.2, mean and std of one CP_g solve


def navigation_of(sc, layout=None, actuator=None):
    """The navigation slot of the closed loop. ``[navigation] model = "noise"`` (default): the
    injection errors of Algorithm 3 (``[errors] delta_r_m``, §5.1.2 range law, white on the truth;
    the [navigation] noise sigmas are not used by cortex and must stay 0). ``model = "ekf"``: the
    relative-navigation filter (:func:`proxops.systems.common.ekf_navigation`) at the impulse
    period delta_t_g on the plant's Hill blocks (``layout``); ``errors.delta_r_m`` must then be 0
    (the sensor sets the measurement errors)."""
    check_navigation(sc)
    e, nav = sc.errors, sc.navigation
    if nav.model == "ekf":
        return ekf_navigation(nav, sc.orbit, sc.guidance.substep_s, system="cortex", layout=layout, actuator=actuator)
    if e.delta_r_m == 0.0:
        return PerfectNavigation()
    sigma_axis = e.delta_r_m / 3.0 / math.sqrt(3.0)
    return GaussianNavigation(sigma_axis, e.velocity_ratio_per_s * sigma_axis, range_scale_m=sc.geometry.r_as_m,
                              range_floor=0.02)


def actuator_of(sc):
    """The engine's actuator slot: the Algorithm 3 execution errors ([errors], through
    :class:`ThrusterModel`), then -- with ``actuator.model = "thrusters"`` -- the thruster chain."""

    e = sc.errors
    errors = None
    if not (e.sigma_dv == 0 and e.sigma_beta_deg == 0 and e.sigma_alpha_deg == 0 and e.p_misthrust == 0):
        errors = ThrusterModel(magnitude_sigma=e.sigma_dv, elevation_sigma_rad=math.radians(e.sigma_beta_deg),
                               azimuth_sigma_rad=math.radians(e.sigma_alpha_deg), missed_probability=e.p_misthrust,
                               missed_window_s=sc.guidance.dt_g_s)
    a = sc.actuator
    if a.model == "thrusters":
        return ThrusterChainActuator(six_thruster_layout(a.thruster_force_n), sc.servicer.mass_kg, a.isp_s,
                                     sc.guidance.substep_s, errors=errors, min_on_time_s=a.min_on_time_s)
    return errors if errors is not None else IdealActuator()


def build_setup(sc):
    """(Setup, supervisor, plan) of a closed-loop scenario; the initial plan is made here."""

    check_loop(sc)
    cfg = config_from_scenario(sc)
    axis = scenario_axis(sc)
    plan = plan_scenario(sc, axis)
    if not plan.ok:
        raise ProxopsError(f"cortex: no initial reference ({plan.status}: {plan.reason})")
    g = sc.guidance
    n = cfg.mean_motion_rad_s
    timeline = timeline_from_plan(plan, n, 0.0, g.substep_s)
    triggers = CortexTriggers(
        r_kos_m=cfg.r_kos_m, rho_bar_m=cfg.rho_bar,
        cone=ApproachCone(axis, cfg.cone_half_angle_rad), cone_bar=ApproachCone(axis, cfg.alpha_c_bar),
        plume=PlumeConstraint(cfg.plume_half_angle_rad), plume_bar=PlumeConstraint(cfg.alpha_p_bar),
        eps_r_m=eps_r(g), buffer_tol_m=g.buffer_tol_m,
        cone_buffer_tol_rad=math.radians(g.cone_buffer_tol_deg), plume_min_dv_mps=g.plume_min_dv_mps)
    settings = SupervisorSettings(dt_g_s=g.dt_g_s, substep_s=g.substep_s, terminal_penalty=g.terminal_penalty,
                                  max_recomputes=g.max_recomputes, null_tol_mps=g.null_tol_mps, abort_at_s=g.abort_at_s,
                                  r_as_m=cfg.r_as_m, plume_in_tracking=g.plume_in_tracking,
                                  plume_weight=g.plume_weight, passive_orbits=g.passive_orbits,
                                  passive_margin_m=g.passive_margin_m, insertion_max_intervals=g.insertion_max_intervals,
                                  insertion_coast_s=g.insertion_coast_s, insertion_drift_tol_m=g.insertion_drift_tol_m,
                                  **_j2_drift_term(sc),
                                  recompute_every=g.recompute_every,
                                  tracking_cone_margin_deg=g.tracking_cone_margin_deg,
                                  plume_linearization=g.plume_linearization,
                                  tracking_plume_margin_deg=g.tracking_plume_margin_deg)
    replanner = CortexReplanner(cfg, axis, eclipse=eclipse_profile(sc), t0_offset_s=sc.planner.start_delay_s,
                                max_candidates=g.replan_candidates, cone_return_s=g.regen_cone_return_s)
    ctrl = CortexSupervisor(n, cfg.a_max_mps2, timeline, triggers, replanner, settings,
                            ApproachCone(axis, cfg.cone_half_angle_rad), plume_bar=PlumeConstraint(cfg.alpha_p_bar))
    x0 = np.asarray(cfg.start_state, float)
    plant = translational_plant(sc.orbit, sc.truth, x0)
    actuator = actuator_of(sc)
    setup = Setup(plant=plant, controller=ctrl, duration_s=sc.sim.duration_s,
                  navigation=navigation_of(sc, plant.layout, actuator), actuator=actuator, meta={"system": "cortex", "control": "impulse", "frame": "Hill/RTN"})
    return setup, ctrl, plan


def _j2_drift_term(sc) -> dict:
    """Settings of the J2 term of the insertion check's predicted drift (J2 or full truth; 0 on CW and
    two-body): gain 9 pi J2 (Re / a)^2 sin^2 i (m/orbit per m of along-track offset, see
    SafeOrbitInsertion.predicted_drift_m_per_orbit) and the target's argument of latitude at t = 0."""
    if sc.truth.model not in ("j2", "full"):
        return {"j2_drift_gain": 0.0, "u0_rad": 0.0}
    o = sc.orbit
    gain = 9.0 * math.pi * J2_EARTH * (R_EARTH / o.sma_m) ** 2 * math.sin(math.radians(o.inc_deg)) ** 2
    return {"j2_drift_gain": gain, "u0_rad": math.radians(o.argp_deg + o.nu_deg)}  # the plant starts at orbit.epoch_utc


def passive_safety(sc, plant, final_state) -> dict:
    """The passive-safety certificate (:func:`proxops.systems.common.passive_safety_certificate`) of an
    aborted run: thrust-free TRUTH from the final state over ``guidance.passive_orbits`` orbits, KOZ = r_KOS."""
    cfg = config_from_scenario(sc)
    return passive_safety_certificate(plant, final_state, KeepOutSphere(cfg.r_kos_m, name="r_KOS"),
                                      2 * math.pi / cfg.mean_motion_rad_s, sc.guidance.passive_orbits)


def run_trace(result, step_s: float) -> dict:
    """The run downsampled for the campaign figures (Figs. 13-14 drawn from the campaign table, no
    saved series): every ``step_s`` seconds and the last sample -- t (s), Hill position x, y, z (m, mm
    rounding), tracking error (m; NaN while no reference is tracked) and the phase index
    (:data:`proxops.control.cortex_supervisor.PHASE_INDEX`). About 5 kB per run at 10 s."""
    t = result.t
    if t.size == 0 or step_s <= 0:
        return {}
    dt = float(t[1] - t[0]) if t.size > 1 else step_s
    k = np.arange(0, t.size, max(1, int(round(step_s / dt))))
    if k[-1] != t.size - 1:
        k = np.append(k, t.size - 1)
    err = result.info.get("track_err_m", np.full(t.size, np.nan))
    phase = result.info.get("phase", np.full(t.size, np.nan))
    r = result.x_true[k, :3]
    return {"t": np.round(t[k], 3).tolist(), "x": np.round(r[:, 0], 3).tolist(), "y": np.round(r[:, 1], 3).tolist(),
            "z": np.round(r[:, 2], 3).tolist(),
            "err": [None if not np.isfinite(v) else float(f"{v:.4g}") for v in err[k]],
            "phase": [None if not np.isfinite(v) else int(v) for v in phase[k]]}


def violation_counts(result, cfg, axis, plume_min_dv_mps: float) -> dict:
    """Samples of the TRUE state that break a true constraint in the phase where it applies
    (KOS in holds/fly-around, cone and plume in the approach), from the recorded series."""
    modes = np.array(result.mode)
    r = result.x_true[:, :3]
    rng = np.linalg.norm(r, axis=1)
    in_fly = np.isin(modes, ["hold1", "flyaround", "hold2"])
    in_app = modes == "approach"
    cone = ApproachCone(axis, cfg.cone_half_angle_rad)
    plume = PlumeConstraint(cfg.plume_half_angle_rad)
    cone_bad = in_app & (cone.margin(r) < 0)
    u = result.u_applied
    thrust = np.linalg.norm(u, axis=1) > plume_min_dv_mps
    pm = plume.margin_rad(r, u)
    plume_bad = in_app & thrust & (pm < 0)
    return {"koz": int((in_fly & (rng < cfg.r_kos_m)).sum()), "cone": int(cone_bad.sum()), "plume": int(plume_bad.sum())}


def run_closed_loop(sc, seed: int = 0, progress: bool = False):
    setup, ctrl, plan = build_setup(sc)
    result = simulate(setup, seed=seed, progress=progress)
    cfg = config_from_scenario(sc)
    axis = scenario_axis(sc)
    outcome = str(result.meta.get("outcome", ""))
    status = outcome if outcome in ("docked", "aborted") else "failed"
    xf = result.x_true[-1]
    target = ctrl.final_target
    if target is not None:
        dr = float(np.linalg.norm(xf[:3] - target[:3]))
        dvr = float(np.linalg.norm(xf[3:6] - target[3:6]))
    else:
        dr = dvr = math.nan
    viol = violation_counts(result, cfg, axis, sc.guidance.plume_min_dv_mps)
    solved = result.solve_time_s[result.solve_time_s > 0]
    summary = {
        "status": status,
        "docked": status == "docked",
        "tof_s": float(result.t[-1]),
        "total_dv_mps": float(result.dv_cum[-1]),
        "terminal_position_error_m": dr if status == "docked" else math.nan,
        "terminal_velocity_error_mps": dvr if status == "docked" else math.nan,
        "recomputes": int(ctrl.recomputes),
        "aborts": int(ctrl.aborts),
        "abort_reason": ctrl.abort_reason,
        "min_range_m": float(np.linalg.norm(result.x_true[:, :3], axis=1).min()),
        "koz_violations": viol["koz"],
        "cone_violations": viol["cone"],
        "plume_violations": viol["plume"],
        "solve_time_ms": {
            "median": float(np.median(solved) * 1e3) if solved.size else 0.0,
            "p95": float(np.percentile(solved, 95) * 1e3) if solved.size else 0.0,
            "max": float(solved.max() * 1e3) if solved.size else 0.0,
        },
        "cpg_solves": int(solved.size),
        "plan_tof_s": float(plan.tof_s), "plan_total_time_s": float(plan.total_time_s),
        "plan_dv_mps": float(plan.dv_total_mps),
    }
    act = setup.actuator
    if hasattr(act, "propellant_kg"):  # thruster chain: propellant of the PWM on-times (eq. 32 mass depletion)
        summary.update(actuator_model="thrusters", propellant_kg=float(act.propellant_kg),
                       thruster_on_time_s=float(act.on_time_s), allocations=int(act.allocations),
                       allocation_max_error_n=float(act.max_allocation_error_n),
                       allocation_lp_ms_mean=float(act.lp_time_s / max(act.allocations, 1) * 1e3))
    else:  # impulsive: the rocket equation on the total delta-v at the chain's Isp
        summary.update(actuator_model="impulsive",
                       propellant_kg=float(propellant_mass_kg(summary["total_dv_mps"], sc.servicer.mass_kg, sc.actuator.isp_s)))
    if status == "aborted":
        cert = passive_safety(sc, setup.plant, result.meta["final_plant_state"])
        # safe only when the truth certificate holds AND the onboard insertion check passed: a retreat that could
        # not be verified (trim cap reached) is never reported safe, whatever the truth did
        verified = bool(ctrl.insertion.verified)
        cert["truth_safe"] = cert["safe"]
        cert["safe"] = bool(cert["safe"] and verified)
        cert["stop_reason"] = ctrl.insertion.stop_reason
        if not verified:
            cert["verdict"] = f"not safe: retreat not verified onboard ({ctrl.insertion.stop_reason}); truth: {cert['verdict']}"
        summary.update(safe_orbit_error_m=dr, passive_orbits=sc.guidance.passive_orbits,
                       passive_min_range_m=cert["min_range_m"], passive_safe=cert["safe"],
                       passive_safety=cert, insertion_trims=int(ctrl.insertion.extensions),
                       drift_trims=int(ctrl.insertion.drift_trims), insertion_verified=verified,
                       predicted_passive_min_range_m=ctrl.insertion.predicted_passive_min_m,
                       predicted_drift_m_per_orbit=ctrl.insertion.predicted_drift_m)
    summary["trace"] = run_trace(result, sc.guidance.trace_step_s)
    result.meta["cortex_summary"] = {k: v for k, v in summary.items() if not isinstance(v, dict)}
    clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in summary.items()}
    return clean, {"run": result}


# --------------------------------------------------------------------------- Table 4
def _level(sc) -> str:
    return "high" if sc.errors.delta_r_m >= 0.5 else "low"


def table4(sc, table) -> str:
    """Table 4 layout (mean, std, [Q1, Q2, Q3, P99]) over docked runs beside the paper's row, with
    counts of runs that recomputed / aborted (the paper counts 12 / 8 of 100 in the high case)."""
    if "metric.tof_s" not in table:
        return ""
    paper = PAPER_TABLE4[_level(sc)]
    done = table[table["outcome"] != "error"] if "outcome" in table else table
    docked = done[done["status"] == "docked"] if "status" in done else done
    rows = [("Total TOF (s)", "metric.tof_s", 1.0, "tof_s", done),
            ("Total Δv (m/s)", "metric.total_dv_mps", 1.0, "total_dv_mps", done),
            ("Δr_rel(t_f) (mm)", "metric.terminal_position_error_m", 1e3, "terminal_position_error_mm", docked),
            ("Δv_rel(t_f) (mm/s)", "metric.terminal_velocity_error_mps", 1e3, "terminal_velocity_error_mmps", docked)]
    table2_tau_lb = type(sc.planner).model_fields["tau_lb_s"].default  # Table 2: 5 min
    calibrated = ([f"CALIBRATED: the reference duration tau_lb = {sc.planner.tau_lb_s:g} s per phase was chosen on the "
                   f"paper's Table 4 TOF (Table 2 gives {table2_tau_lb:g} s), so TOF agreeing is not evidence.", ""]
                  if sc.planner.tau_lb_s != table2_tau_lb else [])
    out = calibrated + [f"Level: {_level(sc)} (Table 3); {len(done)} runs, {len(docked)} docked. TOF and Δv over all runs; "
           "terminal errors over docked runs.", "",
           "| metric | μ | σ | [Q1, Q2, Q3, P99] | paper μ | paper σ | paper [Q1, Q2, Q3, P99] |", "|---|---|---|---|---|---|---|"]
    for label, col, scale, key, frame in rows:
        v = frame[col].astype(float).to_numpy() * scale if col in frame else np.zeros(0)
        v = v[np.isfinite(v)]
        p = paper[key]
        if v.size:
            q1, q2, q3, p99 = np.percentile(v, [25, 50, 75, 99])
            ours = f"{v.mean():.4g} | {v.std(ddof=1) if v.size > 1 else 0.0:.4g} | [{q1:.4g}, {q2:.4g}, {q3:.4g}, {p99:.4g}]"
        else:
            ours = "- | - | -"
        out.append(f"| {label} | {ours} | {p[0]} | {p[1]} | [{p[2]}, {p[3]}, {p[4]}, {p[5]}] |")
    rec = int((done["metric.recomputes"].astype(float) > 0).sum()) if "metric.recomputes" in done else 0
    ab = int((done["metric.aborts"].astype(float) > 0).sum()) if "metric.aborts" in done else 0
    out += ["", f"Runs with a recompute: {rec} of {len(done)} (paper: {paper['recomputes']} of 100); "
            f"runs aborted: {ab} of {len(done)} (paper: {paper['aborts']} of 100)."]
    if "metric.passive_safe" in done:
        ps = done["metric.passive_safe"].dropna()
        if len(ps):
            out.append(f"Aborted runs passively safe over {sc.guidance.passive_orbits:g} orbits: "
                       f"{int(ps.astype(bool).sum())} of {len(ps)}; smallest range "
                       f"{done['metric.passive_min_range_m'].astype(float).min():.2f} m (r_KOS {sc.geometry.r_kos_m:g} m).")
            col = "metric.passive_safety.drift_median_m_per_orbit"
            if col in done:
                d = done[col].astype(float).dropna()
                if len(d):
                    out.append(f"Along-track drift after the insertion (thrust-free truth, median over the orbits of each run, "
                               f"+ = away from the target): median {d.median():+.3f} m/orbit, |max| {d.abs().max():.3f} m/orbit.")
    if "metric.solve_time_ms.median" in done:
        out.append(f"CP_g solve time: median of run medians {done['metric.solve_time_ms.median'].astype(float).median():.3f} ms "
                   f"(paper {PAPER_CPG_SOLVE_MS[0]} ± {PAPER_CPG_SOLVE_MS[1]} ms).")
    return "\n".join(out)
