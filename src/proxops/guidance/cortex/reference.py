"""CORTEX reference generation: the outer problem (Wijayatunga et al. eq. 12, Algorithm 1)
over the fly-around CP1 and the final approach CP2 (:mod:`proxops.guidance.cortex.phases`).

Frame: Hill/RTN (x radial out, y along-track, z orbit normal). The paper's relative
frame is the same: its CW model (eq. 1) has 3n^2 x + 2n ydot in the first row, so the
paper's ``e = [-sin(pi/4), -sin(pi/4), 0]`` (§5.1.2) is Hill ``[-0.7071, -0.7071, 0]``
(radially down and behind the target) and the start ``[0, -r_AS/2, 0]`` is on the V-bar
behind the target.

Outer search (eq. 12). J = sum_i (tau_i + tau_hi + eps_C C_i). Its structure decides the
method:

* C_1 depends on tau_1 only (CP1 joins two fixed states) and C_2 on tau_2 only (CP2
  starts at x_f1 whatever tau_1 is). J holds no delta-v.
* The holds only shift the phases in time: with the sunlight rule, the end of a phase
  ``f(t, tau) = t + hold(t, tau) + tau`` is non-decreasing in its start t and in tau
  (a later start or a longer transfer never makes an earlier sunlit window available).
  So J = t_end(tau_1, tau_2) - t_0 + eps_C (C_1 + C_2) with t_end = f(f(t_0, tau_1), tau_2)
  non-decreasing in both.
* eps_C is read in the unit of tau in Table 2 (minutes): 100 min exceeds the whole range
  tau_ub - tau_lb = 55 min, so any converged phase beats any unconverged one. (Read in
  seconds, 100 s is less than the range and the minimum of J could be an unconverged plan.)

Hence J is minimised by the smallest tau_1 for which CP1 converges and, independently,
the smallest tau_2 for which CP2 converges; the holds follow from those (they need not
enter the search). No PSO is needed: each phase is a 1-D search for the first converged
duration on the grid ``tau_lb + m dt_CP`` (durations that are whole numbers of steps).

* CP1 from a start at rest on the V-bar (a CW equilibrium, as in Table 2): a plan for
  tau stays a plan for tau + m dt (wait m steps at the start with no impulse; the node
  grids coincide), so feasibility of the exact problem is monotone in m and the first
  feasible m is found by galloping (m = 0, 1, 3, 7, ...) then bisection. Caveat: CP1 is
  solved with supporting planes (an inner approximation), which can fail where the
  exact problem is feasible; a non-monotone answer of that heuristic is possible in
  principle, and the first-feasible claim is then relative to the heuristic.
* Any other start (not at rest on the V-bar), and CP2 always (its start is not an
  equilibrium): a linear scan from tau_lb upwards, which finds the first converged
  duration without any monotonicity assumption.

The result is optimal on that grid (to one step: 30 s for CP1, 10 s for CP2 in Table 2).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from proxops.constraints.approach_cone import ApproachCone
from proxops.constraints.keep_out import KeepOutSphere
from proxops.constraints.plume import PlumeConstraint
from proxops.errors import input_error
from proxops.guidance.cortex import holds as hold_logic
from proxops.guidance.cortex.config import CortexConfig, unit_axis
from proxops.guidance.cortex.phases import (
    DV_ZERO_MPS,
    PhaseResult,
    arc_min_distance,
    final_state,
    propagate_impulses,
    solve_final_approach,
    solve_flyaround,
)
from proxops.status import Status

def _last_impulse(phase) -> float:
    """|dv| of a phase's last-node (terminal) impulse (m/s), NaN without a solution."""
    if phase is None or getattr(phase, "dv", None) is None or not len(phase.dv):
        return math.nan
    return float(np.linalg.norm(phase.dv[-1]))


@dataclass
class PlanChecks:
    """Independent checks of a returned plan (re-propagated with the closed-form STM)."""

    dynamics_residual: float = math.nan  # max |x_{k+1} - Phi (x_k + [0; dv_k])| over both phases (m or m/s)
    terminal_miss_m: float = math.nan  # |r_N - r_f| after re-propagating the impulses from x_i (per phase, max)
    terminal_miss_mps: float = math.nan
    impulse_ratio_max: float = math.nan  # max ||dv_k|| / (a_bar dt_k)
    kos_node_margin_m: float = math.nan  # min over free CP1 nodes of ||r|| - rho_bar
    kos_arc_min_range_m: float = math.nan  # min range on the continuous CP1 arcs
    kos_arc_penetration_m: float = math.nan  # max(0, rho_bar - min arc range): worst inter-node penetration
    kos_arc_true_penetration_m: float = math.nan  # same against the true r_KOS
    cone_margin_m: float = math.nan  # min over CP2 nodes of e.r - ||r|| cos(alpha_c_bar)
    plume_margin_deg: float = math.nan  # min over thrusting CP2 nodes of angle(dv, r) - alpha_p_bar
    sunlit: bool | None = None  # both transfers in sunlight on the profile (None: no profile)
    passed: bool = False
    failures: list = field(default_factory=list)


