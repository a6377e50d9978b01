"""Iskender 2026 §8-11: certified safe-start sets, hierarchy, §9 Monte Carlo."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from proxops.report.claims.common import (CALIBRATED, EXPLAINED, NOT_ATTEMPTED, REPRODUCED, UNEXPLAINED, Claim,
                                          Context, sig_round)
from proxops.analysis import reach as R, feasibility_maps as F
from proxops.systems.los import run_case
from proxops import __version__
from proxops.analysis.campaign import MANIFEST


def analytic_rows() -> tuple[list[Claim], dict, object, float]:
    """Table 2, the robust set and the hierarchy (the analytical sets of the 20 combinations): rows,
    the results by (omega, a_max), the grid and the wall time (s)."""

    rows: list[Claim] = []
    t0 = time.perf_counter()
    res, timings, grid = R.reach_table(n_points=300)
    wall = time.perf_counter() - t0
    nominal = np.array([r.pct["nominal"] for r in res]).reshape(5, 4)
    diff = float(np.max(np.abs(nominal - R.PAPER_TABLE2_PCT)))
    rows.append(Claim(
        "reach", "Table 2: forward-certified safe-start fractions (20 combinations)", "Table 2 (§10.1)",
        f"max |ours - paper| = {diff:.2f} pp over the 20 cells",
        CALIBRATED,
        f"FITTED: the grid's y extent ({R.DEFAULT_GRID_Y_MAX_M:g} m) is not stated in the paper; it was chosen because "
        "it reproduces Table 2 (the percentages are fractions of that grid)", data={"max_abs_diff_pp": diff}))
    by = {(r.omega_deg_s, r.a_max_mps2): r for r in res}
    rob = by[(1.0, 0.2)].pct["robust"]
    rows.append(Claim(
        "reach", "Robust safe-start region at (1 deg/s, 0.2 m/s^2)", f"{R.PAPER_ROBUST_PCT[(1.0, 0.2)]} % (§11.1)",
        f"{rob:.1f} %", CALIBRATED,
        "CALIBRATED: the paper gives no disturbance model; the disturbance sigma (Disturbance()) was sized on this "
        "75.2 %, so the match is by construction", data={"robust_pct": rob}))
    viol = sum(r.hierarchy_violations for r in res)
    corr = R.LosCorridor()
    dominates = all(bool(np.all(R.robust_tightening(corr, np.radians(w)) >= R.stochastic_tightening(corr, np.radians(w))))
                    for w in R.PAPER_OMEGAS_DEG_S)
    rows.append(Claim(
        "reach", "Certification hierarchy: robust within stochastic within nominal", "nested sets, by construction (§8.3, §10.3)",
        f"{viol} grid points out of order over the 20 combinations; robust tightening >= stochastic at every row for "
        f"every rate: {dominates}", REPRODUCED if viol == 0 and dominates else UNEXPLAINED,
        "300 x 300 grid. The paper states the nesting holds by construction; its precondition (the robust tightening "
        "at least the stochastic one on every row, both >= 0) is measured here, so the row checks that our "
        "implementation keeps the construction (the §8.4 row shows the nesting fails when the precondition does not hold)",
        data={"violations": int(viol), "robust_dominates_stochastic": dominates},
        tolerance="zero grid points out of order (the paper's 'zero point-wise violations', §10.3)"))
    return rows, by, grid, wall


def reach_claims(ctx: Context) -> list[Claim]:
    rows, by, grid, wall = analytic_rows()
    rows.append(double_integrator_row(51 if ctx.quick else 101))
    rows += backward_rows(grid, by)
    # §9 Monte Carlo: all 20 combinations (3 900 runs), one in --quick

    out = ctx.sub(f"cache/reach-mc-{'1of20' if ctx.quick else '20'}-combinations-v{__version__}")
    omegas, amaxs = ((2.0,), (0.10,)) if ctx.quick else (R.PAPER_OMEGAS_DEG_S, R.PAPER_A_MAX_MPS2)
    outcomes, mc_wall, new_runs = F.run_mc(out, omegas, amaxs, workers=ctx.workers, progress=ctx.progress,
                                           resume=out is not None and (out / MANIFEST).exists())
    how = f"{mc_wall:.0f} s" if new_runs else f"reused from {out}"
    bad = tot = not_viable = recovered = 0
    for w in omegas:
        for a in amaxs:
            cr = by[(w, a)]
            fmap = F.feasibility_map(outcomes, grid, w, a)
            sites = np.column_stack([fmap.sites, np.zeros(len(fmap.sites))])
            sites_nom = R.certified_mask(R.LosCorridor(), sites, np.radians(w), a)
            chk = F.certification_check(fmap, grid, cr.nominal, sites_nom)
            bad += chk["nominal_ics_mc_infeasible"]
            tot += chk["nominal_ics"]
            failed = sites_nom & ~fmap.feasible
            if failed.any():  # could ANY controller have kept them in the corridor for the 400 s?
                viable = R.viable_points(sites[failed], np.radians(w), a, n_back=400)
                not_viable += int(np.count_nonzero(~viable))
                for p in sites[failed][viable]:  # does the single-run MPC (N_p = 40 instead of 20) hold them?
                    recovered += bool(run_case(w, a, list(p), mpc_config="single", duration_s=400.0)["feasible"])
    rows.append(Claim(
        "reach", "§9 Monte Carlo: no certified start fails in closed loop",
        "certified sets inside the MC-feasible region (§9-10, Figs. 2-3)",
        f"{bad} of {tot} certified initial conditions infeasible in closed loop ({len(outcomes)} runs, {how}); "
        f"{not_viable} of those cannot be kept in the corridor by any input (400-step LP), {recovered} are held by "
        f"the single-run MPC (N_p = 40), {bad - not_viable - recovered} remain",
        REPRODUCED if bad == 0 else (EXPLAINED if not_viable + recovered == bad else UNEXPLAINED),
        "J2 truth, the paper's MC MPC configuration (N_p = 20), 400 s; certified = nominal forward certificate at the "
        "IC. A failed certified IC that no input sequence can keep inside (exact LP over 400 steps, box on the body "
        "axes) is a limit of the certificate (a necessary-condition test), not of the MPC; one that the N_p = 40 "
        "MPC holds is the short MC horizon's; the rest fail with both horizons although an input exists: not explained",
        "1 of 20 combinations (2 deg/s, 0.10 m/s^2: 195 runs)" if ctx.quick else "",
        data={"certified_ics": tot, "certified_ics_infeasible": bad, "not_viable": not_viable,
              "recovered_np40": recovered, "runs": int(len(outcomes))}))
    mc_runs_full = 20 * 195
    mc_s = _mc_wall(out, mc_wall, new_runs, len(outcomes))
    if mc_s is not None:
        est = mc_s * mc_runs_full / len(outcomes)
        ratio = est / wall
        per_run = est / mc_runs_full
        rows.append(Claim(
            "reach", "Analytical certification vs Monte Carlo: ~200x faster",
            "53 s vs 2-4 h for 20 x 195 runs on 8 cores, ~200x (Table 4, §10.7, conclusion 3)",
            f"analytical {wall:.1f} s, Monte Carlo {est:.0f} s for {mc_runs_full} runs on {ctx.workers} workers"
            + ("" if len(outcomes) == mc_runs_full else f" (extrapolated from {len(outcomes)} runs)")
            + f": {ratio:.1f}x",
            EXPLAINED if sig_round(ratio) != 200.0 else REPRODUCED,
            f"the gap is on the Monte Carlo side, measured: our closed-loop run costs {per_run:.3f} s of wall time on "
            f"{ctx.workers} workers ({per_run * ctx.workers:.2f} worker-s), the paper's 2-4 h on 8 cores is "
            f"{2 * 3600 * 8 / mc_runs_full:.1f}-{4 * 3600 * 8 / mc_runs_full:.1f} core-s per run (QP MPC on compiled kernels "
            f"vs its unstated implementation); our analytical sets take {wall:.1f} s vs its 53 s. Wall times on the shared "
            "machine (load under the table)",
            "" if len(outcomes) == mc_runs_full else f"Monte Carlo wall extrapolated from {len(outcomes)} runs",
            data={"analytical_s": wall, "mc_s": est, "ratio": ratio, "mc_runs_measured": int(len(outcomes))},
            tolerance="the paper's one significant figure (~200x: 150-250x)"))
    rows.append(Claim(
        "reach", "Double-integrator truth shows up to 80 % phantom Δv", "up to 80 % (§11.3, conclusion 4)", "-",
        NOT_ATTEMPTED, "the paper does not describe the double-integrator implementation it criticises ('reference "
        "blending', 'state teleportation'): there is nothing to rebuild. Our truth is two-body + J2 throughout"))
    return rows


def _mc_wall(out, wall: float, new_runs: int, n: int) -> float | None:
    """Monte Carlo wall time of the whole folder: this call's when it ran every run, else the one a
    complete earlier call recorded in ``out/wall_time.json`` (None: not known)."""
    import json

    rec = Path(out) / "wall_time.json" if out is not None else None
    if new_runs == n and n:
        if rec is not None:
            rec.write_text(json.dumps({"wall_s": wall, "runs": n}))
        return wall
    if rec is not None and rec.exists():
        d = json.loads(rec.read_text())
        return float(d["wall_s"]) if d.get("runs") == n else None
    return None


def backward_rows(grid, by) -> list[Claim]:
    """§10.2 backward (LP) safe sets: ours with thrust (inertially at rest / co-rotating start) and the
    thrust-free co-rotating reading (a_max -> 0), which lands on the paper's numbers."""

    rows = []
    for key, pb in R.PAPER_BACKWARD_PCT.items():
        ours = by[key].pct["backward"] if by is not None else grid.percent(
            R.backward_kernel(R.LosCorridor(), grid, np.radians(key[0]), key[1])[0])
        ours_body = grid.percent(R.backward_kernel(R.LosCorridor(), grid, np.radians(key[0]), key[1],
                                                   initial_velocity="body")[0])
        free = grid.percent(R.backward_kernel(R.LosCorridor(), grid, np.radians(key[0]), THRUST_FREE_MPS2,
                                              initial_velocity="body")[0])
        d_free, d_thrust = abs(free - pb), min(abs(ours - pb), abs(ours_body - pb))
        if d_thrust <= 1.0:
            verdict = REPRODUCED
        elif d_free <= 2.0 and d_free * 5 <= d_thrust:
            verdict = EXPLAINED
        else:
            verdict = UNEXPLAINED
        rows.append(Claim(
            "reach", f"Backward (LP) safe set at {key[0]:g} deg/s, {key[1]:g} m/s^2", f"{pb} % (§10.2)",
            f"with thrust: {ours:.1f} % (inertially at rest) / {ours_body:.1f} % (co-rotating start); thrust-free, "
            f"co-rotating start: {free:.1f} %",
            verdict,
            f"measured: the set of co-rotating starts that stay in the corridor for N_back = 20 s with NO thrust "
            f"(a_max = {THRUST_FREE_MPS2:g} m/s^2) is {free:.1f} %, {d_free:.1f} pp from the paper's {pb} %, while both "
            f"readings with its a_max = {key[1]:g} m/s^2 are at least {d_thrust:.1f} pp away: the paper's backward "
            "numbers behave as thrust-free drift of co-rotating starts (its N_back and initial velocity are unstated; "
            "20 steps of 1 s here)",
            data={"backward_pct": ours, "backward_body_pct": ours_body, "thrust_free_body_pct": free},
            tolerance="reproduced: within 1 pp of a with-thrust reading (the paper's 0.1 % print, plus the grid's "
            "boundary cells); explained: the thrust-free reading within 2 pp and 5x closer than either with-thrust one",
            labels=[FITTED_GRID]))
    return rows


