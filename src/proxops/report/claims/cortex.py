"""Wijayatunga et al. §5: references (§5.1.1-5.1.2), closed loop and Table 4."""

from __future__ import annotations

import math

import numpy as np

from proxops.report.claims.common import (CALIBRATED, EXPLAINED, INCONSISTENT, NOT_ATTEMPTED, REPRODUCED,
                                          UNEXPLAINED, Claim, Context, campaign, run)
from proxops.scenarios.loader import load_scenario
from proxops.systems.cortex import PAPER_5_1_1, PAPER_5_1_2, campaign_statistics, references_scenario
from proxops.systems.cortex_setup import config_from_scenario, eclipse_profile, plan_scenario
from proxops.systems.cortex_loop import PAPER_CPG_SOLVE_MS, PAPER_TABLE4


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


CALIBRATED_TAU = ("CALIBRATED: reference duration tau_lb = 600 s per phase (1200 s in all) chosen on Table 4's TOF "
                  "1179.82 s; Table 2's tau_lb = 300 s gives a 600 s reference")
TUNED_MARGINS = ("TUNED: guidance margins tracking_plume_margin_deg = 2, tracking_cone_margin_deg = 4, "
                 "regen_cone_return_s = 60 chosen by their effect on the counts of campaign seeds 1 (low) and 2 (high); "
                 "reported here on seeds never used for tuning")
UNTUNED_SEEDS = {"low": 1001, "high": 1002}  # campaign seeds never used to choose a setting
PAPER_ABSTRACT_HIGH = {"terminal_position_error_mm": (36.85, 44.46), "terminal_velocity_error_mmps": (1.25, 2.26)}
PAPER_HARDWARE = {"terminal_position_error_mm": (8.09, 5.29), "terminal_velocity_error_mmps": (2.23, 1.72)}


def _median_tolerance(iqr: float, n: int = 100) -> float:
    """Two standard errors of a sample median from the paper's own IQR: SE = 1.2533 sigma / sqrt(n),
    sigma = IQR / 1.349 (normal), so 2 SE = 1.858 IQR / sqrt(n)."""
    return 2 * 1.2533 * (iqr / 1.349) / math.sqrt(n)


def eclipse_hold_row(holds=()) -> Claim:
    """Contribution 1 (§3.1, Fig. 3): cortex-reference started so late before the first eclipse entry
    that less sunlight remains than the shortest transfer: the planner must hold. ``holds``: the
    Fibonacci plans' total holds (s), reported beside it."""

    sc = load_scenario("cortex-reference").scenario

    tt, eta = eclipse_profile(sc)
    eta = np.asarray(eta).astype(int)
    entry = float(tt[np.nonzero(np.diff(eta) < 0)[0][0] + 1])
    delay = max(0.0, entry - 0.5 * sc.planner.tau_lb_s)  # sunlight left < the shortest transfer: the hold must fire
    late = plan_scenario(load_scenario("cortex-reference", [f"planner.start_delay_s={delay:.1f}"]).scenario).summary()
    fired = (late["hold1_s"] or 0.0) > 0 and late["check_sunlit"] is True
    rows = [Claim(
        "cortex", "Eclipse-aware scheduling: a hold waits for sunlight before a transfer",
        "hold points tau_h1 / tau_h2 keep both transfers in sunlight (contribution 1, §3.1, Fig. 3)",
        f"plan started {delay:.0f} s after t0 ({entry - delay:.0f} s before eclipse entry at {entry:.0f} s): hold "
        f"tau_h1 = {late['hold1_s']:.0f} s, tau_h2 = {late['hold2_s']:.0f} s, transfers sunlit: {late['check_sunlit']}; "
        f"{int(np.sum(np.asarray(holds) > 0))} of {len(holds)} Fibonacci plans from t0 hold",
        REPRODUCED if fired else UNEXPLAINED,
        "cortex-reference with planner.start_delay_s so that less sunlight remains than the shortest transfer; the "
        "eclipse profile (conical umbra + penumbra, 1000 samples per orbit) is independent of the planner; "
        "check_sunlit re-reads it along both planned transfers", data={"delay_s": delay, "entry_s": entry, "plan": late},
        tolerance="qualitative: a hold > 0 and both transfers sunlit on the profile")]
    return rows[0]


