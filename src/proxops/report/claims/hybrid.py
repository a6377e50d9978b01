"""Basu et al. §VII: capture, docking, latch snap, re-dock, model check."""

from __future__ import annotations

import math

import numpy as np

from proxops.report.claims.common import (EXPLAINED, NOT_ATTEMPTED, REPRODUCED, UNEXPLAINED, Claim, Context, Goal,
                                          campaign, run)
from proxops.runner import execute, save_run
from proxops.scenarios.loader import load_scenario
from proxops.analysis.hybrid_model_check import AGREEMENT_BLOCKS, block_maxima, relative_model_agreement
from proxops.systems.hybrid import is_true_column, outcome_table
from proxops.plotting.hybrid import plot_model_agreement
from proxops.propagation.hybrid_plant import HYBRID_LAYOUT


def hybrid_claims(ctx: Context) -> list[Claim]:
    """Basu et al. §VII: the capture / post-capture sequence of hybrid-capture and the
    50-run Monte Carlo (ours: the paper runs one case)."""

    out = ctx.sub("hybrid")
    loaded = load_scenario("hybrid-capture")
    s, results = execute(loaded)
    if out is not None:
        save_run(loaded, s, results, out / "hybrid-capture", figures=True)
    res = next(iter(results.values()))
    rows: list[Claim] = []
    note_run = (f"hybrid-capture: status {s['status']}, {s['solver_failures']} flagged controller steps of "
                f"{s['steps']}; sequence: {s['sequence']}. The latch is not eq. 81's (K_T = K_R = 5, D = 2 cannot "
                "hold the pair in the two-body truth under the +-5 N / +-5 N m post-capture bounds: 0.75 m and "
                "0.9 rad static deflection; the paper's f_1 takes the control out of the relative dynamics); ours: "
                "K_T = 750 N/m, D_T = 520 N s/m, K_R = 550 N m/rad, D_R = 150 N m s/rad (hybrid-capture.toml)")
    fc = s.get("first_contact_s")
    rows.append(Claim(
        "hybrid", "First non-resting impact during capture", "t = 11 s (§VII, Fig. 5)",
        f"t = {fc:.2f} s" if fc is not None else "no contact",
        REPRODUCED if fc is not None and abs(fc - 11.0) <= 0.5 else UNEXPLAINED,
        "with eq. 78 as printed (p puts the chief's +y docking face towards -x_T, the deputy starts at +2 m x_T "
        "behind it) the approach speed of eq. 78 (-0.081 m/s) carries the deputy into the chief's back face "
        "before the +-1 N capture thrust can stop it: 10.84 s with no control (DOP853 + exact cuboid guard), "
        f"{fc if fc is not None else float('nan'):.2f} s under the capture MPC; e = 0.5 is our choice (the paper "
        "gives none) and cannot change the first impact time. Judged on the controlled run (hybrid-capture), not "
        "on the free flight",
        data={"first_contact_s": fc, "contacts": s.get("contacts")},
        tolerance="0.5 s: the paper prints the time as a whole second (t = 11 s)"))
    rows.append(Claim(
        "hybrid", "Docking after the contacts (capture -> post-capture)", "docked (§VII, Figs. 6-7)",
        f"docked={s['docked']} at {s['dock_time_s']} s, {s['contacts_before_dock']} contacts before",
        REPRODUCED if s["docked"] else UNEXPLAINED, note_run, tolerance="docked (qualitative)"))
    damped = s["chief_rate_final_deg_s"] < 0.1 * s["chief_rate_initial_deg_s"]
    rows.append(Claim(
        "hybrid", "Chief tumble damped after capture", "omega_c -> 0 (§VII, Fig. 7b)",
        f"|omega_c| {s['chief_rate_initial_deg_s']:.3f} -> {s['chief_rate_final_deg_s']:.3f} deg/s at the end; "
        f"peak {s['chief_rate_peak_deg_s']:.2f} deg/s at {s['chief_rate_peak_time_s']:.0f} s (the contacts spin it up)",
        REPRODUCED if damped else UNEXPLAINED, "hybrid-capture, end of the run",
        tolerance="final rate below 10 % of the initial (Fig. 7b decays to zero; 10 % is our reading of 'damped')"))
    rows.append(tracking_row(s))
    exact, _ = execute(load_scenario("hybrid-capture-exact"))
    rows.append(Claim(
        "hybrid", "Composite CoM orbit tracking, exact states (labelled variant)",
        "millimetre-level error (§VII, Fig. 8)",
        f"max over the last 100 s {exact['tracking_error_last_100s_max_m']:.2e} m; status {exact['status']}",
        NOT_ATTEMPTED, "hybrid-capture-exact: the MPCs see the true state (no navigation noise) on the two-body + J2 "
        "truth; shown beside the estimator run above to separate model mismatch from estimation error, not as a "
        "reproduction", data={"tracking_error_last_100s_max_m": exact["tracking_error_last_100s_max_m"]}))
    rows.append(Claim(
        "hybrid", "Latch snap decouples the pair, then re-docking and tracking resume",
        "0.05 N s snap at ~593 s, capture MPC, re-dock (§VII, Fig. 9)",
        f"decoupled={s['decoupled']} at {s['decouple_time_s']} s (snap at {s['snap_time_s']} s), "
        f"redocked={s['redocked']} at {s['redock_time_s']} s; separation reached "
        f"{1e3 * s['max_separation_after_snap_m']:.1f} mm, inside the 2 cm capture envelope: a re-grab, not a "
        "re-capture (hybrid-redock drives the pair beyond the envelope and re-captures)",
        REPRODUCED if s["decoupled"] and s["redocked"] else UNEXPLAINED,
        "snap at 593 s (scripted); the supervisor sees the open latch at the next expiry of its dwell timer tau "
        "(T_1 = 10 s) and the latch re-arms 10 s after the snap (our choices). " + note_run,
        tolerance="both events happen (qualitative)"))
    rows.append(rotation_row(loaded, s, res))
    rows.append(horizon_row(ctx))
    ctx.goals.append(Goal(
        "hybrid", "Whole §VII run (hybrid-capture) wall time", "< 20 s (the paper gives none)",
        f"{s['wall_time_s']:.1f} s for {s['sim_time_s']:.0f} s simulated; MPC step median "
        f"{s['solve_time_ms']['median']:.2f} ms, p95 {s['solve_time_ms']['p95']:.2f} ms", s["wall_time_s"] < 20.0,
        "wall time on the shared 2-core machine (load under the table)", data={"wall_s": s["wall_time_s"]}))

    ts, _, errors = relative_model_agreement()
    fixed, printed = block_maxima(errors[True]), block_maxima(errors[False])
    if out is not None:
        plot_model_agreement(ts, errors, AGREEMENT_BLOCKS, out / "relative_model_agreement.png")
    rows.append(Claim(
        "hybrid", "The relative model f_0 (eqs. 18-32) predicts the two-body motion",
        "f_0 as printed (§IV, eqs. 21-32)",
        f"100 s tumbling arc, max |error| corrected: rho {fixed['rho [m]']:.1e} m, rho_dot "
        f"{fixed['rho_dot [m/s]']:.1e} m/s, omega_c {fixed['omega_c [rad/s]']:.1e} rad/s; with eq. 21's printed G2: "
        f"rho {printed['rho [m]']:.2f} m, rho_dot {printed['rho_dot [m/s]']:.3f} m/s",
        EXPLAINED if fixed["rho [m]"] < 1e-3 <= printed["rho [m]"] else UNEXPLAINED,
        "the printed G2 = (0, 0, 2 n0)^x has the wrong Coriolis sign (standard CW: x'' = 3n^2 x + 2n y'); with it "
        "corrected f_0 matches the direct truth to integration tolerance (DOP853 rtol 1e-11). Other corrections "
        "(eqs. 33, 38, 48, 49/51, 56-57, 78) are listed in dynamics/hybrid_relative.py",
        data={"corrected": fixed, "printed": printed}))
    runs = 4 if ctx.quick else 50
    mc = campaign("hybrid-capture-mc", ctx, runs)
    t = mc.table

    docked = int(is_true_column(t["metric.docked"]).sum()) if "metric.docked" in t else 0
    redocked = int(is_true_column(t["metric.redocked"]).sum()) if "metric.redocked" in t else 0
    failed = int((~t["success"].astype(bool)).sum())
    ctx.goals.append(Goal(
        "hybrid", "Monte Carlo over the initial relative state and the chief's tumble (the paper runs one case)",
        "every run docks and re-docks (ours)", f"{len(t)} runs: docked {docked}, re-docked {redocked}, failed {failed}"
        + (f" ({runs} runs instead of 50)" if ctx.quick else ""), failed == 0,
        "hybrid-capture-mc dispersions (ours): rho_0 +-0.1/0.2/0.2 m, rho_0_dot +-0.02/0.01/0.01 m/s, omega +-0.02 "
        "rad/s, omega_c +-0.0012 rad/s per axis, uniform. Why runs fail is not measured here",
        data={"table": outcome_table(t)}))
    return rows


