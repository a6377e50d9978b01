"""System ``underactuated``: NMPC docking of a planar underactuated 6U CubeSat
(Aborizk et al.).

Scenarios (src/proxops/scenarios/builtin/underactuated-*.toml)::

    proxops run underactuated-case1 --json          # §5 / Figs. 2-3, averaged-value MPC
    proxops run underactuated-compare --out out/cmp # Figs. 4-5, general vs averaged
    proxops run underactuated-case2 --out out/c2    # Figs. 6-9, Table 3 limits, c = 0 and 1e-3

Plant: :class:`proxops.dynamics.planar_cubesat.PlanarCubeSatPlant` — the measured state is
the planar state ``[x, y, theta, vx, vy, omega]`` (m, rad, m/s, rad/s; positions are
``[0:2]``, velocities ``[3:5]``); control ``[thrust N, wheel_acc rad/s^2]``. Controller:
:class:`proxops.control.nmpc_underactuated.UnderactuatedNMPC`. A run stops with outcome
``docked`` when the true state enters the Table 1 admissible set.

A scenario may run several closed loops (``[[runs]]``: variant, horizon, damping per run);
the first is the main one. The JSON summary adds ``docked``, ``steps``, ``dock_time_s``,
``value_function_monotone``, ``value_bound_violations``, ``solve_time_ms_per_step`` and, with
several runs, ``runs`` (the same keys per run) and ``step_time_ratio`` (median step time of
each run over the fastest).
"""

from __future__ import annotations

import math

import numpy as np

from proxops.control.nmpc_underactuated import NMPCConfig, UnderactuatedNMPC
from proxops.dynamics.planar_cubesat import PlanarCubeSatPlant
from proxops.errors import input_error
from proxops.navigation.mekf import attitude_summary, consistency_keys
from proxops.navigation.planar_ekf import PlanarPoseEKF
from proxops.scenarios.registry import register_system
from proxops.sim.engine import Setup, simulate
from proxops.solvers.stats import solve_time_stats
from proxops.systems.base import SystemBase
from proxops.systems.common import navigation_model
from proxops.systems.schema.underactuated import (UnderactuatedScenario, initial_vector, model_objects,
                                                  run_configs)


def planar_sigma(position_sigma_m: float, velocity_sigma_mps: float) -> np.ndarray:
    """Navigation 1-sigma per planar state component: position on x, y, velocity on vx, vy;
    the attitude and its rate are measured exactly."""
    p, v = position_sigma_m, velocity_sigma_mps
    return np.array([p, p, 0.0, v, v, 0.0])


def build_setup(sc: UnderactuatedScenario, run: dict | None = None) -> Setup:
    """Plant, NMPC and stop condition for one closed loop (``run`` from :func:`run_configs`)."""
    run = run or run_configs(sc)[0]
    params, limits, docking = model_objects(sc, run["damping_Nms"])
    c = sc.controller
    config = NMPCConfig(
        variant=run["variant"],
        horizon=run["horizon"],
        dt_s=c.dt_s,
        average_window=c.average_window,
        q_diag=tuple(c.q),
        r_diag=tuple(c.r),
        terminal_weight=c.terminal_weight,
        terminal_box_fraction=c.terminal_box_fraction,
        solver=c.solver,
        model_substeps=c.model_substeps,
        max_iter=c.max_iter,
    )
    controller = UnderactuatedNMPC(params, limits, config, docking)
    plant = PlanarCubeSatPlant(params, initial_vector(sc.initial_state))
    meta = {"run": run}
    if sc.navigation.model == "ekf":  # planar pose estimated
        navigation = planar_navigation(sc, params, c.dt_s)
        meta["attitude_filter"] = navigation.record  # filled during the run (summary: att_*, pose_nees_*)
    else:
        navigation = navigation_model(sc.navigation, per_state_sigma=planar_sigma,
                                      system="underactuated (planar state)")

    def docked(t: float, s: np.ndarray) -> str | None:
        return "docked" if docking.contains(s) else None

    return Setup(
        plant=plant,
        controller=controller,
        duration_s=sc.sim.duration_s,
        navigation=navigation,
        stop_condition=docked,
        check_substeps=sc.sim.check_substeps,
        meta=meta,
    )