FITTED_GRID = ("FITTED: the percentages are fractions of the body-frame grid whose y extent (320 m) was chosen to "
               "reproduce Table 2")
THRUST_FREE_MPS2 = 1e-9  # "no thrust" for the backward LP (a_max must be > 0)


def _di_safe_set(tight: np.ndarray, xs: np.ndarray, vs: np.ndarray, target: float) -> np.ndarray:
    """Safe starts (bool (len(xs), len(vs))) of eq. 17 over N = len(tight) - 1 steps with the state rows
    [x1, x2, -x1, -x2] <= [5, 3, 5, 3] - tight[k] and x_N in the box |x| <= target - tight[N]."""
    from scipy.optimize import linprog

    N = len(tight) - 1
    A = np.array([[1.0, 1.0], [0.0, 1.0]])
    B = np.array([0.5, 1.0])
    H = np.vstack([np.eye(2), -np.eye(2)])
    h = np.array([5.0, 3.0, 5.0, 3.0])
    Ak = [np.linalg.matrix_power(A, k) for k in range(N + 1)]
    G = np.zeros((N + 1, 2, N))  # x_k = A^k x0 + sum_j A^(k-1-j) B u_j
    for k in range(1, N + 1):
        for j in range(k):
            G[k, :, j] = Ak[k - 1 - j] @ B
    mask = np.zeros((len(xs), len(vs)), bool)
    for b, x2 in enumerate(vs):
        # the safe x1 at this x2 is an interval (a projection of a polytope): two LPs in (x1, u_0..u_N-1)
        A_ub = np.vstack([np.column_stack([H @ Ak[k][:, 0], H @ G[k]]) for k in range(1, N + 1)])
        b_ub = np.concatenate([(h if k < N else np.full(4, target)) - tight[k] - H @ Ak[k][:, 1] * x2
                               for k in range(1, N + 1)])
        ends = []
        for sign in (1.0, -1.0):
            r = linprog(np.r_[sign, np.zeros(N)], A_ub=A_ub, b_ub=b_ub, bounds=[(-5.0, 5.0)] + [(-1.0, 1.0)] * N,
                        method="highs")
            ends.append(r.x[0] if r.status == 0 else None)
        if ends[0] is not None:
            mask[:, b] = (xs >= ends[0] - 1e-9) & (xs <= ends[1] + 1e-9)
    return mask