# Tolerances of the checks (stated in the report)
TOL_DYN = 1e-6  # m and m/s
TOL_IMPULSE = 1e-6  # relative excess of the impulse bound
TOL_KOS_M = 1e-5
TOL_CONE_M = 1e-5
TOL_PLUME_DEG = 0.01


@dataclass
class CortexPlan:
    """A reference (or the reason there is none). Times in s, delta-v in m/s, Hill frame. ``status``: OK,
    INFEASIBLE (a phase converged for no duration), INFEASIBLE_SOLUTION (the independent plan check failed)
    or FAILED (the eclipse profile is too short); ``reason`` says which and why."""

    status: Status
    reason: str
    axis: np.ndarray
    tau1_s: float = math.nan
    tau2_s: float = math.nan
    hold1_s: float = math.nan
    hold2_s: float = math.nan
    dv1_mps: float = math.nan
    dv2_mps: float = math.nan
    objective_s: float = math.nan  # J of eq. 12
    evaluations_cp1: int = 0
    evaluations_cp2: int = 0
    kos_iterations: int = 0  # CP1 solves of the returned plan
    scp_iterations: int = 0  # CP2 solves of the returned plan
    compute_time_s: float = math.nan  # the whole plan: outer search, phases and checks
    cp1_solve_times_s: list = field(default_factory=list)
    cp2_solve_times_s: list = field(default_factory=list)
    cp1: PhaseResult | None = None
    cp2: PhaseResult | None = None
    checks: PlanChecks | None = None
    tried: list = field(default_factory=list)  # [(phase, tau_s, status)]

    @property
    def ok(self) -> bool:
        return self.status is Status.OK

    @property
    def dv_total_mps(self) -> float:
        return self.dv1_mps + self.dv2_mps

    @property
    def tof_s(self) -> float:
        """Transfer time tau_1 + tau_2 (holds excluded)."""
        return self.tau1_s + self.tau2_s

    @property
    def total_time_s(self) -> float:
        """Mission time with the holds: tau_h1 + tau_1 + tau_h2 + tau_2."""
        return self.tau1_s + self.tau2_s + self.hold1_s + self.hold2_s

    def summary(self) -> dict:
        """Flat, JSON-ready keys (units in the names)."""
        c = self.checks
        out = {
            "status": self.status.value, "reason": self.reason,
            "axis_x": float(self.axis[0]), "axis_y": float(self.axis[1]), "axis_z": float(self.axis[2]),
            "tau1_s": self.tau1_s, "tau2_s": self.tau2_s, "hold1_s": self.hold1_s, "hold2_s": self.hold2_s,
            "dv1_mps": self.dv1_mps, "dv2_mps": self.dv2_mps, "dv_total_mps": self.dv_total_mps,
            "tof_s": self.tof_s, "total_time_s": self.total_time_s, "objective_s": self.objective_s,
            "evaluations_cp1": self.evaluations_cp1, "evaluations_cp2": self.evaluations_cp2,
            "kos_iterations": self.kos_iterations, "scp_iterations": self.scp_iterations,
            "plan_wall_time_s": self.compute_time_s,
            "cp1_solve_time_median_s": float(np.median(self.cp1_solve_times_s)) if self.cp1_solve_times_s else math.nan,
            "cp2_solve_time_median_s": float(np.median(self.cp2_solve_times_s)) if self.cp2_solve_times_s else math.nan,
            "n_cp1_solves": len(self.cp1_solve_times_s), "n_cp2_solves": len(self.cp2_solve_times_s),
            # the terminal burn at each phase's last node (impulses at nodes 0..N, one more than eqs. 17 / 20), m/s
            "dv1_terminal_mps": _last_impulse(self.cp1), "dv2_terminal_mps": _last_impulse(self.cp2),
        }
        if c is not None:
            out.update({f"check_{k}": v for k, v in asdict(c).items() if k != "failures"})
            out["check_failures"] = "; ".join(c.failures)
        # strict JSON: no NaN/inf (an infeasible plan has no durations)
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in out.items()}

    def trajectory(self, samples_per_interval: int = 1) -> dict:
        """Reference time line (s, from t0): hold 1, CP1, hold 2, CP2. Returns arrays t, x (n, 6),
        dv (n, 3, impulse applied at that node) and phase labels. Holds are two nodes each
        (station keeping at the hold point is not part of the reference)."""
        if self.cp1 is None or self.cp2 is None or self.cp1.x is None or self.cp2.x is None:
            return {"t": np.zeros(0), "x": np.zeros((0, 6)), "dv": np.zeros((0, 3)), "phase": []}
        h1 = 0.0 if not math.isfinite(self.hold1_s) else self.hold1_s
        h2 = 0.0 if not math.isfinite(self.hold2_s) else self.hold2_s
        t, x, dv, ph = [], [], [], []
        if h1 > 0:
            t.append(0.0); x.append(self.cp1.x[0]); dv.append(np.zeros(3)); ph.append("hold1")  # noqa: E702
        t1 = h1 + self.cp1.t
        d1 = self.cp1.dv
        t += list(t1); x += list(self.cp1.x); dv += list(d1); ph += ["flyaround"] * len(t1)
        t2 = h1 + self.tau1_s + h2 + self.cp2.t
        d2 = self.cp2.dv
        if h2 > 0:
            ph[-1] = "hold2"
        t += list(t2); x += list(self.cp2.x); dv += list(d2); ph += ["approach"] * len(t2)
        return {"t": np.array(t), "x": np.array(x), "dv": np.array(dv), "phase": ph}