NAV_KEYS = ("nav_position_error_m", "navigation", "nav_nees_mean")  # a translational filter ran


def tracking_row(s: dict) -> Claim:
    """Fig. 8: composite CoM tracking, read from whatever hybrid-capture reports. With exact states the
    truth's translation is the MPC's own linear model, so the number cannot differ: not a reproduction.
    When the run reports navigation (any of NAV_KEYS), the row is judged on it."""
    trk = s.get("tracking_error_last_100s_max_m")
    noisy = any(k in s for k in NAV_KEYS) or s.get("estimation", "exact") != "exact"
    ours = (f"max |rho_n - r_des| over the last 100 s: {trk:.2e} m; final {s['final_tracking_error_m']:.2e} m"
            if trk is not None else "no tracking error reported")
    if not noisy:
        return Claim(
            "hybrid", "Composite CoM orbit tracking", "millimetre-level error (§VII, Fig. 8)", ours, NOT_ATTEMPTED,
            "exact states: the truth's translation of the latched pair is the MPC's own linear CW model and there is "
            "no navigation noise, so the error cannot differ from zero by more than integration error: not a "
            "reproduction. The row reads hybrid-capture's summary and is judged once the run has navigation",
            data={"tracking_error_last_100s_max_m": trk, "navigation": False})
    ok = s.get("docked") and trk is not None and trk < 1e-2
    return Claim(
        "hybrid", "Composite CoM orbit tracking", "millimetre-level error (§VII, Fig. 8)", ours,
        REPRODUCED if ok else UNEXPLAINED, f"hybrid-capture on estimates (estimation = {s.get('estimation')!r}: "
        "noisy relative pose and composite CoM, MEKF of the chief attitude and rate) on the two-body + J2 truth, "
        "last 100 s of the run (after the re-dock)",
        data={"tracking_error_last_100s_max_m": trk, "navigation": True},
        tolerance="'millimetre-level' read as below 10 mm over the last 100 s")