def di_tightenings(N: int = 5, sigma: float = 0.01, alpha: float = 0.05, w_max=(0.02, 0.03)) -> dict:
    """Row tightenings (N + 1, 4) of eq. 17: stochastic = Bonferroni Gaussian quantile (alpha over the
    4N + 4 rows) of the accumulated covariance sigma^2 sum A^j A^jT; robust = worst case of
    |w|_inf <= w_max, w_max sum_j |row A^j| 1."""
    from scipy.stats import norm

    A = np.array([[1.0, 1.0], [0.0, 1.0]])
    H = np.vstack([np.eye(2), -np.eye(2)])
    z = norm.ppf(1 - alpha / (4 * N + 4))
    Ak = [np.linalg.matrix_power(A, k) for k in range(N + 1)]
    out = {"nominal": np.zeros((N + 1, 4)), "stochastic": np.zeros((N + 1, 4))}
    out.update({f"robust {w:g}": np.zeros((N + 1, 4)) for w in w_max})
    for k in range(1, N + 1):
        cov = sum(Ak[j] @ Ak[j].T for j in range(k)) * sigma**2
        l1 = sum(np.abs(Ak[j]) for j in range(k))
        for i, row in enumerate(H):
            out["stochastic"][k, i] = z * math.sqrt(row @ cov @ row)
            for w in w_max:
                out[f"robust {w:g}"][k, i] = w * float(np.abs(row) @ l1 @ np.ones(2))
    return out


