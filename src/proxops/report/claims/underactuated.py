"""Aborizk et al.: averaged vs general NMPC, Case 1 and Case 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxops.report.claims.common import INCONSISTENT, NOT_ATTEMPTED, REPRODUCED, UNEXPLAINED, Claim, Context
from proxops.runner import execute, save_run
from proxops.scenarios.loader import load_scenario


def _sign_changes(x: np.ndarray, dead: float) -> int:
    """Sign changes of ``x`` ignoring |x| <= dead (a reversal counts once the value leaves the dead band)."""
    sgn = np.sign(x[np.abs(x) > dead])
    return int(np.count_nonzero(sgn[1:] != sgn[:-1]))


def case1_row(out: Path | None = None) -> Claim:
    """Case 1 (Figs. 2-3): underactuated-case1, Table 2 limits, s0 of §5."""

    loaded = load_scenario("underactuated-case1")
    summary, results = execute(loaded)
    if out is not None:
        save_run(loaded, summary, results, out, figures=True)
    label = next(iter(results))
    res = results[label]
    s = summary if "docked" in summary else summary["runs"][label]
    rng = np.hypot(res.x_true[:, 0], res.x_true[:, 1])
    k_max = int(np.argmax(rng))
    away = bool(rng[k_max] > rng[0])
    value = np.asarray(res.info["value_function"][:-1], float)
    value = value[np.isfinite(value)]
    ups = int(np.sum(np.diff(value) > 0))
    ok = bool(s["docked"]) and away and ups > 0
    return Claim(
        "underactuated", "Case 1: docks, drifting away first; the value function is not monotone",
        "docks; 'the deputy moves away from the chief at the start'; 'monotonicity was not achieved' (§5, Figs. 2-3; "
        "§4 replaces the monotone decrease by the averaged bound, eq. 14)",
        f"docked={s['docked']} after {s['steps']} steps; range {rng[0]:.1f} m -> {rng[k_max]:.1f} m at "
        f"{res.t[k_max]:.0f} s before closing; value function rises at {ups} of {len(value) - 1} steps; "
        f"{s['value_bound_violations']} relaxations of the eq. 14 bound",
        REPRODUCED if ok else UNEXPLAINED,
        "underactuated-case1 (averaged variant, horizon 30, our Q/R: the paper gives none). The eq. 14 bound is a "
        "constraint of our NLP, so it holds by construction except where relaxed (counted); it is reported, not judged",
        data={"docked": s["docked"], "steps": s["steps"], "range_start_m": float(rng[0]), "range_max_m": float(rng[k_max]),
              "t_range_max_s": float(res.t[k_max]), "value_increases": ups},
        tolerance="qualitative: docked, max range > initial range, at least one rise of the value function")


def case2_row(out: Path | None = None) -> Claim:
    """Case 2 (Figs. 6-9): Table 3 limits, undamped (eq. 4) and damped c = 1e-3 (eq. 5)."""

    loaded = load_scenario("underactuated-case2")
    summary, results = execute(loaded)
    if out is not None:
        save_run(loaded, summary, results, out, figures=True)
    dead = 0.05  # deg/s: a rate reversal smaller than this is not an oscillation (Table 1 docking rate: 1 deg/s)
    m = {}
    for lab, res in results.items():
        w = np.degrees(res.x_true[:, 5])
        th = np.degrees(np.unwrap(res.x_true[:, 2]))
        half = len(w) // 2
        m[lab] = {"docked": bool(summary["runs"][lab]["docked"]), "steps": int(summary["runs"][lab]["steps"]),
                  "rate_reversals": _sign_changes(w, dead),
                  "theta_amp_first_half_deg": float(np.ptp(th[:half])) if half else 0.0,
                  "theta_amp_second_half_deg": float(np.ptp(th[half:])) if half else 0.0}
    u, d = m["undamped"], m["damped"]
    osc = u["docked"] and u["rate_reversals"] >= 3 and u["theta_amp_second_half_deg"] < u["theta_amp_first_half_deg"]
    smooth = d["docked"] and d["rate_reversals"] <= 1
    return Claim(
        "underactuated", "Case 2 (Table 3 limits): oscillatory but converging; damping c = 1e-3 removes the oscillations",
        "converges with decaying angular oscillations (Figs. 6-7); with c = 1e-3 'complete elimination of the angular "
        "oscillations' (Figs. 8-9)",
        f"undamped: docked={u['docked']} in {u['steps']} steps, {u['rate_reversals']} reversals of the rotation rate, "
        f"theta range {u['theta_amp_first_half_deg']:.1f} deg (first half) -> {u['theta_amp_second_half_deg']:.1f} deg "
        f"(second half); damped: docked={d['docked']} in {d['steps']} steps, {d['rate_reversals']} reversals",
        REPRODUCED if osc and smooth else UNEXPLAINED,
        "underactuated-case2: the paper gives no s0 for Case 2 (we use Figs. 4-5's, inside Table 3), no horizon or "
        "weights (ours: horizon 60). Reversals of the body rate omega are counted outside a 0.05 deg/s dead band",
        data=m,
        tolerance="oscillatory = at least 3 rate reversals with a smaller theta range in the second half of the run; "
        "eliminated = at most 1 reversal (one reorientation and its stop)")


def underactuated_claims(ctx: Context) -> list[Claim]:
    rows: list[Claim] = []
    repeats = 2 if ctx.quick else 5
    ratios, med = [], {"general": [], "averaged": []}
    summary = None
    for k in range(repeats):
        loaded = load_scenario("underactuated-compare")
        summary, results = execute(loaded)
        if k == 0:
            res_cmp = results
        ratios.append(summary["step_time_ratio"]["general"])
        for lab in med:
            med[lab].append(summary["runs"][lab]["solve_time_ms"]["median"])
        if k == 0 and ctx.out is not None:
            save_run(loaded, summary, results, ctx.sub("underactuated") / "compare", figures=True)
    runs = summary["runs"]
    red = f"{repeats} repeats instead of 5" if ctx.quick else ""
    rows.append(Claim(
        "underactuated", "Both MPC variants dock from the Figs. 4-5 start", "docked (Figs. 4-5)",
        f"general docked={runs['general']['docked']}, averaged docked={runs['averaged']['docked']}",
        REPRODUCED if runs["general"]["docked"] and runs["averaged"]["docked"] else UNEXPLAINED,
        "underactuated-compare; docked = the Table 1 admissible set entered", tolerance="both enter the Table 1 set"))
    g, a = runs["general"]["steps"], runs["averaged"]["steps"]
    rows.append(Claim(
        "underactuated", "Steps to dock", "general 275, averaged 1676 (§5, 2-s steps): 6.1x longer averaged run",
        f"general {g}, averaged {a} ({a / g:.2f}x)", UNEXPLAINED,
        "the paper gives no horizon, weights or averaging window; ours are documented choices (H = 100 / 30, Q, R in "
        "underactuated-compare.toml). Its averaged run is 6.1x longer than its general one, ours "
        f"{a / g:.2f}x: no measurement here shows why", data={"general": g, "averaged": a}))
    rows.append(Claim(
        "underactuated", "Per-step computation, general vs averaged", "9.34 s vs 0.58 s = 16x (§5, text of Figs. 4-5)",
        f"ratio {np.median(ratios):.2f}x (min {np.min(ratios):.2f}, max {np.max(ratios):.2f} over {repeats} repeats); "
        f"medians general {np.median(med['general']):.1f} ms, averaged {np.median(med['averaged']):.1f} ms",
        INCONSISTENT,
        "the paper's own numbers disagree in the same paragraph (§5, after Fig. 3): 'the general MPC required 17,569 "
        "seconds to generate a 275-timestep trajectory, averaging 9.34 seconds' -- 17 569 / 275 = 63.9 s per step "
        "(9.34 x 275 = 2 569 s); the averaged 971 s / 1 676 = 0.58 s is consistent. The 16x is 9.34 / 0.58; with "
        "63.9 s it would be 110x. Ours: both variants on fatrop (warm-started), horizons 100 vs 30; timings under the "
        "machine's load (printed under the table)", red,
        data={"ratios": ratios, "median_ms": med}))
    vg = np.asarray(res_cmp["general"].info["value_function"][:-1], float)
    va = np.asarray(res_cmp["averaged"].info["value_function"][:-1], float)
    n = min(len(vg), len(va))
    both = np.isfinite(vg[:n]) & np.isfinite(va[:n])
    below = int(np.sum(vg[:n][both] < va[:n][both]))
    rows.append(Claim(
        "underactuated", "The general MPC's value function stays below the averaged one",
        "'consistently lower value function values' (§5, Fig. 5)",
        f"general below averaged at {below} of {int(both.sum())} common steps",
        REPRODUCED if below == int(both.sum()) and below > 0 else UNEXPLAINED,
        "underactuated-compare, same start (Figs. 4-5); each value function is its own NLP's optimal cost (general: "
        "horizon 100 with the paper's terminal ingredients, averaged: horizon 30 with the eq. 14 bound), compared step "
        "by step while both run", data={"below": below, "common_steps": int(both.sum())},
        tolerance="every common step (the paper's 'consistently')"))
    rows.append(case1_row(ctx.sub("underactuated") / "case1" if ctx.out is not None else None))
    if ctx.quick:
        rows.append(Claim(
            "underactuated", "Case 2 (Table 3 limits): oscillatory but converging; damping c = 1e-3 removes the "
            "oscillations", "Figs. 6-9", "-", NOT_ATTEMPTED, "runs in the full reproduction only (two 4000 s closed loops, "
            "about 70 s)", "not run in --quick"))
    else:
        rows.append(case2_row(ctx.sub("underactuated") / "case2"))
    return rows