def rotation_row(loaded, s: dict, res) -> Claim:
    """§VII: 'the optimizer prioritizes correcting the rotational misalignment within approximately one
    horizon length' (T^0 = 10 s): first time the relative attitude error and rate enter the scenario's
    capture envelope (docking.angle_deg, docking.rate_deg_s), from the truth."""

    sc = loaded.scenario
    T = float(sc.control.horizon_capture_s)
    ang_tol, rate_tol = math.radians(sc.docking.angle_deg), math.radians(sc.docking.rate_deg_s)
    blk = {b.name: b for b in HYBRID_LAYOUT.blocks}
    om = res.x_true[:, blk["omega"].start:blk["omega"].stop]
    q = res.x_true[:, blk["q"].start:blk["q"].stop]  # relative attitude, scalar last
    env = np.zeros((len(res.t), 4))
    env[:, 2] = np.linalg.norm(om, axis=1)
    env[:, 3] = 2.0 * np.arctan2(np.linalg.norm(q[:, :3], axis=1), np.abs(q[:, 3]))
    inside = (env[:, 3] <= ang_tol) & (env[:, 2] <= rate_tol)
    k = int(np.argmax(inside)) if inside.any() else None
    t_conv = float(res.t[k]) if k is not None else math.nan
    ratio = t_conv / T
    ok = k is not None and round(ratio) == 1
    return Claim(
        "hybrid", "Rotational states converge within about one horizon (capture phase)",
        "within approximately one horizon length, T^0 = 10 s (§VII, Figs. 5-6)",
        f"relative attitude within {sc.docking.angle_deg:g} deg and rate within {sc.docking.rate_deg_s:g} deg/s from "
        f"t = {t_conv:.1f} s = {ratio:.2f} horizons (initial {math.degrees(env[0, 3]):.1f} deg, "
        f"{math.degrees(env[0, 2]):.2f} deg/s)",
        REPRODUCED if ok else UNEXPLAINED,
        "hybrid-capture truth, relative attitude quaternion q and relative rate omega (the plant's state layout); "
        "the thresholds are the scenario's capture envelope", data={"t_converged_s": t_conv, "horizon_s": T, "ratio": ratio},
        tolerance="the ratio t / T rounds to 1 (0.5-1.5 horizons: 'approximately one')")