class _Timer:
    def __init__(self):
        self.t0 = time.perf_counter()

    def __call__(self) -> float:
        return time.perf_counter() - self.t0


def first_converged(solve, grid: np.ndarray, monotone: bool, tried: list, label: str):
    """Smallest grid duration whose phase converges: galloping + bisection when feasibility is
    monotone, a linear scan otherwise. Returns (index or None, results by index)."""
    results: dict[int, PhaseResult] = {}

    def ok(i: int) -> bool:
        if i not in results:
            results[i] = solve(float(grid[i]))
            tried.append((label, float(grid[i]), results[i].status))
        return results[i].ok

    if not monotone:
        for i in range(len(grid)):
            if ok(i):
                return i, results
        return None, results
    if ok(0):
        return 0, results
    lo, step, hi = 0, 1, None
    while hi is None:
        cand = min(lo + step, len(grid) - 1)
        if ok(cand):
            hi = cand
        elif cand == len(grid) - 1:
            return None, results
        else:
            lo, step = cand, 2 * step
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if ok(mid):
            hi = mid
        else:
            lo = mid
    return hi, results


def duration_grid(tau_lb_s: float, tau_ub_s: float, dt_s: float) -> np.ndarray:
    """tau_lb + m dt for m = 0, 1, ... up to tau_ub (s)."""
    m = int(math.floor((tau_ub_s - tau_lb_s) / dt_s + 1e-9))
    return tau_lb_s + dt_s * np.arange(m + 1)


def _is_vbar_rest(x0: np.ndarray, tol: float = 1e-9) -> bool:
    scale = max(1.0, float(np.linalg.norm(x0[:3])))
    return abs(x0[0]) <= tol * scale and abs(x0[2]) <= tol * scale and float(np.linalg.norm(x0[3:])) <= tol


