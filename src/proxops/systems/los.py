"""System ``los``: approach to a tumbling target through its rotating LOS corridor
(Iskender 2026 §2-7, §10.6).

Scenario ``los-tumble`` (src/proxops/scenarios/builtin/los-tumble.toml), e.g.::

    proxops run los-tumble --set target.tumble_rate_deg_s=2 --set chaser.a_max_mps2=0.1 --json

Truth: two-body + J2 (RelativeTruth, Encke, DOP853) on the 500 km circular orbit of
Table 1 plus the target quaternion (eq. 2); the measured relative state is the
body-frame state of eqs. (7)-(8). Controller: §7 regimes + eq.-(11) MPC
(:class:`proxops.control.los_regimes.LosGuidanceController`).

Programmatic use (Monte Carlo)::

    from proxops.systems.los import run_case
    out = run_case(tumble_rate_deg_s=2, a_max_mps2=0.1, initial_body_position_m=[0, 80, 0],
                   mpc_config="monte-carlo")       # dict: feasible, los_violations, ...

``feasible`` follows §9.3 (:func:`is_feasible_run`, also ``LosSystem.success`` and the
reach feasibility maps): no violation above 1e-3 m, no QP infeasibility, no early
termination.

Table 3 sweep (§10.6): scenario ``los-sweep`` (grid dispersions, 15 combinations x hard/soft
constraints) through the campaign engine; ``run_sweep()`` runs it and ``sweep_table()``
prints the paper's layout with our columns next to the paper's. Standalone:
``python -m proxops.analysis.los_sweep sweep [--workers 2] [--out DIR] [--no-campaign]``.
"""

from __future__ import annotations

import math

import numpy as np

from proxops.constraints.los_corridor import LosCorridor
from proxops.control.los_mpc import LosMpcConfig
from proxops.control.los_regimes import LosGuidanceConfig, LosGuidanceController
from proxops.core.cw import mean_motion
from proxops.core.memo import memo_get
from proxops.dynamics.tumbling_target import BodyFrameModel, TumblingTarget, TumblingTargetTruth, sync_range
from proxops.errors import input_error
from proxops.frames.elements import OrbitalElements, elements_to_eci
from proxops.navigation.mekf import PoseAttitudeSensor, attitude_summary
from proxops.navigation.target_attitude import TargetAttitudeNavigation
from proxops.propagation.truth import RelativeTruth
from proxops.scenarios.registry import register_system
from proxops.sim.engine import Setup, simulate
from proxops.status import Status
from proxops.systems.base import SystemBase
from proxops.systems.common import navigation_model
from proxops.systems.schema._build_free import actuator_model
from proxops.systems.schema.los import LosScenario, check_settings

VIOLATION_TOLERANCE_M = 1e-3  # §9 step 3
COMPLETED_OUTCOMES = ("completed", "hold_reached")  # ran to T_sim (or stopped at hold on request)


def is_feasible_run(los_violations, max_violation_m, qp_infeasible, outcome) -> bool:
    """§9 step 3 classification of one closed-loop run (the one rule for summaries,
    campaigns and feasibility maps): *feasible* = zero corridor violations above
    1e-3 m over T_sim, the QP never reported infeasible, and no early termination
    (``outcome`` "completed", or "hold_reached" when ``guidance.stop_at_hold`` ends the run
    at hold). Missing or NaN values (e.g. a run that raised) count as infeasible."""
    try:
        n_viol, v_max = float(los_violations), float(max_violation_m)
    except (TypeError, ValueError):
        return False
    qp_bad = True if qp_infeasible is None else bool(qp_infeasible)  # NaN -> True
    return bool(n_viol == 0 and v_max <= VIOLATION_TOLERANCE_M and not qp_bad and str(outcome) in COMPLETED_OUTCOMES)


