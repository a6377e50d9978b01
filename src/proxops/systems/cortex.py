"""System ``cortex``: eclipse-aware convex reference generation (Wijayatunga et al. §3.1, §5.1.1).

Scenario ``cortex-reference`` (src/proxops/scenarios/builtin/cortex-reference.toml)::

    proxops cortex reference --axis -0.7071 -0.7071 0 --json
    proxops cortex references --n 100 --workers 2 --out out/cortex
    proxops run cortex-reference --json        # same plan through the runner

Without ``guidance.closed_loop`` a "run" of this system is one plan: :meth:`CortexSystem.run`
returns the reference as a SimResult (states at the nodes, impulses as ``u_cmd``), so the
campaign engine plans the Fibonacci axes as a grid campaign
(``[dispersions] "axis.fibonacci_index" = {grid = [...]}``). With ``guidance.closed_loop = true``
the reference is tracked by the convex guidance CP_g on the full truth, with the Table 1
recompute and abort triggers (:mod:`proxops.systems.cortex_loop`, ``cortex-nominal``).

Eclipse: Earth shadow (conical umbra/penumbra by default) along the Keplerian CSO orbit
of §5.1 from ``orbit.epoch_utc`` (:func:`proxops.environment.eclipse.eclipse_profile`),
``samples_per_orbit`` = 1000 as in §3.1.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from proxops.errors import input_error
from proxops.scenarios.catalog import read_toml, resolve
from proxops.scenarios.registry import register_system
from proxops.sim.result import SimResult
from proxops.status import Status
from proxops.systems.base import SystemBase
from proxops.systems.cortex_setup import check_loop, config_from_scenario, plan_scenario, scenario_axis
from proxops.systems.schema.cortex import MAX_FIBONACCI_N, CortexScenario

PAPER_5_1_1 = {  # §5.1.1, 100 Fibonacci axes
    "dv_median_mps": 0.6579, "dv_iqr_mps": 0.1600,
    "tof_median_min": 12.07, "tof_iqr_min": 1.7723,
    "compute_median_s": 30.9, "compute_iqr_s": 7.23, "compute_std_s": 5.01,
}
PAPER_5_1_2 = {"tof_min": 19.66, "tau1_min": 14.66, "tau2_min": 4.5, "dv_mps": 1.1740}  # fixed axis


def plan_to_result(sc: CortexScenario, plan):
    """The plan as a SimResult (t, node states, impulses as u_cmd, phase as mode)."""

    traj = plan.trajectory()
    if len(traj["t"]) == 0:
        x0 = np.asarray(config_from_scenario(sc).start_state, float)
        traj = {"t": np.zeros(1), "x": x0[None, :], "dv": np.zeros((1, 3)), "phase": ["none"]}
    dv = traj["dv"]
    n = len(traj["t"])
    return SimResult(
        t=traj["t"], x_true=traj["x"], x_est=traj["x"].copy(), u_cmd=dv, u_applied=dv.copy(),
        dv_cum=np.cumsum(np.linalg.norm(dv, axis=1)), status=[plan.status] * n,
        solve_time_s=np.zeros(n), mode=list(traj["phase"]), info={},
        meta={"system": "cortex", "outcome": plan.status.value, "wall_time_s": plan.compute_time_s,
              "control": "impulse", "frame": "Hill/RTN", "axis": np.asarray(plan.axis, dtype=float).tolist()},
    )


def summarize_plan(plan) -> dict:
    return plan.summary()


def plan_trace(plan) -> dict:
    """The plan's node positions for the campaign's Fig. 11 drawn from the table (no saved series): Hill
    x, y, z (m, 0.1 mm rounding) of the nodes of hold 1 and CP1, then of CP2 from index ``approach_from``.
    About 2 kB per plan; empty without a plan."""
    traj = plan.trajectory()
    if len(traj["t"]) == 0:
        return {}
    r = np.round(traj["x"][:, :3], 4)
    return {"x": r[:, 0].tolist(), "y": r[:, 1].tolist(), "z": r[:, 2].tolist(),
            "approach_from": int(sum(p != "approach" for p in traj["phase"]))}


def _loop():
    """The closed loop's module (engine, solvers, numba): imported only when a loop is run or built."""
    from proxops.systems import cortex_loop

    return cortex_loop