def plan_reference(axis, cfg: CortexConfig, eclipse=None, t0_s: float = 0.0) -> CortexPlan:
    """Plan the reference for docking axis ``axis`` (Hill, normalised here).

    ``eclipse``: optional sampled profile ``(t_ecl_s, eta)`` (s from the scenario epoch, flags
    1 = sunlit) for the holds of Algorithm 1; None: no eclipse (holds are zero). Bad input
    raises ProxopsInputError; a plan that cannot be found is a status with a reason."""
    clock = _Timer()
    cfg.validate()
    e = unit_axis(axis)
    x_i1 = np.asarray(cfg.start_state, float)
    rho_bar = cfg.rho_bar
    r_f1 = rho_bar if cfg.flyaround_end_range_m is None else float(cfg.flyaround_end_range_m)
    x_f1 = np.concatenate([r_f1 * e, np.zeros(3)])
    if cfg.approach_end_position_m is not None:
        r_f2 = np.asarray(cfg.approach_end_position_m, float)
        if r_f2.shape != (3,) or not np.all(np.isfinite(r_f2)):
            raise input_error("approach end position", list(np.ravel(r_f2)), "must be 3 finite numbers", "m")
    else:
        r_f2 = cfg.approach_end_range_m * e
    x_f2 = np.concatenate([r_f2, np.zeros(3)])
    cone = ApproachCone(e, cfg.alpha_c_bar)
    if not cone.contains(r_f2, tol_m=1e-9) or np.linalg.norm(r_f2) < 1e-9:
        raise input_error("approach end position", np.round(r_f2, 6).tolist(),
                          f"lies outside the approach cone (half-angle cone_margin x alpha_c = "
                          f"{math.degrees(cfg.alpha_c_bar):.3f} deg about the axis {np.round(e, 6).tolist()})", "m")
    plume = PlumeConstraint(cfg.alpha_p_bar)
    if eclipse is not None:
        t_ecl, eta = hold_logic.check_profile(*eclipse)
    plan = CortexPlan(status=Status.INFEASIBLE, reason="", axis=e)
    n = cfg.mean_motion_rad_s

    def cp1(tau):
        return solve_flyaround(n, tau, cfg.dt_cp1_s, x_i1, x_f1, cfg.a_bar, rho_bar, kos_max_iter=cfg.kos_max_iter,
                               arc_planes=cfg.kos_arc_planes)

    def cp2(tau):
        return solve_final_approach(n, tau, cfg.dt_cp2_s, x_f1, x_f2, cfg.a_bar, cone, plume,
                                    scp_max_iter=cfg.scp_max_iter, scp_tol_mps=cfg.scp_tol_mps,
                                    plume_tol_rad=cfg.plume_tol_rad)

    # a fixed duration replaces the search of that phase (a one-point grid)
    g1 = np.array([float(cfg.tau1_s)]) if cfg.tau1_s is not None else duration_grid(cfg.tau_lb_s, cfg.tau_ub_s, cfg.dt_cp1_s)
    g2 = np.array([float(cfg.tau2_s)]) if cfg.tau2_s is not None else duration_grid(cfg.tau_lb_s, cfg.tau_ub_s, cfg.dt_cp2_s)
    mono1 = cfg.search == "auto" and _is_vbar_rest(x_i1)
    i1, res1 = first_converged(cp1, g1, mono1, plan.tried, "cp1")
    i2, res2 = first_converged(cp2, g2, False, plan.tried, "cp2")
    plan.evaluations_cp1, plan.evaluations_cp2 = len(res1), len(res2)
    for r in res1.values():
        plan.cp1_solve_times_s += r.solve_times_s
    for r in res2.values():
        plan.cp2_solve_times_s += r.solve_times_s
    reasons = []
    if i1 is None:
        last = res1[max(res1)]
        reasons.append(f"CP1 did not converge for any tau_1 in [{g1[0]:g}, {g1[-1]:g}] s "
                       f"(tau_1 = {g1[max(res1)]:g} s: {last.status}: {last.reason})")
    else:
        plan.cp1 = res1[i1]
        plan.tau1_s = float(g1[i1])
        plan.dv1_mps = plan.cp1.dv_total_mps
        plan.kos_iterations = plan.cp1.iterations
    if i2 is None:
        last = res2[max(res2)]
        reasons.append(f"CP2 did not converge for any tau_2 in [{g2[0]:g}, {g2[-1]:g}] s "
                       f"(tau_2 = {g2[max(res2)]:g} s: {last.status}: {last.reason})")
    else:
        plan.cp2 = res2[i2]
        plan.tau2_s = float(g2[i2])
        plan.dv2_mps = plan.cp2.dv_total_mps
        plan.scp_iterations = plan.cp2.iterations
    if reasons:
        plan.status, plan.reason = Status.INFEASIBLE, "; ".join(reasons)
        plan.objective_s = math.inf
        plan.compute_time_s = clock()
        return plan
    # holds (Algorithm 1) on the chosen durations
    if eclipse is None:
        plan.hold1_s = plan.hold2_s = 0.0
    else:
        plan.hold1_s = hold_logic.hold_time(t_ecl, eta, t0_s, plan.tau1_s)
        t_end1 = t0_s + plan.hold1_s + plan.tau1_s
        plan.hold2_s = hold_logic.hold_time(t_ecl, eta, t_end1, plan.tau2_s) if math.isfinite(t_end1) else math.inf
    plan.objective_s = plan.tau1_s + plan.tau2_s + plan.hold1_s + plan.hold2_s  # C_1 = C_2 = 0
    plan.checks = check_plan(plan, cfg, x_i1, x_f1, x_f2, cone, plume, eclipse=(t_ecl, eta) if eclipse is not None else None,
                             t0_s=t0_s)
    if not (math.isfinite(plan.hold1_s) and math.isfinite(plan.hold2_s)):
        plan.status, plan.reason = Status.FAILED, "eclipse profile short: it ends before a sunlit window fits; extend it"
    elif not plan.checks.passed:
        plan.status, plan.reason = Status.INFEASIBLE_SOLUTION, "plan check failed: " + "; ".join(plan.checks.failures)
    else:
        plan.status, plan.reason = Status.OK, ""
    plan.compute_time_s = clock()
    return plan


