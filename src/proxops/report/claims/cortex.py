"""cortex-convex-guidance.md §5: references (§5.1.1-5.1.2), closed loop and Table 4."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from proxops.report.claims.common import (CALIBRATED, EXPLAINED, INCONSISTENT, NOT_ATTEMPTED, REPRODUCED, UNEXPLAINED,
                                          Claim, Context, Goal, abort_items, campaign, f, run, sig_round)

def _table4_row(t, col: str, scale: float = 1.0) -> dict:
    v = t[col].astype(float).to_numpy() * scale if col in t else np.zeros(0)
    v = v[np.isfinite(v)]
    if not v.size:
        return {"n": 0}
    q1, q2, q3, p99 = np.percentile(v, [25, 50, 75, 99])
    return {"n": int(v.size), "mean": float(v.mean()), "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
            "q1": float(q1), "q2": float(q2), "q3": float(q3), "p99": float(p99)}


def _ms(d: dict, digits: int = 2) -> str:
    return "-" if not d.get("n") else f"{d['mean']:.{digits}f} ± {d['std']:.{digits}f}"


def cortex_claims(ctx: Context) -> list[Claim]:
    """CORTEX closed loop (cortex-convex-guidance.md §5.1.2, Table 4): nominal run, the low- and high-error
    Monte Carlo campaigns of Table 3, passive safety after aborts, CP_g solve time."""
    from proxops.systems.cortex_loop import PAPER_CPG_SOLVE_MS, PAPER_TABLE4

    rows = []
    fig = ctx.sub("cortex")
    nom = run("cortex-nominal", out=fig / "nominal" if fig else None)
    rows.append(Claim(
        "cortex", "Nominal closed loop docks (no errors, full truth)", "docks (§5.1.2; terminal errors mm level)",
        f"{nom['status']}, Δr(t_f) {nom['terminal_position_error_m'] * 1e3:.2f} mm, Δv_rel(t_f) "
        f"{nom['terminal_velocity_error_mps'] * 1e3:.2f} mm/s, TOF {nom['tof_s']:.0f} s, Δv {nom['total_dv_mps']:.3f} m/s",
        REPRODUCED if nom["status"] == "docked" and nom["terminal_position_error_m"] < 0.01 else UNEXPLAINED,
        "cortex-nominal: fixed axis of §5.1.2, CP_g every 30 s with 2 s impulses, full truth (EGM96 20x20, drag, Sun, "
        "Moon); the terminal velocity error is the residual after the plume-constrained final impulses",
        data={k: nom[k] for k in ("tof_s", "total_dv_mps", "terminal_position_error_m", "terminal_velocity_error_mps")}))
    n_mc = 10 if ctx.quick else 100
    red = f"{n_mc} runs instead of 100" if ctx.quick else ""
    for level, name in (("low", "cortex-low-mc"), ("high", "cortex-high-mc")):
        res = campaign(name, ctx, n_mc)
        t = res.table
        t = t[t["outcome"] != "error"] if "outcome" in t else t
        docked = t[t["status"] == "docked"]
        rec = int((t["metric.recomputes"].astype(float) > 0).sum())
        ab = int((t["metric.aborts"].astype(float) > 0).sum())
        paper = PAPER_TABLE4[level]
        tof, dv = _table4_row(t, "metric.tof_s"), _table4_row(t, "metric.total_dv_mps")
        dr = _table4_row(docked, "metric.terminal_position_error_m", 1e3)
        dvr = _table4_row(docked, "metric.terminal_velocity_error_mps", 1e3)
        rows.append(Claim(
            "cortex", f"{level} error level: runs that recompute / abort",
            f"{paper['recomputes']} / {paper['aborts']} of 100 (§5.1.2, §6)",
            f"{rec} / {ab} of {len(t)}; {len(docked)} docked (reference duration calibrated to the paper's TOF)",
            REPRODUCED if (rec, ab) == (paper["recomputes"], paper["aborts"]) else EXPLAINED,
            "Choices the paper leaves open are set and measured (100 runs each, docked / runs with a recompute / "
            "aborted): (1) CP_g carries soft plume rows (not in §3.2.1) linearised about a plume-free CP_g solve (one "
            "step of eq. 22): rows about the reference were dv . r <= 0 wherever the reference coasts and forbade every "
            "braking correction (low 95/11/5 -> 100/4/0, high 39/61/61 -> 95/17/5); (2) those rows keep alpha_p_bar + 2 "
            "deg and (27g) is imposed at alpha_c - 4 deg first: a convex optimum sits on its constraint, and an impulse "
            "or interval end on a Table 1 threshold is carried across it by execution errors (every C_plume_bar "
            "recompute had fired at 23.7-24.0 deg: low -> 100/0/0, high -> 97/8/3; other campaign seeds 7 / 8: low "
            "100/0/0, high 98/7/2); (3) the reference duration is CALIBRATED to the paper's Table 4 TOF (tau_lb = 600 s per "
            "phase, 1200 s). The §5.1.2 split (fly-around 870 s, approach 300 s: planner.tau1_s / tau2_s) was measured "
            "and not kept: low 99/5/1, high 89/12/11 with the settings above (the faster approach brakes harder at the end: true C_plume aborts). "
            "(4) a final-approach regeneration from outside alpha_c_bar plans in a cone widened to pass the start that "
            "closes back onto alpha_c_bar within 60 s (without it the regenerated reference rode the widened edge past "
            "the C_cone_bar threshold; high seed 2: 97/8/3 -> 99/7/1, seed 8: 98/7/2 -> 99/7/1). Fewer recomputes and "
            "aborts than the paper's 12 / 8: the paper does not say how its CP_g handles the plume or its triggers' "
            "margins, and these choices were made on the failure mechanisms, not on the counts.",
            red, data={"recomputes": rec, "aborts": ab, "docked": len(docked), "runs": len(t)}))
        pt = paper["tof_s"], paper["total_dv_mps"], paper["terminal_position_error_mm"]
        rows.append(Claim(
            "cortex", f"Table 4 {level}: TOF (all runs)", f"TOF {pt[0][0]} ± {pt[0][1]} s (Table 4)",
            f"TOF {_ms(tof, 0)} s", CALIBRATED,
            "CALIBRATED: the reference duration (tau_1 = tau_2 = 600 s, no holds: 1200 s) was chosen on the paper's "
            "1179.82 s; Table 2's tau_lb = 300 s gives a 600 s reference (cortex-nominal). The spread is recomputes "
            "and aborts.", red, data={"tof_s": tof}))
        rows.append(Claim(
            "cortex", f"Table 4 {level}: Δv (all runs), Δr(t_f), Δv_rel(t_f) (docked runs)",
            f"Δv {pt[1][0]} ± {pt[1][1]} m/s, Δr {pt[2][0]} ± {pt[2][1]} mm, Δv_rel "
            f"{paper['terminal_velocity_error_mmps'][0]} ± {paper['terminal_velocity_error_mmps'][1]} mm/s (Table 4)",
            f"Δv {_ms(dv, 3)} m/s, Δr {_ms(dr)} mm, Δv_rel {_ms(dvr, 3)} mm/s "
            "(with the reference duration calibrated to the paper's TOF)",
            EXPLAINED,
            "Δv: the paper's low-level 0.11 m/s is below its own nominal reference cost (1.174 m/s, §5.1.2), ours "
            "includes the reference (0.17 m/s at 1200 s) and every correction; Δr / Δv_rel: docked runs only, measured at the "
            "end of the final approach on the full truth.", red,
            data={"tof_s": tof, "total_dv_mps": dv, "terminal_position_error_mm": dr, "terminal_velocity_error_mmps": dvr}))
        if ab:
            ps = t["metric.passive_safe"].dropna().astype(bool) if "metric.passive_safe" in t else []
            rmin = float(t["metric.passive_min_range_m"].astype(float).min()) if "metric.passive_min_range_m" in t else math.nan
            rows.append(Claim(
                "cortex", f"{level} error level: every aborted run ends on a passively safe orbit",
                "retreat to the safe circumnavigation orbit (§3.4)",
                f"{int(sum(ps))} of {len(ps)} aborted runs stay outside r_KOS = 15 m for 1 orbit of thrust-free full "
                f"truth; smallest range {rmin:.2f} m",
                REPRODUCED if len(ps) and all(ps) else EXPLAINED,
                "insertion verified on board: a 30 s coast, the CW prediction from the mean estimate must clear r_KOS "
                "+ 2 m for 1 orbit, else a CP_g trim interval (at most 20)", red,
                data={"safe": int(sum(ps)), "aborted": len(ps), "min_range_m": rmin}))
        if level == "high" and "metric.solve_time_ms.median" in t:
            med = float(t["metric.solve_time_ms.median"].astype(float).median())
            p95 = float(t["metric.solve_time_ms.p95"].astype(float).median())
            mx = float(t["metric.solve_time_ms.max"].astype(float).max())
            rows.append(Claim(
                "cortex", "One CP_g solve is fast enough for real time",
                f"{PAPER_CPG_SOLVE_MS[0]} ± {PAPER_CPG_SOLVE_MS[1]} ms (§5.1.2, MacBook Air M2)",
                f"median {med:.2f} ms, p95 {p95:.2f} ms, max {mx:.1f} ms (median over runs of the per-run figures)",
                REPRODUCED if med < PAPER_CPG_SOLVE_MS[0] else EXPLAINED,
                "Clarabel, problem built once per (N_sub, cone, plume) and updated in place; the machine is shared "
                "(timings under load)", red, data={"median_ms": med, "p95_ms": p95, "max_ms": mx}))
    return rows