def reference_rows(ctx: Context) -> list[Claim]:
    """§5.1.1 (Fibonacci axes, `proxops cortex references` machinery), §5.1.2's fixed-axis reference,
    the eclipse hold, and the terminal impulse the planner adds."""

    rows = []
    n = 10 if ctx.quick else 100
    red = f"{n} axes instead of 100" if ctx.quick else ""
    data = references_scenario("cortex-reference", n)
    res = campaign(f"cortex-reference-fibonacci-{n}", ctx, None, scenario=data)
    st = campaign_statistics(res.table)
    p = PAPER_5_1_1
    tol_dv, tol_tof = _median_tolerance(p["dv_iqr_mps"]), _median_tolerance(p["tof_iqr_min"])
    d_dv = abs(st["dv_mps"]["median"] - p["dv_median_mps"])
    d_tof = abs(st["tof_min"]["median"] - p["tof_median_min"])
    rows.append(Claim(
        "cortex", "§5.1.1 references for 100 Fibonacci docking axes: Δv, TOF, compute time",
        f"median Δv {p['dv_median_mps']} m/s (IQR {p['dv_iqr_mps']}), TOF {p['tof_median_min']} min (IQR "
        f"{p['tof_iqr_min']}), compute {p['compute_median_s']} s (IQR {p['compute_iqr_s']}) (§5.1.1, Fig. 12)",
        f"{st['n_ok']}/{st['n_plans']} plans ok; median Δv {st['dv_mps']['median']:.4f} m/s (IQR {st['dv_mps']['iqr']:.4f}), "
        f"TOF {st['tof_min']['median']:.2f} min (IQR {st['tof_min']['iqr']:.2f}), compute {st['compute_s']['median']:.2f} s "
        f"(IQR {st['compute_s']['iqr']:.2f})",
        REPRODUCED if d_dv <= tol_dv and d_tof <= tol_tof else UNEXPLAINED,
        "`proxops cortex references` (cortex-reference, Table 2 settings, tau_lb = 300 s, eq. 12 search taking the "
        "first converged duration). Compute time is ours on the shared machine (the paper's hardware is not stated "
        "for §5.1.1): shown, not judged. The TOF is set by the search's first feasible duration; the paper's longer "
        "TOF and larger Δv with it are not explained by a measurement here",
        red, data={"ours": st, "paper": p, "tolerance": {"dv_mps": tol_dv, "tof_min": tol_tof}},
        tolerance=f"two standard errors of a 100-sample median from the paper's own IQR (1.858 IQR / 10): Δv "
        f"{tol_dv:.3f} m/s, TOF {tol_tof:.2f} min"))
    sc = load_scenario("cortex-reference").scenario
    plan = plan_scenario(sc).summary()
    sc600 = load_scenario("cortex-reference", ["planner.tau_lb_s=600"]).scenario
    plan600 = plan_scenario(sc600).summary()
    q = PAPER_5_1_2
    rows.append(Claim(
        "cortex", "§5.1.2 fixed-axis reference: TOF and Δv", f"TOF {q['tof_min']} min, Δv {q['dv_mps']} m/s (§5.1.2)",
        f"tau_lb = 300 s (Table 2): TOF {plan['tof_s'] / 60:.2f} min, Δv {plan['dv_total_mps']:.3f} m/s; tau_lb = 600 s "
        f"(the closed loop's calibrated value): TOF {plan600['tof_s'] / 60:.2f} min, Δv {plan600['dv_total_mps']:.3f} m/s",
        UNEXPLAINED,
        "axis [-sin(pi/4), -sin(pi/4), 0], Table 2 settings. Our Δv is 3.4-7x below the paper's at both durations; the "
        "paper's CP1/CP2 cost split and its search's stopping rule are not given, and no measurement here shows why",
        data={"tau_lb_300": plan, "tau_lb_600": plan600, "paper": q}))
    rows.append(Claim(
        "cortex", "§5.1.2 fixed-axis phase durations", "fly-around 14.66 min + final approach 4.5 min = 19.66 min (§5.1.2)",
        f"the sum is {q['tau1_min'] + q['tau2_min']:.2f} min", INCONSISTENT,
        "§5.1.2 gives TOF 19.66 min with fly-around 14.66 min and final approach 4.5 min: 14.66 + 4.5 = 19.16, not "
        "19.66 (Table 4's 1179.82 s = 19.66 min); and 4.5 min is below Table 2's own search range tau in [5, 60] min",
        data={"sum_min": q["tau1_min"] + q["tau2_min"], "table2_tau_lb_min": 5.0}))

    a_bar = config_from_scenario(sc).a_bar
    t = res.table
    term = {k: t[f"metric.{k}"].astype(float).to_numpy() for k in ("dv1_terminal_mps", "dv2_terminal_mps")
            if f"metric.{k}" in t}
    cap1 = a_bar * sc.planner.dt_cp1_s if math.isfinite(a_bar) else math.nan
    if "dv1_terminal_mps" in term:
        v1 = term["dv1_terminal_mps"]
        at_bound = int(np.sum(np.abs(v1 - cap1) <= 1e-6 * cap1))
        ours = (f"fly-around: terminal impulse at its bound a_bar dt = {cap1:.4f} m/s in {at_bound} of {len(v1)} plans "
                f"(median {np.nanmedian(v1):.4f} m/s); final approach: median {np.nanmedian(term['dv2_terminal_mps']):.4f} "
                f"m/s; fixed axis: {plan['dv1_terminal_mps']:.4f} / {plan['dv2_terminal_mps']:.4f} m/s")
    else:
        ours = f"fixed axis: {plan['dv1_terminal_mps']:.4f} / {plan['dv2_terminal_mps']:.4f} m/s"
    rows.append(Claim(
        "cortex", "Impulses of CP1 / CP2: one per interval (eqs. 17, 20)", "N impulses at nodes 0..N-1 (eqs. 17, 20)",
        ours, EXPLAINED,
        "ours adds a terminal burn at each phase's last node (impulses at nodes 0..N: the arrival velocity x_f is met "
        "by it), measured above from the plans' own impulses; the fly-around's sits at the impulse bound in the plans "
        "listed. It lowers the reference Δv against eqs. 17 / 20 as printed (measured a median 0.020 m/s, up "
        "to 0.19 m/s per axis on 101 plans; not re-measured here: there is no option without it)", red,
        data={"fixed_axis": {"dv1_terminal_mps": plan["dv1_terminal_mps"], "dv2_terminal_mps": plan["dv2_terminal_mps"]},
              "a_bar_dt_cp1_mps": cap1}))
    holds = (t["metric.hold1_s"].astype(float) + t["metric.hold2_s"].astype(float)).to_numpy() if "metric.hold1_s" in t else []
    rows.append(eclipse_hold_row(holds))
    rows.append(Claim(
        "cortex", "Hardware-in-the-loop: planar air-bearing testbed (Table 5)",
        f"terminal errors {PAPER_HARDWARE['terminal_position_error_mm'][0]} ± "
        f"{PAPER_HARDWARE['terminal_position_error_mm'][1]} mm, {PAPER_HARDWARE['terminal_velocity_error_mmps'][0]} ± "
        f"{PAPER_HARDWARE['terminal_velocity_error_mmps'][1]} mm/s (abstract, §5.2, Table 5)", "-", NOT_ATTEMPTED,
        "needs the air-bearing testbed and its motion capture. Note: §5.2.1 quotes 'a mean value of 3.67 mm and median "
        "below 3 mm' for the hardware, the same numbers as Table 4's low-error software row (3.67, 2.88)"))
    return rows