def check_plan(plan: CortexPlan, cfg: CortexConfig, x_i1, x_f1, x_f2, cone: ApproachCone, plume: PlumeConstraint,
               eclipse=None, t0_s: float = 0.0) -> PlanChecks:
    """Check a plan against the constraints, independently of the solver's own report."""
    n = cfg.mean_motion_rad_s
    c = PlanChecks()
    fails = c.failures
    dyn, miss_r, miss_v, ratio = 0.0, 0.0, 0.0, 0.0
    for ph, x0, xf in ((plan.cp1, x_i1, x_f1), (plan.cp2, x_f1, x_f2)):
        xp = propagate_impulses(n, ph.t, x0, ph.dv)
        dyn = max(dyn, float(np.abs(xp - ph.x).max()))
        end = final_state(xp, ph.dv)
        miss_r = max(miss_r, float(np.linalg.norm(end[:3] - xf[:3])))
        miss_v = max(miss_v, float(np.linalg.norm(end[3:] - xf[3:])))
        dt = np.diff(ph.t)
        ratio = max(ratio, float((np.linalg.norm(ph.dv, axis=1) / (cfg.a_bar * np.append(dt, dt.max()))).max()))
    c.dynamics_residual, c.terminal_miss_m, c.terminal_miss_mps, c.impulse_ratio_max = dyn, miss_r, miss_v, ratio
    if dyn > TOL_DYN:
        fails.append(f"dynamics residual {dyn:.3g} > {TOL_DYN:g}")
    if miss_r > TOL_DYN or miss_v > TOL_DYN:
        fails.append(f"terminal miss {miss_r:.3g} m / {miss_v:.3g} m/s > {TOL_DYN:g}")
    if ratio > 1.0 + TOL_IMPULSE:
        fails.append(f"impulse bound exceeded: max ||dv||/(a_bar dt) = {ratio:.6f}")
    sphere = KeepOutSphere(cfg.rho_bar)
    x1 = plan.cp1.x
    c.kos_node_margin_m = float(sphere.distance_to_surface(x1[1:-1, :3]).min()) if len(x1) > 2 else math.inf
    if c.kos_node_margin_m < -TOL_KOS_M:
        fails.append(f"CP1 node inside the inflated KOS by {-c.kos_node_margin_m:.3g} m")
    rmin, _ = arc_min_distance(n, plan.cp1.t, x1, plan.cp1.dv)
    c.kos_arc_min_range_m = rmin
    c.kos_arc_penetration_m = max(0.0, cfg.rho_bar - rmin)
    c.kos_arc_true_penetration_m = max(0.0, cfg.r_kos_m - rmin)
    if c.kos_arc_true_penetration_m > TOL_KOS_M:
        fails.append(f"CP1 coast arc enters the true KOS by {c.kos_arc_true_penetration_m:.3g} m")
    x2 = plan.cp2.x
    c.cone_margin_m = float(cone.margin(x2[:, :3]).min())
    if c.cone_margin_m < -TOL_CONE_M:
        fails.append(f"CP2 node outside the approach cone by {-c.cone_margin_m:.3g} m")
    pm = plume.margin_rad(x2[:, :3], plan.cp2.dv, DV_ZERO_MPS)
    c.plume_margin_deg = float(np.degrees(pm.min())) if np.isfinite(pm).any() else math.inf
    if c.plume_margin_deg < -TOL_PLUME_DEG:
        fails.append(f"CP2 plume angle below alpha_p_bar by {-c.plume_margin_deg:.3g} deg")
    if eclipse is not None:
        t_ecl, eta = eclipse
        s1 = t0_s + plan.hold1_s
        s2 = s1 + plan.tau1_s + plan.hold2_s
        c.sunlit = bool(math.isfinite(s2) and hold_logic.transfer_in_sunlight(t_ecl, eta, s1, plan.tau1_s)
                        and hold_logic.transfer_in_sunlight(t_ecl, eta, s2, plan.tau2_s))
        if not c.sunlit:
            fails.append("a transfer is not entirely in sunlight on the eclipse profile")
    c.passed = not fails
    return c