def default_scenario(**sections) -> LosScenario:
    """A LosScenario with Table 1 defaults (500 km circular, 51.6 deg); keyword
    arguments are section dicts, e.g. ``chaser={"a_max_mps2": 0.05}``."""
    data = {
        "name": "los-tumble",
        "system": "los",
        "sim": {"duration_s": 600.0, "dt_s": 1.0},
        "orbit": {"altitude_km": 500.0, "inc_deg": 51.6},
    }
    for key, value in sections.items():
        data[key] = {**data.get(key, {}), **value}
    return LosScenario.model_validate(data)


_TARGET_CACHE: dict = {}  # orbit, tumble rate, initial angle, dt -> (elements, TumblingTarget, BodyFrameModel)


def build_setup(sc: LosScenario) -> Setup:
    """Plant (J2 truth + tumbling target), controller, corridor check for one scenario."""
    o = sc.orbit
    dt = sc.sim.dt_s or 1.0

    def target_side():
        """Orbit, target attitude and prediction model: the same for every run of a campaign that
        disperses only the chaser (objects nothing modifies, shared by those runs of a worker)."""
        elements = OrbitalElements(o.sma_m, o.ecc, np.radians(o.inc_deg), np.radians(o.raan_deg),
                                   np.radians(o.argp_deg), np.radians(o.nu_deg))
        w_t = np.radians(sc.target.tumble_rate_deg_s)
        theta0 = np.radians(sc.target.initial_angle_deg)
        target = TumblingTarget.aligned_with_hill(w_t, elements_to_eci(elements), theta0)
        return elements, target, BodyFrameModel(mean_motion(o.sma_m), w_t, dt, theta0)

    key = (o.sma_m, o.ecc, o.inc_deg, o.raan_deg, o.argp_deg, o.nu_deg, sc.target.tumble_rate_deg_s,
           sc.target.initial_angle_deg, dt)
    elements, target, model = memo_get(_TARGET_CACHE, key, target_side)
    x0_body = np.array(sc.chaser.initial_body_position_m + sc.chaser.initial_velocity_mps, float)
    if sc.chaser.initial_velocity_frame == "lvlh":
        x_hill = model.hill_from_body(0.0, np.concatenate([x0_body[:3], np.zeros(3)]))
        x_hill[3:6] = x0_body[3:6]
        x0_body = model.body_from_hill(0.0, x_hill)
    check_settings(sc)  # ECI truth, PD gains
    inner = RelativeTruth(elements, np.zeros(6), j2=sc.truth.model == "j2", integrator=sc.truth.integrator)
    plant = TumblingTargetTruth(inner, target, x0_body)
    corridor = LosCorridor(np.radians(sc.target.corridor_half_angle_deg), sc.target.corridor_floor_m,
                           sc.target.corridor_faces, VIOLATION_TOLERANCE_M)
    m = sc.mpc
    base = LosMpcConfig.single_run if m.config == "single" else LosMpcConfig.monte_carlo
    mpc_cfg = base(constraint_mode=m.constraint_mode, slack_penalty=m.slack_penalty)
    if m.horizon is not None:
        mpc_cfg.horizon = m.horizon
    g = sc.guidance
    guidance = LosGuidanceConfig(hold_range_m=g.hold_range_m, hold_band_m=g.hold_band_m, v_switch_mps=g.v_switch_mps,
                                 v_max_mps=g.v_max_mps, pd_natural_frequency_rad_s=2 * np.pi / g.pd_period_s,
                                 use_mpc=g.use_mpc, stop_on_infeasible=g.stop_on_infeasible,
                                 stop_at_hold=g.stop_at_hold)
    ekf = sc.navigation.model == "ekf"  # the target attitude and rate estimated
    if ekf:
        navigation = attitude_navigation(sc, target, dt)
        model = BodyFrameModel(model.n, model.tumble_rate_rad_s, model.dt, model.theta0_rad)  # own copy: its angle
    else:                                                                                    # follows the estimate
        navigation = navigation_model(sc.navigation, system="los (target body frame)")
    ctrl = LosGuidanceController(model, sc.chaser.a_max_mps2, corridor, mpc_cfg, guidance)
    meta = {"system": "los", "r_sync_m": ctrl.r_sync, "frame": "target body (eqs. 7-8)"}
    if ekf:
        ctrl.attitude_source = navigation
        meta["attitude_filter"] = navigation.record  # filled during the run (summary: att_* keys)
    return Setup(plant=plant, controller=ctrl, duration_s=sc.sim.duration_s,
                 navigation=navigation, actuator=actuator_model(sc.actuator),
                 constraints=(corridor,), check_substeps=sc.sim.check_substeps, meta=meta)


