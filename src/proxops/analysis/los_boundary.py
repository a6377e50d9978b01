"""The measured feasibility boundary of the los closed loop (Iskender 2026 §10.6).

The paper states that starts inside r_sync = 2 a_max / w_t^2 (eq. 14) "achieve zero
violations". This module measures, for one (w_t, a_max) combination and one start type, the
largest start range on the docking axis (as a fraction of r_sync) from which the closed loop
(J2 truth, hard corridor constraints) runs to the end with zero corridor violations, by
bisection between a fraction known to hold and one known to fail::

    from proxops.analysis.los_boundary import boundary_fraction
    boundary_fraction(2.0, 0.10, "body")     # co-rotating start (zero body-frame velocity)
    boundary_fraction(2.0, 0.10, "lvlh")     # inertially at rest (zero Hill-frame velocity)

Start types: ``"body"`` = co-rotating with the target (the §9 Monte Carlo and the Table 3 sweep),
``"lvlh"`` = at rest in the Hill frame (the corridor sweeps past the chaser at w_t r).

Physics behind the numbers (used in the reproduction table): to stay at rest on the rotating
axis at range r the chaser needs the centripetal acceleration w_t^2 r along the axis, and the
input box (11e) is on the target body axes, so at most a_max along the axis: a co-rotating hold
is possible only for r <= a_max / w_t^2 = 0.5 r_sync. Starts beyond that survive only by building
a tangential body-frame velocity whose Coriolis term 2 w_t v_t pulls them inward before they leave
the 30 deg corridor; how far beyond 0.5 r_sync that works is what the bisection measures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from proxops.control.los_regimes import sync_range
from proxops.systems.los import build_setup, default_scenario, summarize_result
from proxops.sim.engine import simulate
from proxops.constraints.los_corridor import LosCorridor
from proxops.core.constants import MU_EARTH, R_EARTH
from proxops.core.cw import mean_motion
from proxops.dynamics.tumbling_target import BodyFrameModel, body_from_hill_matrix
from proxops.solvers.highs_lp import HighsLP


@dataclass
class BoundaryResult:
    """Largest zero-violation start fraction of r_sync, bracketed to ``tol``."""

    omega_deg_s: float
    a_max_mps2: float
    start: str  # "body" (co-rotating) or "lvlh" (inertially at rest)
    r_sync_m: float
    fraction: float  # largest fraction found to hold (lower end of the bracket)
    fails_at: float  # smallest fraction found to fail (upper end of the bracket)
    horizon: int | None
    runs: int

    def as_dict(self) -> dict:
        return {"omega_deg_s": self.omega_deg_s, "a_max_mps2": self.a_max_mps2, "start": self.start,
                "r_sync_m": self.r_sync_m, "fraction": self.fraction, "fails_at": self.fails_at,
                "horizon": self.horizon, "runs": self.runs}


def holds(omega_deg_s: float, a_max_mps2: float, fraction: float, start: str = "body", *,
          horizon: int | None = None, duration_s: float = 600.0) -> tuple[bool, dict]:
    """One closed loop from ``fraction * r_sync`` on the docking axis (hard constraints, J2 truth,
    the single-run MPC configuration, ``horizon`` overriding N_p): (zero violations and feasible, summary)."""

    r_sync = sync_range(a_max_mps2, math.radians(omega_deg_s))
    mpc = {"config": "single", "constraint_mode": "hard"}
    if horizon is not None:
        mpc["horizon"] = int(horizon)
    sc = default_scenario(sim={"duration_s": float(duration_s), "dt_s": 1.0, "seed": 0},
                          target={"tumble_rate_deg_s": float(omega_deg_s)},
                          chaser={"a_max_mps2": float(a_max_mps2), "initial_body_position_m": [0.0, fraction * r_sync, 0.0],
                                  "initial_velocity_frame": start},
                          mpc=mpc)
    result = simulate(build_setup(sc), seed=0)
    summary = summarize_result(sc, result)
    ok = bool(summary["los_violations"] == 0 and summary["feasible"])
    return ok, summary


def boundary_fraction(omega_deg_s: float, a_max_mps2: float, start: str = "body", *, horizon: int | None = None,
                      lo: float = 0.3, hi: float = 1.2, tol: float = 0.02, duration_s: float = 600.0) -> BoundaryResult:
    """Bisection for the largest zero-violation start fraction of r_sync in [lo, hi] (to ``tol``).
    Assumes one boundary (holds below, fails above); checks both ends first: ``fraction = 0`` when
    even ``lo`` fails, ``fraction = hi`` when ``hi`` holds."""

    r_sync = sync_range(a_max_mps2, math.radians(omega_deg_s))
    runs = 0
    ok_lo, _ = holds(omega_deg_s, a_max_mps2, lo, start, horizon=horizon, duration_s=duration_s)
    runs += 1
    if not ok_lo:
        return BoundaryResult(omega_deg_s, a_max_mps2, start, r_sync, 0.0, lo, horizon, runs)
    ok_hi, _ = holds(omega_deg_s, a_max_mps2, hi, start, horizon=horizon, duration_s=duration_s)
    runs += 1
    if ok_hi:
        return BoundaryResult(omega_deg_s, a_max_mps2, start, r_sync, hi, math.inf, horizon, runs)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        ok, _ = holds(omega_deg_s, a_max_mps2, mid, start, horizon=horizon, duration_s=duration_s)
        runs += 1
        lo, hi = (mid, hi) if ok else (lo, mid)
    return BoundaryResult(omega_deg_s, a_max_mps2, start, r_sync, lo, hi, horizon, runs)


def boundary_table(combos, starts=("body", "lvlh"), horizons=(None,), tol: float = 0.02) -> list[dict]:
    """``boundary_fraction`` for every combination, start type and horizon; rows as dicts, plus the
    best horizon per (combination, start) under ``best``."""
    rows = []
    for w, a in combos:
        for start in starts:
            results = [boundary_fraction(w, a, start, horizon=h, tol=tol) for h in horizons]
            best = max(results, key=lambda r: r.fraction)
            row = best.as_dict()
            row["by_horizon"] = {str(r.horizon): r.fraction for r in results}
            rows.append(row)
    return rows


def summarize_boundaries(rows: list[dict]) -> dict:
    """Range of the measured fractions per start type."""
    out = {}
    for start in sorted({r["start"] for r in rows}):
        f = np.array([r["fraction"] for r in rows if r["start"] == start])
        out[start] = {"min": float(f.min()), "median": float(np.median(f)), "max": float(f.max()), "n": int(f.size)}
    return out


def open_loop_feasible(omega_deg_s: float, a_max_mps2: float, fraction: float, start: str = "body", *,
                       horizon_s: float = 600.0, dt: float = 2.0, half_angle_deg: float = 30.0,
                       floor_m: float = 1.0, terminal_hold: bool = True, altitude_km: float = 500.0) -> bool:
    """Does ANY input sequence keep the chaser in the corridor for ``horizon_s`` (and, with
    ``terminal_hold``, end at rest in the body frame on a range it can hold, <= a_max / w_t^2)?
    An LP (HiGHS) on the same model as the MPC's prediction: CW in the Hill frame (mean motion of
    the Table 1 orbit), the target body turning at w_t - n relative to it (BodyFrameModel), ZOH inputs
    in a box on the body axes (as (11e)), the corridor rows (eq. 9) on the body-frame position at every
    step, the start converted exactly as the los system does. States and inputs are LP variables with
    the dynamics as equality rows (sparse). It is the controller-independent bound of :func:`holds` up
    to J2 and the step size; ``terminal_hold=False`` only asks to stay inside for ``horizon_s``."""
    import scipy.sparse as sp

    w = math.radians(omega_deg_s)
    r0 = fraction * sync_range(a_max_mps2, w)
    model = BodyFrameModel(mean_motion(R_EARTH + altitude_km * 1e3, MU_EARTH), w, dt)
    x_body = np.array([0.0, r0, 0.0, 0.0, 0.0, 0.0])
    if start == "lvlh":  # at rest in the Hill frame, as LosSystem's initial_velocity_frame = "lvlh"
        x_hill = model.hill_from_body(0.0, x_body)
        x_hill[3:6] = 0.0
        x_body = model.body_from_hill(0.0, x_hill)
    x0 = model.hill_from_body(0.0, x_body)
    K = int(round(horizon_s / dt))
    nx, nu = 6 * (K + 1), 3 * K
    cor = LosCorridor(math.radians(half_angle_deg), floor_m)
    F = cor.G.shape[0]
    eq_r, eq_c, eq_v = [], [], []
    Phi, Bd = model.Phi, model.Bd

    def put(rows, cols, vals, r0_, c0_, block):
        rr, cc = np.nonzero(np.ones_like(block, dtype=bool))
        rows.append(rr + r0_); cols.append(cc + c0_); vals.append(block[rr, cc])

    put(eq_r, eq_c, eq_v, 0, 0, np.eye(6))  # x_0 = x0
    rhs = [x0]
    for k in range(K):
        R_LB = model.rotation_body_from_hill(k * dt).T
        r = 6 * (k + 1)
        put(eq_r, eq_c, eq_v, r, 6 * (k + 1), np.eye(6))
        put(eq_r, eq_c, eq_v, r, 6 * k, -Phi)
        put(eq_r, eq_c, eq_v, r, nx + 3 * k, -Bd @ R_LB)
        rhs.append(np.zeros(6))
    n_eq = 6 * (K + 1)
    in_r, in_c, in_v, lo, hi = [], [], [], [], []
    row = n_eq
    for k in range(1, K + 1):
        block = cor.G @ model.rotation_body_from_hill(k * dt)
        put(in_r, in_c, in_v, row, 6 * k, np.hstack([block, np.zeros((F, 3))]))
        lo.append(np.full(F, -np.inf)); hi.append(cor.h)
        row += F
    if terminal_hold:  # body-frame velocity 0 and body range <= a_max / w^2 at the end

        T = body_from_hill_matrix(float(model.theta(K * dt)), model.w_rel)
        put(in_r, in_c, in_v, row, 6 * K, T[3:6])
        lo.append(np.zeros(3)); hi.append(np.zeros(3))
        put(in_r, in_c, in_v, row + 3, 6 * K, T[1:2])
        lo.append([-np.inf]); hi.append([a_max_mps2 / w**2])
        row += 4
    A = sp.csc_matrix((np.concatenate(eq_v + in_v), (np.concatenate(eq_r + in_r), np.concatenate(eq_c + in_c))),
                      shape=(row, nx + nu))
    b = np.concatenate(rhs)
    rl = np.concatenate([b, np.concatenate([np.asarray(x, float) for x in lo])])
    ru = np.concatenate([b, np.concatenate([np.asarray(x, float) for x in hi])])
    lb = np.concatenate([np.full(nx, -np.inf), np.full(nu, -a_max_mps2)])
    ub = np.concatenate([np.full(nx, np.inf), np.full(nu, a_max_mps2)])
    lp = HighsLP(settings={"solver": "ipm"})  # IPM: infeasible cases in ~1 s (dual simplex: 14-67 s)
    lp.setup_native(np.zeros(nx + nu), A, rl, ru, lb, ub)
    res = lp.solve()
    return bool(res.ok and res.x is not None)


def open_loop_boundary(omega_deg_s: float, a_max_mps2: float, start: str = "body", *, lo: float = 0.3,
                       hi: float = 1.5, tol: float = 0.01, **kw) -> tuple[float, float]:
    """Bisection of :func:`open_loop_feasible`: (largest feasible fraction, smallest infeasible)."""
    if not open_loop_feasible(omega_deg_s, a_max_mps2, lo, start, **kw):
        return 0.0, lo
    if open_loop_feasible(omega_deg_s, a_max_mps2, hi, start, **kw):
        return hi, math.inf
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if open_loop_feasible(omega_deg_s, a_max_mps2, mid, start, **kw) else (lo, mid)
    return lo, hi