def cortex_claims(ctx: Context) -> list[Claim]:
    """CORTEX (Wijayatunga et al. §5): references (§5.1.1-5.1.2), nominal closed loop, the low- and
    high-error Monte Carlo campaigns of Table 3 on untuned seeds, passive safety after aborts, CP_g solve time."""

    rows = reference_rows(ctx)
    fig = ctx.sub("cortex")
    nom = run("cortex-nominal", out=fig / "nominal" if fig else None)
    rows.append(Claim(
        "cortex", "Nominal closed loop docks (no errors, full truth)", "docks (§5.1.2; terminal errors mm level)",
        f"{nom['status']}, Δr(t_f) {nom['terminal_position_error_m'] * 1e3:.2f} mm, Δv_rel(t_f) "
        f"{nom['terminal_velocity_error_mps'] * 1e3:.2f} mm/s, TOF {nom['tof_s']:.0f} s, Δv {nom['total_dv_mps']:.3f} m/s",
        REPRODUCED if nom["status"] == "docked" and nom["terminal_position_error_m"] < 0.01 else UNEXPLAINED,
        "cortex-nominal: fixed axis of §5.1.2, CP_g every 30 s with 2 s impulses, full truth (EGM96 20x20, drag, Sun, "
        "Moon); the terminal velocity error is the residual after the plume-constrained final impulses",
        data={k: nom[k] for k in ("tof_s", "total_dv_mps", "terminal_position_error_m", "terminal_velocity_error_mps")},
        tolerance="'mm level' read as below 10 mm (Table 4's low-error P99 is 21 mm)", labels=[TUNED_MARGINS]))
    n_mc = 10 if ctx.quick else 100
    red = f"{n_mc} runs instead of 100" if ctx.quick else ""
    labels = [CALIBRATED_TAU, TUNED_MARGINS]
    for level, name in (("low", "cortex-low-mc"), ("high", "cortex-high-mc")):
        seed = UNTUNED_SEEDS[level]
        res = campaign(name, ctx, n_mc, seed=seed)
        t = res.table
        t = t[t["outcome"] != "error"] if "outcome" in t else t
        docked = t[t["status"] == "docked"]
        rec = int((t["metric.recomputes"].astype(float) > 0).sum())
        ab = int((t["metric.aborts"].astype(float) > 0).sum())
        paper = PAPER_TABLE4[level]
        tof, dv = _table4_row(t, "metric.tof_s"), _table4_row(t, "metric.total_dv_mps")
        dr = _table4_row(docked, "metric.terminal_position_error_m", 1e3)
        dvr = _table4_row(docked, "metric.terminal_velocity_error_mps", 1e3)
        same = (rec, ab) == (paper["recomputes"], paper["aborts"])
        rows.append(Claim(
            "cortex", f"{level} error level: runs that recompute / abort",
            f"{paper['recomputes']} / {paper['aborts']} of 100 (§5.1.2, §6)",
            f"{rec} / {ab} of {len(t)} (campaign seed {seed}); {len(docked)} docked",
            REPRODUCED if same else UNEXPLAINED,
            "computed from the campaign's rows (follows the code). Choices the paper leaves open are set and were "
            "measured on seeds 1 / 2 (see the scenario files): soft plume rows in CP_g linearised about a plume-free "
            "solve, a 2 deg plume and 4 deg cone margin in CP_g, a regenerated final approach that closes back onto "
            "alpha_c_bar within 60 s, and the calibrated reference duration. The paper does not say how its CP_g "
            "handles the plume or its triggers' margins; why its counts differ from ours is not measured",
            red, data={"recomputes": rec, "aborts": ab, "docked": len(docked), "runs": len(t), "seed": seed},
            tolerance="equal counts (the paper's integers)", labels=labels))
        pt = paper["tof_s"], paper["total_dv_mps"], paper["terminal_position_error_mm"]
        pv = paper["terminal_velocity_error_mmps"]
        rows.append(Claim(
            "cortex", f"Table 4 {level}: TOF (all runs)", f"TOF {pt[0][0]} ± {pt[0][1]} s (Table 4)",
            f"TOF {_ms(tof, 0)} s", CALIBRATED,
            "the reference duration was chosen on the paper's 1179.82 s; the spread is recomputes and aborts", red,
            data={"tof_s": tof}, labels=labels))
        if level == "low":
            dv_verdict, dv_note = INCONSISTENT, (
                "Table 4's low-error Δv 0.11 ± 0.01 m/s is below the cost of the reference it tracks, 1.1740 m/s in "
                "§5.1.2 for the same fixed axis (and a tracked run pays at least its reference). Ours includes the "
                "reference and every correction")
        else:
            dv_verdict, dv_note = UNEXPLAINED, "ours includes the reference and every correction; no measurement here "\
                "shows why the paper's high-error Δv is larger"
        rows.append(Claim(
            "cortex", f"Table 4 {level}: Δv (all runs)", f"Δv {pt[1][0]} ± {pt[1][1]} m/s (Table 4)",
            f"Δv {_ms(dv, 3)} m/s", dv_verdict, dv_note, red, data={"total_dv_mps": dv}, labels=labels))
        rows.append(Claim(
            "cortex", f"Table 4 {level}: Δr(t_f), Δv_rel(t_f) (docked runs)",
            f"Δr {pt[2][0]} ± {pt[2][1]} mm, Δv_rel {pv[0]} ± {pv[1]} mm/s (Table 4)",
            f"Δr {_ms(dr)} mm, Δv_rel {_ms(dvr, 3)} mm/s", UNEXPLAINED,
            "docked runs only, measured at the end of the final approach on the full truth. The paper's docking "
            "criterion, its navigation filter and its thruster model are not given; no measurement here shows why the "
            "terminal errors differ", red,
            data={"terminal_position_error_mm": dr, "terminal_velocity_error_mmps": dvr}, labels=labels))
        if level == "high":
            ab_p, ab_v = PAPER_ABSTRACT_HIGH["terminal_position_error_mm"], PAPER_ABSTRACT_HIGH["terminal_velocity_error_mmps"]
            rows.append(Claim(
                "cortex", "High-error terminal errors: abstract vs Table 4",
                f"abstract: {ab_p[0]} ± {ab_p[1]} mm, {ab_v[0]} ± {ab_v[1]} mm/s; Table 4: {pt[2][0]} ± {pt[2][1]} mm, "
                f"{pv[0]} ± {pv[1]} mm/s", f"ours (above): Δr {_ms(dr)} mm, Δv_rel {_ms(dvr, 3)} mm/s", INCONSISTENT,
                "the abstract ('under the strongest error case investigated') and Table 4 (high error) disagree on both "
                "numbers; §5.1.2's text also calls Table 4's means 31.26 mm and 0.5243 mm/s 'the median' (Table 4 "
                "medians: 25.53 mm, 0.2747 mm/s)", data={"abstract": PAPER_ABSTRACT_HIGH}))
        if level == "high" and "metric.solve_time_ms.median" in t:
            med = float(t["metric.solve_time_ms.median"].astype(float).median())
            p95 = float(t["metric.solve_time_ms.p95"].astype(float).median())
            mx = float(t["metric.solve_time_ms.max"].astype(float).max())
            rows.append(Claim(
                "cortex", "One CP_g solve is fast enough for real time",
                f"{PAPER_CPG_SOLVE_MS[0]} ± {PAPER_CPG_SOLVE_MS[1]} ms (§5.1.2, MacBook Air M2)",
                f"median {med:.2f} ms, p95 {p95:.2f} ms, max {mx:.1f} ms (median over runs of the per-run figures)",
                REPRODUCED if mx < 30_000.0 else UNEXPLAINED,
                "Clarabel, problem built once per (N_sub, cone, plume) and updated in place; the machine is shared "
                "(timings under load). The claim is real-time feasibility: every solve well inside the 30 s guidance "
                "step", red, data={"median_ms": med, "p95_ms": p95, "max_ms": mx},
                tolerance="every solve shorter than the guidance interval Δt_g = 30 s (the paper's real-time criterion)"))
    rows.append(abort_safety_row(ctx))
    return rows