def attitude_navigation(sc: LosScenario, target, dt: float):
    """:class:`proxops.navigation.target_attitude.TargetAttitudeNavigation` of a ``model = "ekf"``
    [navigation] section: the target's attitude and rate from pose measurements (attitude_* keys),
    the truth from ``target`` (the plant's closed-form attitude)."""
    nav = sc.navigation
    period = nav.update_period_s
    if period is not None:
        ratio = dt / period
        if period > dt * (1 + 1e-9) or abs(ratio - round(ratio)) > 1e-6:
            raise input_error("navigation.update_period_s", period, f"must divide the control period {dt:g} s", "s")
    sensor = PoseAttitudeSensor(
        sigma_rad=math.radians(nav.attitude_sigma_deg),
        rate_sigma_rad_s=None if nav.attitude_rate_sigma_deg_s is None else math.radians(nav.attitude_rate_sigma_deg_s),
        fov_rad=math.radians(nav.attitude_fov_deg), boresight=np.array([0.0, 1.0, 0.0]),
        outage_probability=nav.outage_probability)
    p0 = np.diag([math.radians(nav.initial_attitude_sigma_deg) ** 2] * 3
                 + [math.radians(nav.initial_rate_sigma_deg_s) ** 2] * 3)
    return TargetAttitudeNavigation(target_truth_attitude(target), sensor, p0, np.array(nav.attitude_inertia_kgm2),
                                    nav.attitude_process_noise_rad2_s3, gate_probability=nav.gate_probability,
                                    position_sigma_m=nav.position_sigma_m, velocity_sigma_mps=nav.velocity_sigma_mps,
                                    period_s=period)


class target_truth_attitude:  # noqa: N801 (a picklable callable)
    """``t -> (q_IB, w_B)`` of a :class:`proxops.dynamics.tumbling_target.TumblingTarget` (eq. 2)."""

    def __init__(self, target):
        self.target = target

    def __call__(self, t: float):
        return self.target.quaternion(t), self.target.omega_body


def summarize_result(sc: LosScenario, result) -> dict:
    """Extra JSON keys: los_violations, max_violation_m, r_sync_m, hold_reached, ..."""
    corridor = LosCorridor(np.radians(sc.target.corridor_half_angle_deg), sc.target.corridor_floor_m,
                           sc.target.corridor_faces, VIOLATION_TOLERANCE_M)
    viol = np.asarray(corridor.violation_body(result.x_true[:, :3]))
    outcome = result.meta.get("outcome", "completed")
    n_viol = int(np.sum(viol > VIOLATION_TOLERANCE_M))
    qp_infeasible = outcome == "qp_infeasible" or any(Status.parse(s) is Status.INFEASIBLE for s in result.status)
    hold = any(kind == "hold" for _, kind, _ in result.events) or outcome == "hold_reached"
    w = np.radians(sc.target.tumble_rate_deg_s)
    r_sync = sync_range(sc.chaser.a_max_mps2, w) if w > 0 else float("inf")
    r0 = float(np.linalg.norm(sc.chaser.initial_body_position_m))
    max_viol = float(viol.max()) if viol.size else 0.0
    extra = {}
    if "attitude_filter" in result.meta:
        extra = attitude_summary(result.meta["attitude_filter"])
    if qp_infeasible and sc.mpc.constraint_mode == "hard":
        where = "beyond" if r0 > r_sync else "inside"
        extra["hint"] = (f"the hard corridor rows became infeasible; the start ({r0:.1f} m) is {where} r_sync = "
                         f"{r_sync:.1f} m, the range within which a_max can hold the rotating corridor "
                         "(Iskender 2026 §7): start inside r_sync, raise chaser.a_max_mps2, or "
                         "set mpc.constraint_mode = \"soft\" to fly with penalised violations")
    return {
        **extra,
        "los_violations": n_viol,
        "max_violation_m": max_viol,
        "r_sync_m": float(r_sync),
        "hold_reached": bool(hold),
        "r_min_m": float(np.min(np.linalg.norm(result.x_true[:, :3], axis=1))),
        "initial_range_m": r0,
        "starts_inside_r_sync": bool(r0 <= r_sync),
        "qp_infeasible": bool(qp_infeasible),
        "feasible": is_feasible_run(n_viol, max_viol, qp_infeasible, outcome),
        "outcome": outcome,
    }