def double_integrator_row(n_grid: int = 101, sigma: float = 0.01, w_max=(0.02, 0.03), target: float = 0.5) -> Claim:
    """§8.4, eq. 17: 2-D double integrator, |x1| <= 5, |x2| <= 3, |u| <= 1, N = 5 steps to a target box.
    The paper gives no W, w_max or target: sigma, two w_max and target |x| <= 0.5 are ours; the row
    shows for which disturbance bound the nesting holds."""
    tight = di_tightenings(sigma=sigma, w_max=w_max)
    xs, vs = np.linspace(-5.0, 5.0, n_grid), np.linspace(-3.0, 3.0, n_grid)
    sets = {k: _di_safe_set(t, xs, vs, target) for k, t in tight.items()}
    frac = {k: float(v.mean() * 100) for k, v in sets.items()}
    res = {}
    for w in w_max:
        rob = sets[f"robust {w:g}"]
        res[w] = {"dominates": bool(np.all(tight[f"robust {w:g}"] >= tight["stochastic"])),
                  "out_of_order": int(np.sum(rob & ~sets["stochastic"]) + np.sum(sets["stochastic"] & ~sets["nominal"])),
                  "robust_pct": frac[f"robust {w:g}"]}
    ok = all((r["out_of_order"] == 0) == r["dominates"] for r in res.values()) and any(
        r["out_of_order"] == 0 and r["robust_pct"] > 0 for r in res.values())
    all_nested = all(r["out_of_order"] == 0 for r in res.values())
    return Claim(
        "reach", "§8.4 double-integrator example: robust within stochastic within nominal",
        "nesting verified numerically (§8.4, eq. 17)",
        f"{n_grid} x {n_grid} grid of the state box: nominal {frac['nominal']:.1f} %, stochastic {frac['stochastic']:.1f} %; "
        + "; ".join(f"w_max = {w:g}: robust {r['robust_pct']:.1f} %, {r['out_of_order']} points out of order "
                    f"(robust tightening >= stochastic at every row: {r['dominates']})" for w, r in res.items()),
        REPRODUCED if all_nested else (EXPLAINED if ok else UNEXPLAINED),
        f"exact sets: at each grid velocity the safe positions are an interval whose ends are two LPs in (x1, u) "
        f"(HiGHS). Ours: sigma = {sigma} per axis, alpha = 0.05 Bonferroni over the 4N + 4 rows, target |x_i| <= {target}, "
        "two robust bounds. Measured: the nesting holds exactly when the robust tightening is at least the stochastic "
        "one at every row; with the smaller w_max it is not (first rows: one step of noise, where the Gaussian quantile "
        "exceeds w_max) and points fall out of order. The paper's 'by construction' needs that condition, which its "
        "unstated W and w_max may or may not meet",
        data={"pct": frac, "by_w_max": {str(w): r for w, r in res.items()}},
        tolerance="set inclusion at every grid point")