def abort_safety_row(ctx: Context) -> Claim:
    """§3.4: every abort ends on a passively safe orbit. Measured on ground aborts at 700 s (mid fly-around)
    of the high error level (Table 3) on the untuned campaign seed: each aborted run's passive-safety
    certificate over 5 orbits of thrust-free full truth (min range, keep-out entries, along-track drift)."""
    runs = 4 if ctx.quick else 10
    seed = UNTUNED_SEEDS["high"]
    res = campaign("cortex-high-mc", ctx, runs, overrides=["guidance.abort_at_s=700"], seed=seed)
    t = res.table
    t = t[t["outcome"] != "error"] if "outcome" in t else t
    col = "metric.passive_safety."
    aborted = t[t["status"] == "aborted"] if "status" in t else t.iloc[0:0]
    n = len(aborted)
    entries = int(aborted[col + "first_koz_entry_s"].notna().sum()) if col + "first_koz_entry_s" in aborted else n
    safe = int(aborted[col + "safe"].astype(bool).sum()) if col + "safe" in aborted else 0
    rmin = float(aborted[col + "min_range_m"].astype(float).min()) if n and col + "min_range_m" in aborted else math.nan
    drift = aborted[col + "drift_median_m_per_orbit"].astype(float).abs() if col + "drift_median_m_per_orbit" in aborted else []
    dmed = float(drift.median()) if len(drift) else math.nan
    dmax = float(drift.max()) if len(drift) else math.nan
    ok = n > 0 and entries == 0 and safe == n
    return Claim(
        "cortex", "Every abort ends on a passively safe orbit (ground aborts at 700 s, high error level)",
        "retreat to the safe circumnavigation orbit (§3.4)",
        f"{n} of {len(t)} runs aborted; {entries} enter r_KOS = 15 m within 5 orbits of thrust-free full truth; "
        f"{safe} certified safe; smallest range {rmin:.2f} m; |drift| median {dmed:.2f} m/orbit (max {dmax:.2f})",
        REPRODUCED if ok else UNEXPLAINED,
        f"`proxops mc cortex-high-mc --runs {runs} --seed {seed} --set guidance.abort_at_s=700`: the retreat nulls the "
        "along-track drift 2x + y_dot/n before the thrusters stop (insertion check: 120 s coast, predicted min range "
        ">= r_KOS + 2 m and drift <= 0.5 m/orbit over 5 orbits, else a trim); the certificate propagates the final "
        "state thrust-free on the full truth" + (f" ({runs} runs instead of 10)" if ctx.quick else ""),
        data={"aborted": n, "entries": entries, "safe": safe, "min_range_m": rmin, "drift_median_m_per_orbit": dmed},
        tolerance="0 keep-out entries in every aborted run over the 5-orbit window (the paper's safe-orbit claim)",
        labels=[CALIBRATED_TAU, TUNED_MARGINS])
