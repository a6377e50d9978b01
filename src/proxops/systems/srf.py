"""System ``srf``: the Short Range Framework of Silva et al. 2026 (V-bar, R-bar and
glideslope hopping recovered inside an MPC, passive abort safety, CBF keep-out zone).

Scenarios ``srf-vbar``, ``srf-rbar``, ``srf-glideslope-40`` (and -20, -250), ``srf-cbf-demo``
and the Monte Carlo versions ``srf-*-mc``::

    proxops run srf-vbar --json
    proxops mc srf-rbar-mc --runs 50 --json

Frames: the scenario speaks the paper's LVLH (x = V-bar, y = -orbit normal, z = R-bar
towards the Earth) for the approach axis, the initial state (``frame = "lvlh-srf"``) and the
KOZ centre; everything inside (truth, MPC, constraints) is Hill, converted here with
:mod:`proxops.frames.lvlh`.

Defaults the paper does not give (documented choices): KOZ radius 50 m (the reference point is
100 m out), the MPC plans against radius + 10 m (CW-vs-truth and navigation mismatch), CBF alpha 0.01 1/s, free drift x_u sampled 36 times per orbit (200 s), 6 MPC steps per hop, engine step t_orb / 720 (about 10 s, so
half an orbit is an exact number of steps), u_max 3 m/s per axis (the largest designed R-bar
impulse is 2.4 m/s), terminal box 2 m / 5 mm/s, hop tolerances 1 m / 2 mm/s. For the
glideslope and R-bar approaches each hop end must also lie within 10 % of its hop length of the
guidance distance and impulses between hop instants cost twice as much (without these the MPC
finds cheaper multi-impulse transfers that are not hops). V-bar keeps the paper's (29n)-(29o)
plus a tiny quadratic pull (1e-7 per m^2) of the hop ends towards Algorithm 1's distances: radial
hops cost the same fuel for any split, and without it the split sits on a vertex of (29n)-(29o)
that the next disturbance makes infeasible.

Passive abort (§2: V-bar "returning to its initial position after each hop ... an indefinite hold"):
V-bar adds a drift-free row after every hop-start impulse (``mpc.drift_free_tol_mps`` = 0.05 mm/s
on the J2-aware invariant: chaser-minus-target specific energy over |v_t|, from an onboard target
ephemeris; ``vy + 2 n x`` on CW truth; see :mod:`proxops.control.srf_mpc`) and the same row at a trim
node one MPC node (1/12 orbit) after every hop start (``mpc.drift_trim``: a mm/s trim impulse nulls
the drift that the hop impulse's execution error and its single-sample estimate left; later impulses
of the hop keep it), and :func:`passive_abort` propagates the unforced truth from every hop (after its
trim) over ``safety.abort_orbits`` (default 3) orbits, reporting the return miss after each whole
orbit and the untrimmed drift (an abort before the trim) beside it. Success requires the whole window for V-bar and one orbit for R-bar and
glideslopes (which the paper says lack indefinite safety); all report ``safe_window_orbits``,
the time to the first KOZ entry within the window.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from proxops.constraints.keep_out import KeepOutSphere
from proxops.constraints.passive_safety import free_drift_checks, hermite_min_range
from proxops.control.srf_mpc import EnergyDrift, SrfMpc, SrfMpcConfig, build_schedule
from proxops.core.constants import J2_EARTH, MU_EARTH, R_EARTH
from proxops.core.cw import mean_motion
from proxops.core.memo import memo_get
from proxops.frames.lvlh import hill_vector_to_lvlh
from proxops.guidance.hop_times import plan_hops
from proxops.propagation.truth import CWPlant, RelativeTruth
from proxops.scenarios.registry import register_system
from proxops.sim.engine import Setup, simulate
from proxops.solvers.stats import solve_time_stats
from proxops.systems.base import SystemBase
from proxops.systems.common import navigation_model, translational_plant
from proxops.systems.schema._build_free import actuator_model, target_elements
from proxops.systems.schema.srf import (SrfScenario, _is_vbar, approach_axes_hill, check_mission, engine_dt,
                                        initial_state_hill, keep_out_hill, mpc_steps_per_hop)

# Per-process caches of what every run of a campaign recomputes identically (srf-*-mc disperse only
# the initial state): Algorithm 1's plan (root finding: 50 ms per glideslope/R-bar run) and the
# onboard target ephemeris. Keyed on every input they depend on; a dispersed input only misses.
_PLAN_CACHE: dict = {}
_EPHEMERIS_CACHE: dict = {}


def plan_of(sc: SrfScenario):
    """Algorithm 1 output for the scenario (raises ProxopsInputError in the infeasible band); a copy
    of the plan cached per (approach, orbit) in this process."""
    ap = sc.approach
    args = (math.radians(ap.angle_deg), ap.hops, ap.gamma, ap.start_m, ap.end_m, mean_motion(sc.orbit.sma_m))
    key = (*args, ap.vbar_period_fraction)
    plan = memo_get(_PLAN_CACHE, key, lambda: plan_hops(*args, vbar_period_fraction=ap.vbar_period_fraction))
    return copy.deepcopy(plan)


def onboard_drift_model(sc: SrfScenario, dt: float, span_s: float):
    """The MPC's J2-aware drift invariant: the target's ECI states every engine step over the mission
    (the onboard ephemeris of the known target orbit, same force model as the truth: two-body or J2).
    The ephemeris (read-only) is cached per (orbit, truth model, dt, span) in this process."""
    j2 = sc.truth.model == "j2"
    key = (sc.orbit.model_dump_json(), j2, sc.truth.integrator, float(dt), float(span_s))
    states = memo_get(_EPHEMERIS_CACHE, key, lambda: _target_ephemeris(sc, j2, dt, span_s))
    return EnergyDrift(dt, states, MU_EARTH, J2_EARTH if j2 else 0.0, R_EARTH)


def _target_ephemeris(sc: SrfScenario, j2: bool, dt: float, span_s: float) -> np.ndarray:
    plant = RelativeTruth(target_elements(sc.orbit), np.zeros(6), j2=j2, integrator=sc.truth.integrator)
    n = int(math.ceil(span_s / dt)) + 3
    # n - 1 propagate() calls of dt in one (jitted) coast: the same numbers
    full, _ = plant.coast(np.arange(n - 1) * dt, plant.initial_state(), np.zeros(3), dt)
    states = np.array([plant.target_state(y) for y in full])
    states.flags.writeable = False
    return states


def build_controller(sc: SrfScenario, cbf: bool | None = None):
    """(controller, plan, schedule) of a scenario; ``cbf`` overrides keep_out.cbf."""
    ap, m, ko = sc.approach, sc.mpc, sc.keep_out
    theta = math.radians(ap.angle_deg)
    vbar = _is_vbar(theta)
    plan = plan_of(sc)
    steps = mpc_steps_per_hop(sc)
    dt = engine_dt(sc)
    sched = build_schedule(plan.durations_s, steps, dt)
    mission_s = float(sched.times[-1])
    check_mission(sc, mission_s, dt)  # duration, keep-out geometry, V-bar ladder, planning margin
    a, b = approach_axes_hill(theta)
    koz = keep_out_hill(sc)
    target = ap.end_m * a
    d = np.array([h.start_m for h in plan.hops] + [plan.hops[-1].end_m])
    frac = m.hop_distance_tol_frac if m.hop_distance_tol_frac is not None else (None if vbar else 0.1)
    use_cbf = ko.cbf if cbf is None else cbf
    cfg = SrfMpcConfig(
        q_terminal_per_m2=m.q_terminal_per_m2, r_fuel=m.r_fuel, u_max_mps=m.u_max_mps,
        u_budget_mps=m.u_budget_mps if m.u_budget_mps is not None else math.inf,
        terminal_pos_tol_m=m.terminal_pos_tol_m, terminal_vel_tol_mps=m.terminal_vel_tol_mps,
        r_tol_m=m.r_tol_m, w_tol_mps=m.w_tol_mps, vbar_rows=vbar, h_min_m=m.h_min_m,
        h_max_m=m.h_max_m if m.h_max_m is not None else ap.start_m, epsilon_m=m.epsilon_m,
        hop_distance_tol_m=None if frac is None else list(frac * -np.diff(d)),
        mid_hop_fuel_weight=m.mid_hop_fuel_weight if m.mid_hop_fuel_weight is not None else (1.0 if vbar else 2.0),
        hop_distance_weight_per_m2=(m.hop_distance_weight_per_m2 if m.hop_distance_weight_per_m2 is not None
                                    else (1e-7 if vbar else 0.0)),
        drift_free_tol_mps=m.drift_free_tol_mps if (vbar and m.drift_free) else None,
        drift_outward_mps=m.drift_outward_mps,
        drift_model=onboard_drift_model(sc, dt, mission_s) if (vbar and m.drift_free and sc.truth.model != "cw") else None,
        drift_trim_delay_nodes=m.drift_trim_delay_nodes if (vbar and m.drift_free and m.drift_trim) else None,
        drift_hold_after_trim=m.drift_hold_after_trim, drift_estimator_window_s=m.drift_estimator_window_s,
        min_impulse_mps=float(sc.actuator.min_impulse or 0.0),
        cbf=use_cbf, cbf_alpha_per_s=ko.alpha_per_s, free_drift_s=ko.free_drift_orbits * plan.period_s,
        free_drift_nodes=max(4, int(round(ko.free_drift_nodes_per_orbit * ko.free_drift_orbits))), solver=m.solver)
    planning_koz = KeepOutSphere(koz.radius_m + ko.margin_m, koz.center_m, name="keep_out_planning")
    ctrl = SrfMpc(mean_motion(sc.orbit.sma_m), sched, a, b, target, planning_koz, cfg, hop_distances_m=d)
    return ctrl, plan, sched


def build_setup(sc: SrfScenario, cbf: bool | None = None) -> Setup:
    ctrl, plan, sched = build_controller(sc, cbf)
    plant = translational_plant(sc.orbit, sc.truth, initial_state_hill(sc))
    theta = math.radians(sc.approach.angle_deg)
    meta = {"system": "srf", "approach_deg": sc.approach.angle_deg, "period_s": plan.period_s,
            "hop_plan": plan.as_dict(), "node_times_s": sched.times.tolist(),
            "hop_node_times_s": sched.times[sched.hop_nodes].tolist(), "cbf": bool(ctrl.cfg.cbf),
            "hop_trim_times_s": [float(sched.times[j]) for j in sorted(ctrl.trim_nodes)],
            "vbar": _is_vbar(theta), "mpc_steps_per_hop": int(len(sched.steps) - 1) // sc.approach.hops}
    # The run ends one sample after the braking impulse (its coast simulated), with outcome
    # "handover": duration and stop condition say so, so the engine's step count (progress bar)
    # is the number of steps simulated (it was one too many with a 2-step margin).
    actuator = actuator_model(sc.actuator)
    return Setup(plant=plant, controller=ctrl, duration_s=float(sched.times[-1]) + sched.dt,
                 navigation=navigation_model(sc.navigation, orbit=sc.orbit, control_dt_s=ctrl.dt, system="srf",
                                             actuator=actuator),
                 actuator=actuator, constraints=(keep_out_hill(sc),), stop_condition=_Handover(ctrl),
                 check_substeps=sc.sim.check_substeps, meta=meta)


class _Handover:
    """Stop condition: the MPC has applied its braking impulse (picklable, unlike a closure)."""

    def __init__(self, ctrl):
        self.ctrl = ctrl

    def __call__(self, t: float, x) -> str | None:
        return "handover" if self.ctrl.finished else None


# --------------------------------------------------------------------------- safety
def required_abort_orbits(sc: SrfScenario) -> float:
    """Passive-abort window that counts for success (orbits): the whole ``safety.abort_orbits`` for
    V-bar (the paper's indefinite hold), one orbit for R-bar and glideslopes, which the paper says
    lack indefinite passive safety (§5.2 and conclusion) -- unless ``safety.abort_required_orbits``."""
    s = sc.safety
    if s.abort_required_orbits is not None:
        return min(s.abort_required_orbits, s.abort_orbits)
    return s.abort_orbits if _is_vbar(math.radians(sc.approach.angle_deg)) else min(1.0, s.abort_orbits)


def passive_abort(sc: SrfScenario, result) -> list[dict]:
    """From each hop's last hop-start impulse: propagate the unforced TRUTH for ``safety.abort_orbits`` orbits.

    The hop's drift starts after its trim impulse when the MPC trims (``mpc.drift_trim``, V-bar: the
    trim nulls the drift the hop impulse left), else after the hop impulse. Returns per hop ``{t_s,
    dv_mps, min_range_m, min_koz_distance_m, safe, safe_window_orbits, safe_required}``: ``safe`` over
    the whole window, ``safe_window_orbits`` the time to the first KOZ entry (the window if none),
    ``safe_required`` over :func:`required_abort_orbits`, and ``return_miss_m`` (distance to the
    drift's start after 1, 2, ... whole orbits of the window) and ``return_miss_per_orbit_m`` (the last
    of those divided by its number of orbits); ``hop_t_s``; with a trim also ``trim_dv_mps`` and the
    drift from the hop impulse alone (an abort between hop impulse and trim): ``untrimmed_safe_window_orbits``,
    ``untrimmed_min_koz_distance_m``, ``untrimmed_return_miss_per_orbit_m``."""
    period = float(result.meta.get("period_s") or 2 * math.pi / mean_motion(sc.orbit.sma_m))
    hop_starts = [0.0] + list(result.meta.get("hop_node_times_s", []))[:-1]
    trims = list(result.meta.get("hop_trim_times_s", []))
    koz = keep_out_hill(sc)
    plant = translational_plant(sc.orbit, sc.truth, initial_state_hill(sc))
    state = {"full": plant.initial_state(), "t": 0.0}
    window = sc.safety.abort_orbits
    required = required_abort_orbits(sc)
    times = np.linspace(0.0, window * period, int(round(window * sc.safety.abort_samples_per_orbit)) + 1)
    zero = np.zeros(3)

    def sample(t_at: float) -> int | None:
        k = int(np.argmin(np.abs(result.t - t_at)))
        return k if abs(result.t[k] - t_at) <= 1e-6 * max(1.0, t_at) + 1e-9 else None

    def drift_from(k: int) -> dict:
        if not isinstance(plant, CWPlant):  # move the target (and reference state) to t_k
            state["full"] = plant.propagate(state["t"], state["full"], zero, result.t[k] - state["t"])
            state["t"] = result.t[k]
        x_post = result.x_true[k].copy()
        x_post[3:6] += result.u_applied[k]
        if isinstance(plant, RelativeTruth):
            drift = plant.free_drift(plant.with_relative_state(state["full"], x_post), times)
        else:
            drift = plant.free_drift(x_post, times)
        cert, checks = free_drift_checks(times, drift, koz, period, window)  # one pass: entry, minima, orbit samples
        entry = checks["first_entry_s"]
        misses = [float(np.linalg.norm(drift[k, :3] - x_post[:3])) for k in checks["orbit_index"][1:]]
        cert.update(truth=type(plant).__name__, samples_per_orbit=int(sc.safety.abort_samples_per_orbit))
        return {**checks["safety"], "safe_window_orbits": float(min(entry / period, window)),
                "safe_required": bool(entry > required * period * (1 - 1e-9)), "return_miss_m": misses,
                "return_miss_per_orbit_m": misses[-1] / len(misses) if misses else math.nan,
                "passive_safety": cert}

    out = []
    for m, t_hop in enumerate(hop_starts):
        k_hop = sample(t_hop)
        if k_hop is None:
            continue  # run ended before this hop
        k_trim = sample(trims[m]) if m < len(trims) else None
        hop = drift_from(k_hop)
        if k_trim is None:  # no trim (or the run ended before it): the hop impulse's drift
            item = {"t_s": float(result.t[k_hop]), "hop_t_s": float(result.t[k_hop]),
                    "dv_mps": float(np.linalg.norm(result.u_applied[k_hop])), **hop}
        else:
            item = {"t_s": float(result.t[k_trim]), "hop_t_s": float(result.t[k_hop]),
                    "dv_mps": float(np.linalg.norm(result.u_applied[k_hop])),
                    "trim_dv_mps": float(np.linalg.norm(result.u_applied[k_trim])), **drift_from(k_trim),
                    "untrimmed_safe_window_orbits": hop["safe_window_orbits"],
                    "untrimmed_min_koz_distance_m": hop["min_koz_distance_m"],
                    "untrimmed_return_miss_per_orbit_m": hop["return_miss_per_orbit_m"],
                    "untrimmed_passive_safety": hop["passive_safety"]}
        out.append(item)
    return out


def summarize_result(sc: SrfScenario, result) -> dict:
    """Extra JSON keys of an srf run: arrival, hops, dv per LVLH axis, KOZ and passive-abort safety."""
    theta = math.radians(sc.approach.angle_deg)
    a, _ = approach_axes_hill(theta)
    p_ref = sc.approach.end_m * a
    node_times = result.meta.get("node_times_s") or [result.t[-1]]
    t_arrival = float(node_times[-1])
    k_arr = int(np.argmin(np.abs(result.t - t_arrival)))
    reached_time = abs(result.t[k_arr] - t_arrival) < 1e-6 * max(1.0, t_arrival) + 1e-9
    arrival_err = float(np.linalg.norm(result.x_true[k_arr, :3] - p_ref))
    # arrived: the run lasted to the planned arrival AND the chaser is at the reference point
    arrived = bool(reached_time and arrival_err <= sc.safety.reference_tolerance_m)
    koz = keep_out_hill(sc)
    dist = koz.distance_to_surface(result.x_true[:, :3])
    u = result.u_applied
    fired = np.nonzero(np.linalg.norm(u, axis=1) > 0)[0]
    dv_lvlh = np.abs(hill_vector_to_lvlh(u)).sum(axis=0)
    l1 = float(dv_lvlh.sum())
    hop_nodes = result.meta.get("hop_node_times_s", [])
    hop_start_times = [0.0] + list(hop_nodes)[:-1]
    abort = passive_abort(sc, result)
    min_range_fine = hermite_min_range(result.t, result.x_true, np.zeros(3))
    koz_fine = (min_range_fine if not np.any(koz.center_m)
                else hermite_min_range(result.t, result.x_true, koz.center_m)) - koz.radius_m
    period = float(result.meta.get("period_s", 1.0))
    out = {
        "approach_deg": sc.approach.angle_deg,
        "hops": sc.approach.hops,
        "period_s": period,
        "arrived": arrived,
        "arrival_time_s": t_arrival,
        "arrival_time_orbits": t_arrival / period,
        "arrival_error_m": arrival_err,
        "reached_reference": arrived,
        "reference_tolerance_m": sc.safety.reference_tolerance_m,
        "min_range_fine_m": min_range_fine,
        "koz_violation_samples": int(np.sum(dist < 0.0)),
        "koz_min_distance_m": koz_fine,
        "koz_violated": bool(koz_fine < 0.0),
        "impulses": int(fired.size),
        "impulse_times_s": [float(result.t[k]) for k in fired],
        "impulse_dv_mps": [float(np.linalg.norm(u[k])) for k in fired],  # |dv| of each fired impulse (m/s)
        "hop_start_times_s": [float(t) for t in hop_start_times],
        "hop_intervals_s": [float(x) for x in np.diff([0.0] + list(hop_nodes))],
        "dv_l1_mps": l1,
        "dv_lvlh_abs_mps": {"x_vbar": float(dv_lvlh[0]), "y": float(dv_lvlh[1]), "z_rbar": float(dv_lvlh[2])},
        "dv_share_along_track": float(dv_lvlh[0] / l1) if l1 > 0 else 0.0,
        "abort": abort,
        "abort_safe_all": bool(all(item["safe"] for item in abort)) if abort else False,
        "abort_min_range_m": float(min(item["min_range_m"] for item in abort)) if abort else math.nan,
        "solves": int(np.nansum(result.info.get("solved", np.zeros(1)))),
    }
    if not arrived:  # the engine's stop reason (e.g. handover) says nothing of where the chaser is
        out["status"] = (f"failed: ended {arrival_err:.1f} m from the reference point (tolerance "
                         f"{sc.safety.reference_tolerance_m:g} m)" if reached_time else
                         f"failed: the run ended at {result.t[-1]:.1f} s, before the planned arrival at {t_arrival:.1f} s")
    if abort:
        out["abort_window_orbits"] = sc.safety.abort_orbits
        out["abort_required_orbits"] = required_abort_orbits(sc)
        out["abort_safe_window_orbits"] = float(min(item["safe_window_orbits"] for item in abort))
        out["abort_safe_required"] = bool(all(item["safe_required"] for item in abort))
    if abort:  # the certificate block (one name for every system): the hop drift nearest the KOZ, and the drift signs
        worst = min(abort, key=lambda item: item["passive_safety"]["min_koz_distance_m"])
        out["passive_safety"] = {**worst["passive_safety"], "hop_t_s": worst["hop_t_s"],
                                 "drift_median_m_per_orbit_by_hop": [i["passive_safety"]["drift_median_m_per_orbit"]
                                                                     for i in abort],
                                 "verdict_by_hop": [i["passive_safety"]["verdict"] for i in abort]}
        untrimmed = [i["untrimmed_passive_safety"] for i in abort if "untrimmed_passive_safety" in i]
        if untrimmed:
            out["untrimmed_first_koz_entry_orbits"] = [u["first_koz_entry_orbits"] for u in untrimmed]
            out["untrimmed_verdict_by_hop"] = [u["verdict"] for u in untrimmed]
    if abort and "return_miss_per_orbit_m" in abort[0]:
        out["abort_return_miss_per_orbit_max_m"] = float(max(item["return_miss_per_orbit_m"] for item in abort))
    mask = result.info.get("solved")
    if mask is not None:
        sel = np.nan_to_num(mask) > 0
        st = result.solve_time_s[sel]
        if st.size:
            out["mpc_solve_ms"] = solve_time_stats(st)
    return out


@register_system("srf")
class SrfSystem(SystemBase):
    Scenario = SrfScenario

    def build(self, sc: SrfScenario) -> Setup:
        return build_setup(sc)

    def summarize(self, sc: SrfScenario, result) -> dict:
        return summarize_result(sc, result)

    def run(self, sc: SrfScenario, seed: int = 0, progress: bool = False):
        """One run, or two (with / without the CBF) when keep_out.compare_without_cbf (§5.4)."""
        if not sc.keep_out.compare_without_cbf:
            result = simulate(build_setup(sc), seed=seed, progress=progress)
            return summarize_result(sc, result), {"run": result}
        with_cbf = simulate(build_setup(sc, cbf=True), seed=seed, progress=progress)
        without = simulate(build_setup(sc, cbf=False), seed=seed, progress=progress)
        s_with, s_without = summarize_result(sc, with_cbf), summarize_result(sc, without)
        extra = dict(s_with)
        extra["without_cbf"] = {k: s_without[k] for k in ("koz_min_distance_m", "koz_violated", "abort_safe_all",
                                                         "abort_min_range_m", "dv_l1_mps", "arrival_error_m")}
        extra["without_cbf"]["abort_koz_distance_m"] = [i["min_koz_distance_m"] for i in s_without["abort"]]
        extra["with_cbf_abort_koz_distance_m"] = [i["min_koz_distance_m"] for i in s_with["abort"]]
        return extra, {"cbf": with_cbf, "no_cbf": without}

    def success(self, sc: SrfScenario, summary: dict) -> bool:
        return bool(summary.get("reached_reference") and not summary.get("koz_violated")
                    and summary.get("abort_safe_required", summary.get("abort_safe_all")))