def run_case(tumble_rate_deg_s: float, a_max_mps2: float, initial_body_position_m, *,
             mpc_config: str = "monte-carlo", duration_s: float | None = None, truth: str = "j2",
             constraint_mode: str = "hard", initial_velocity_frame: str = "body",
             guidance: dict | None = None, seed: int = 0) -> dict:
    """One closed-loop run (J2 truth by default) -> summary dict (``summarize_result`` keys
    plus the engine summary's min_range_m, total_dv_mps, wall_time_s, solve_time_ms).

    Defaults follow the paper's Monte Carlo (§9): MC MPC configuration, 400 s, zero
    body-frame initial velocity, hard constraints (infeasible QP = failed run)."""
    if duration_s is None:
        duration_s = 600.0 if mpc_config == "single" else 400.0
    sc = default_scenario(
        sim={"duration_s": float(duration_s), "dt_s": 1.0, "seed": seed},
        truth={"model": truth},
        target={"tumble_rate_deg_s": float(tumble_rate_deg_s)},
        chaser={"a_max_mps2": float(a_max_mps2), "initial_body_position_m": [float(c) for c in initial_body_position_m],
                "initial_velocity_frame": initial_velocity_frame},
        mpc={"config": mpc_config, "constraint_mode": constraint_mode},
        guidance=guidance or {},
    )
    result = simulate(build_setup(sc), seed=seed)
    out = result.summary()
    out.update(summarize_result(sc, result))
    return out


# --------------------------------------------------------------------------------------
# Table 3 sweep (§10.6)
# --------------------------------------------------------------------------------------
SWEEP_RATES_DEG_S = (1.0, 2.0, 3.0, 4.0, 5.0)
SWEEP_A_MAX_MPS2 = (0.10, 0.05, 0.02)
# Iskender 2026 Table 3: (w_t deg/s, a_max) -> (r_sync m, hold, r_min m)
PAPER_TABLE3 = {
    (1.0, 0.10): (656.6, False, 0.0), (1.0, 0.05): (328.3, False, 143.7), (1.0, 0.02): (131.3, False, 145.3),
    (2.0, 0.10): (164.1, False, 143.0), (2.0, 0.05): (82.1, False, 141.9), (2.0, 0.02): (32.8, False, 111.8),
    (3.0, 0.10): (73.0, False, 138.2), (3.0, 0.05): (36.5, False, 111.4), (3.0, 0.02): (14.6, False, 67.1),
    (4.0, 0.10): (41.0, False, 113.2), (4.0, 0.05): (20.5, False, 67.3), (4.0, 0.02): (8.2, False, 62.1),
    (5.0, 0.10): (26.3, False, 75.0), (5.0, 0.05): (13.1, False, 63.9), (5.0, 0.02): (5.3, False, 51.1),
}
SWEEP_METRICS = ("r_sync_m", "hold_reached", "r_min_m", "los_violations", "max_violation_m", "outcome", "feasible",
                  "initial_range_m", "total_dv_mps")


