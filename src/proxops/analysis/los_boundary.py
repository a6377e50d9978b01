"""The measured feasibility boundary of the los closed loop (tumbling-target-reachability.md §10.6).

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
    from proxops.guidance.los_regimes import sync_range
    from proxops.systems.los import build_setup, default_scenario, summarize_result
    from proxops.sim.engine import simulate

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
    from proxops.guidance.los_regimes import sync_range

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
                       floor_m: float = 1.0, terminal_hold: bool = True) -> bool:
    """Does ANY input sequence keep the chaser in the corridor for ``horizon_s`` and end at rest in the
    body frame on a range it can hold (<= a_max / w_t^2)? An LP (HiGHS) on the planar body-frame
    dynamics ``p'' = u + w^2 p - 2 w x p'`` (rotation about z at w_t; the orbital rate n is
    neglected, n / w_t = 0.03 at 2 deg/s), ZOH inputs on a box on the body axes (as (11e)), the
    corridor rows at z = 0 at every step; ``terminal_hold=False`` drops the end condition (only stay
    inside for ``horizon_s``, what a closed-loop run of that length is scored on). This is the controller-independent (physical) bound of
    :func:`holds`, up to the neglected orbit terms and the finite horizon."""
    from scipy.linalg import expm

    from proxops.constraints.los_corridor import LosCorridor
    from proxops.guidance.los_regimes import sync_range
    from proxops.solvers.highs_lp import HighsLP

    w = math.radians(omega_deg_s)
    r0 = fraction * sync_range(a_max_mps2, w)
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [w * w, 0, 0, 2 * w], [0, w * w, -2 * w, 0]], dtype=float)
    M = expm(np.block([[A, np.vstack([np.zeros((2, 2)), np.eye(2)])], [np.zeros((2, 6))]]) * dt)
    Ad, Bd = M[:4, :4], M[:4, 4:]
    K = int(round(horizon_s / dt))
    x0 = np.array([0.0, r0, 0.0, 0.0]) if start == "body" else np.array([0.0, r0, w * r0, 0.0])
    # ("lvlh" start at rest inertially: body-frame velocity -w x p = (w y, -w x) for rotation +w about z)
    cor = LosCorridor(math.radians(half_angle_deg), floor_m)
    G2, h = cor.G[:, :2], cor.h
    keep = np.linalg.norm(G2, axis=1) > 1e-12
    G2, h = G2[keep], h[keep]
    # condensed: x_k = Ad^k x0 + sum_{j<k} Ad^(k-1-j) Bd u_j
    pw = [np.eye(4)]
    for _ in range(K):
        pw.append(Ad @ pw[-1])
    rows, lo, hi = [], [], []
    for k in range(1, K + 1):
        Sk = np.zeros((4, 2 * K))
        for j in range(k):
            Sk[:, 2 * j:2 * j + 2] = pw[k - 1 - j] @ Bd
        free = pw[k] @ x0
        rows.append(G2 @ Sk[:2]); lo.append(np.full(len(h), -np.inf)); hi.append(h - G2 @ free[:2])
        if k == K and terminal_hold:  # end at rest, close enough to hold
            rows.append(Sk[2:]); lo.append(-free[2:]); hi.append(-free[2:])
            rows.append(Sk[1:2]); lo.append([-np.inf]); hi.append([a_max_mps2 / w**2 - free[1]])
    lp = HighsLP()
    lp.setup(np.zeros(2 * K), np.vstack(rows), np.concatenate(lo), np.concatenate(hi),
             np.full(2 * K, -a_max_mps2), np.full(2 * K, a_max_mps2))
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