def planar_navigation(sc: UnderactuatedScenario, params, control_dt_s: float):
    """:class:`proxops.navigation.planar_ekf.PlanarPoseEKF` of a ``model = "ekf"`` [navigation] section:
    pose [x, y, theta] with ``range_sigma_m`` per position axis and ``attitude_sigma_deg``; process noise
    ``process_noise_m2_s3`` (translation) and ``attitude_process_noise_rad2_s3`` (rotation); initial sigmas
    initial_position_sigma_m, initial_velocity_sigma_mps, initial_attitude_sigma_deg, initial_rate_sigma_deg_s."""
    nav = sc.navigation
    period = nav.update_period_s
    if period is not None:
        ratio = control_dt_s / period
        if period > control_dt_s * (1 + 1e-9) or abs(ratio - round(ratio)) > 1e-6:
            raise input_error("navigation.update_period_s", period,
                              f"must divide the control period {control_dt_s:g} s", "s")
    p0 = np.diag([nav.initial_position_sigma_m ** 2] * 2 + [math.radians(nav.initial_attitude_sigma_deg) ** 2]
                 + [nav.initial_velocity_sigma_mps ** 2] * 2 + [math.radians(nav.initial_rate_sigma_deg_s) ** 2])
    return PlanarPoseEKF(params, p0, nav.range_sigma_m, math.radians(nav.attitude_sigma_deg),
                         q_accel_m2_s3=nav.process_noise_m2_s3, q_angular_rad2_s3=nav.attitude_process_noise_rad2_s3,
                         fov_rad=math.radians(nav.attitude_fov_deg), outage_probability=nav.outage_probability,
                         gate_probability=nav.gate_probability, period_s=period)


def summarize_result(sc: UnderactuatedScenario, result) -> dict:
    """Docking outcome, value-function behaviour and per-step computation of one run."""
    solved = result.solve_time_s[: max(len(result.t) - 1, 0)]
    value = result.info.get("value_function", np.full(len(result.t), np.nan))[: len(solved)]
    bound = result.info.get("value_bound", np.full(len(result.t), np.nan))[: len(solved)]
    relaxed = result.info.get("bound_relaxed", np.zeros(len(result.t)))[: len(solved)]
    finite = value[np.isfinite(value)]
    docked = result.meta.get("outcome") == "docked"
    active = np.isfinite(bound) & np.isfinite(value)
    out = {
        "docked": bool(docked),
        "steps": int(len(result.t) - 1),
        "dock_time_s": float(result.t[-1]) if docked else None,
        "value_function_monotone": bool(finite.size > 1 and np.all(np.diff(finite) <= 1e-9 * max(1.0, finite.max()))),
        "value_function_increases": int(np.sum(np.diff(finite) > 1e-9 * max(1.0, finite.max()))) if finite.size else 0,
        "value_bound_violations": int(np.sum(np.nan_to_num(relaxed) > 0)),
        "value_bound_steps": int(np.sum(active)),
        "final_state": {
            "x_m": float(result.x_true[-1, 0]),
            "y_m": float(result.x_true[-1, 1]),
            "theta_deg": float(np.degrees(result.x_true[-1, 2])),
            "vx_mps": float(result.x_true[-1, 3]),
            "vy_mps": float(result.x_true[-1, 4]),
            "omega_deg_s": float(np.degrees(result.x_true[-1, 5])),
        },
        "solve_time_ms": solve_time_stats(solved),  # whole controller step (shift + NLP + checks)
        "solve_time_ms_per_step": [round(float(v) * 1e3, 3) for v in solved],
        "mean_iterations": float(np.nanmean(result.info["iterations"][: len(solved)])) if "iterations" in result.info and len(solved) else 0.0,
        "controller_wall_time_s": float(np.sum(solved)),
    }
    if "attitude_filter" in result.meta:
        rec = result.meta["attitude_filter"]
        out.update(attitude_summary(rec))
        out.update(consistency_keys(rec.get("pose_nees", []), rec.get("pose_nees_dof", 6), "pose_nees"))
    return out


@register_system("underactuated")
class UnderactuatedSystem(SystemBase):
    Scenario = UnderactuatedScenario

    def build(self, sc: UnderactuatedScenario) -> Setup:
        return build_setup(sc)

    def summarize(self, sc: UnderactuatedScenario, result) -> dict:
        return summarize_result(sc, result)

    def run(self, sc: UnderactuatedScenario, seed: int = 0, progress: bool = False):
        """Every closed loop of the scenario; the summary keys of the first at top level."""
        results, summaries = {}, {}
        for run in run_configs(sc):
            result = simulate(build_setup(sc, run), seed=seed, progress=progress)
            results[run["label"]] = result
            summary = summarize_result(sc, result)
            summary.update(variant=run["variant"], horizon=run["horizon"], damping_Nms=run["damping_Nms"],
                           wall_time_s=float(result.meta.get("wall_time_s", 0.0)))
            summaries[run["label"]] = summary
        extra = dict(next(iter(summaries.values())))
        if len(summaries) > 1:
            extra["runs"] = {label: {k: v for k, v in s.items() if k != "solve_time_ms_per_step"}
                             for label, s in summaries.items()}
            fastest = min(s["solve_time_ms"]["median"] for s in summaries.values())
            extra["step_time_ratio"] = {label: (s["solve_time_ms"]["median"] / fastest if fastest > 0 else math.nan)
                                        for label, s in summaries.items()}
            extra["all_docked"] = all(s["docked"] for s in summaries.values())
        return extra, results

    def success(self, sc: UnderactuatedScenario, summary: dict) -> bool:
        return bool(summary.get("docked"))