def sweep_frame(table):
    """Campaign rows (``disp.*``/``metric.*`` columns) -> the sweep DataFrame of :func:`run_sweep`."""
    import pandas as pd

    out = pd.DataFrame({
        "tumble_rate_deg_s": table["disp.target.tumble_rate_deg_s"].astype(float),
        "a_max_mps2": table["disp.chaser.a_max_mps2"].astype(float),
        "mode": table["disp.mpc.constraint_mode"].astype(str) if "disp.mpc.constraint_mode" in table else "hard",
    })
    for key in SWEEP_METRICS:
        col = "metric." + key
        out[key] = table[col] if col in table else np.nan
    return out


def sweep_table(source) -> str:
    """Table 3 in the paper's layout (Markdown), ours next to the paper's columns.

    ``source``: sweep DataFrame (:func:`proxops.analysis.los_sweep.run_sweep`) or campaign rows
    (a campaign folder: :func:`proxops.analysis.los_sweep.sweep_table`). Hold / r_min /
    violations are given for the hard (QP infeasible = failed run, §9.3) and the soft
    (exact-penalty slack, the run continues) constraint modes."""
    import pandas as pd

    df = source if isinstance(source, pd.DataFrame) and "mode" in source else sweep_frame(source)
    lines = [
        "| w_t (deg/s) | a_max (m/s^2) | r_sync (m) | paper r_sync | start (m) | Hold hard/soft | paper Hold "
        "| r_min (m) hard/soft | paper r_min | hard outcome | soft violations (steps, max m) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    yn = lambda b: "Yes" if bool(b) else "No"  # noqa: E731
    for w in SWEEP_RATES_DEG_S:
        for a in SWEEP_A_MAX_MPS2:
            sel = df[np.isclose(df.tumble_rate_deg_s, w) & np.isclose(df.a_max_mps2, a)]
            hard = sel[sel["mode"] == "hard"]
            soft = sel[sel["mode"] == "soft"]
            h = hard.iloc[0] if len(hard) else None
            so = soft.iloc[0] if len(soft) else None
            any_row = h if h is not None else so
            if any_row is None:
                continue
            paper = PAPER_TABLE3.get((w, a), (np.nan, None, np.nan))
            hold = f"{yn(h.hold_reached) if h is not None else '-'}/{yn(so.hold_reached) if so is not None else '-'}"
            rmin = (f"{h.r_min_m:.1f}" if h is not None else "-") + "/" + (f"{so.r_min_m:.1f}" if so is not None else "-")
            hard_out = "-" if h is None else ("feasible" if bool(h.feasible) else str(h.outcome))
            viol = "-" if so is None else f"{int(so.los_violations)}, {so.max_violation_m:.3g}"
            lines.append(
                f"| {w:g} | {a:.2f} | {any_row.r_sync_m:.1f} | {paper[0]:.1f} | {any_row.initial_range_m:.0f} | {hold} "
                f"| {'No' if paper[1] is False else '-'} | {rmin} | {paper[2]:.1f} | {hard_out} | {viol} |"
            )
    return "\n".join(lines)


@register_system("los")
class LosSystem(SystemBase):
    Scenario = LosScenario

    def build(self, sc: LosScenario) -> Setup:
        return build_setup(sc)

    def summarize(self, sc: LosScenario, result) -> dict:
        return summarize_result(sc, result)

    def success(self, sc: LosScenario, summary: dict) -> bool:
        """Campaign classification (§9 step 3, :func:`is_feasible_run`) from a run summary:
        zero violations > 1e-3 m, no QP infeasibility, no early termination."""
        return is_feasible_run(summary.get("los_violations"), summary.get("max_violation_m"),
                               summary.get("qp_infeasible"), summary.get("outcome"))

    def campaign_table(self, sc: LosScenario, table) -> str:
        """Table 3 layout (§10.6) when the campaign is a tumble-rate x a_max grid, else ''."""
        if not {"disp.target.tumble_rate_deg_s", "disp.chaser.a_max_mps2"} <= set(table.columns):
            return ""
        return sweep_table(sweep_frame(table))