def horizon_row(ctx: Context, horizons=(5.0, 10.0, 20.0, 40.0), duration_s: float = 10.0) -> Claim:
    """§VII: 'the observed solution time ... increases approximately linearly with the horizon length'.
    Median capture-MPC step time over the first ``duration_s`` of hybrid-capture per horizon; a
    straight line and a parabola (both with offset) are fitted and compared."""
    med = []
    for h in horizons:
        s = run("hybrid-capture", [f"control.horizon_capture_s={h:g}", f"sim.duration_s={duration_s:g}"], cache=False)
        med.append(float(s["solve_time_ms"]["median"]))
    h, m = np.array(horizons), np.array(med)
    lin = np.polyfit(h, m, 1)
    quad = np.polyfit(h**2, m, 1)
    r_lin = float(np.sqrt(np.mean((np.polyval(lin, h) - m) ** 2)))
    r_quad = float(np.sqrt(np.mean((np.polyval(quad, h**2) - m) ** 2)))
    slope = float(np.polyfit(np.log(h), np.log(m), 1)[0])
    ok = r_lin < r_quad and lin[0] > 0
    return Claim(
        "hybrid", "Capture-MPC solve time grows about linearly with the horizon",
        "approximately linear in the horizon length (§VII; YALMIP + SDPT3, Apple M3)",
        "median step " + ", ".join(f"{x:g} s: {y:.2f} ms" for x, y in zip(horizons, med))
        + f"; rms residual linear {r_lin:.2f} ms vs quadratic {r_quad:.2f} ms; log-log slope {slope:.2f}",
        REPRODUCED if ok else UNEXPLAINED,
        f"hybrid-capture, first {duration_s:g} s (capture phase), control.horizon_capture_s varied; wall times on the "
        "shared machine (load under the table)", "" if not ctx.quick else "",
        data={"horizons_s": list(horizons), "median_ms": med, "rms_linear_ms": r_lin, "rms_quadratic_ms": r_quad,
              "loglog_slope": slope},
        tolerance="a straight line (with offset) fits the medians better than t = a + b T^2")