@register_system("cortex")
class CortexSystem(SystemBase):
    Scenario = CortexScenario

    def run(self, sc: CortexScenario, seed: int = 0, progress: bool = False):
        if sc.guidance.closed_loop:
            return _loop().run_closed_loop(sc, seed=seed, progress=progress)
        plan = plan_scenario(sc)
        summary = summarize_plan(plan)
        summary["trace"] = plan_trace(plan)
        return summary, {"plan": plan_to_result(sc, plan)}

    def check(self, sc: CortexScenario) -> None:
        """The checks a plan makes before solving (``validate`` and campaigns call this)."""
        config_from_scenario(sc).validate()
        scenario_axis(sc)
        if sc.guidance.closed_loop:
            check_loop(sc)

    def warm_up(self, sc: CortexScenario) -> None:
        """The check, and for the planner one plan of the scenario's axis: what a campaign worker would do
        first (solver and numba imports, the eclipse profile and phase set-ups cached per process), done once
        by the pool's fork server (:mod:`proxops.exec.worker_warmup`) before it forks the workers."""
        self.check(sc)
        if not sc.guidance.closed_loop:
            plan_scenario(sc)

    def build(self, sc: CortexScenario):
        if sc.guidance.closed_loop:
            return _loop().build_setup(sc)[0]
        raise input_error("system", "cortex", "is a planner: use proxops run / proxops cortex reference (no closed loop)")

    def summarize(self, sc: CortexScenario, result) -> dict:
        return {}

    def success(self, sc: CortexScenario, summary: dict) -> bool:
        if sc.guidance.closed_loop:
            return str(summary.get("status", "")) == "docked"
        return Status.parse(summary.get("status", "")) is Status.OK

    def campaign_table(self, sc: CortexScenario, table) -> str:
        if sc.guidance.closed_loop:
            return _loop().table4(sc, table)
        if "metric.dv_total_mps" not in table:
            return ""
        return statistics_table(campaign_statistics(table))


def references_scenario(scenario: str, n: int) -> dict:
    """The scenario data with the Fibonacci grid: ``axis.fibonacci_index`` = 0..n-1 (overrides are
    applied by the campaign engine)."""
    if isinstance(n, bool) or not 1 <= n <= MAX_FIBONACCI_N:
        raise input_error("--n", n, f"must be a whole number from 1 to {MAX_FIBONACCI_N:,}")
    data = copy.deepcopy(read_toml(resolve(scenario)))
    if data.get("system") != "cortex":
        raise input_error("--scenario", scenario, f"is a {data.get('system')!r} scenario; give a cortex one "
                          "(system = \"cortex\", e.g. cortex-reference)")
    data.setdefault("axis", {})["fibonacci_n"] = int(n)
    data["axis"].pop("fibonacci_index", None)
    data["axis"]["fibonacci_index"] = 0
    data["dispersions"] = {"axis.fibonacci_index": {"grid": list(range(int(n)))}}
    data["name"] = f"{data.get('name', 'cortex')}-fibonacci-{n}"
    return data


def campaign_statistics(table) -> dict:
    """Median / IQR of delta-v, TOF (tau_1 + tau_2) and compute time over the successful plans."""
    ok = table[table["success"].astype(bool)] if "success" in table else table

    def stats(col, scale=1.0):
        v = ok[col].astype(float).to_numpy() * scale if col in ok else np.zeros(0)
        if v.size == 0:
            return {"median": math.nan, "iqr": math.nan, "max": math.nan, "std": math.nan}
        q1, q2, q3 = np.percentile(v, [25, 50, 75])
        return {"median": float(q2), "iqr": float(q3 - q1), "max": float(v.max()), "std": float(v.std(ddof=1)) if v.size > 1 else 0.0}

    return {
        "n_plans": int(len(table)), "n_ok": int(len(ok)),
        "dv_mps": stats("metric.dv_total_mps"), "tof_min": stats("metric.tof_s", 1 / 60),
        "total_time_min": stats("metric.total_time_s", 1 / 60),
        "compute_s": stats("metric.plan_wall_time_s"),
        "tau1_min": stats("metric.tau1_s", 1 / 60), "tau2_min": stats("metric.tau2_s", 1 / 60),
        "hold_total_min": {"median": float(np.median((ok["metric.hold1_s"] + ok["metric.hold2_s"]).astype(float)) / 60)
                           if len(ok) else math.nan},
        "cp1_solve_median_s": float(np.nanmedian(ok["metric.cp1_solve_time_median_s"].astype(float))) if len(ok) else math.nan,
        "cp2_solve_median_s": float(np.nanmedian(ok["metric.cp2_solve_time_median_s"].astype(float))) if len(ok) else math.nan,
    }


def statistics_table(st: dict) -> str:
    """Markdown: our medians/IQRs next to §5.1.1."""
    p = PAPER_5_1_1
    return "\n".join([
        f"| quantity ({st['n_ok']}/{st['n_plans']} plans ok) | median | IQR | paper median | paper IQR |",
        "|---|---|---|---|---|",
        f"| delta-v (m/s) | {st['dv_mps']['median']:.4f} | {st['dv_mps']['iqr']:.4f} | {p['dv_median_mps']} | {p['dv_iqr_mps']} |",
        f"| TOF tau_1 + tau_2 (min) | {st['tof_min']['median']:.2f} | {st['tof_min']['iqr']:.4f} | {p['tof_median_min']} | {p['tof_iqr_min']} |",
        f"| time with holds (min) | {st['total_time_min']['median']:.2f} | {st['total_time_min']['iqr']:.4f} | - | - |",
        f"| compute time per plan (s) | {st['compute_s']['median']:.4f} | {st['compute_s']['iqr']:.4f} | {p['compute_median_s']} | {p['compute_iqr_s']} |",
    ])
