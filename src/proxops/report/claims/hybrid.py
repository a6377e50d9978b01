"""hybrid-mpc-capture.md §VII: capture, docking, latch snap, re-dock, model check."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from proxops.report.claims.common import (CALIBRATED, EXPLAINED, INCONSISTENT, NOT_ATTEMPTED, REPRODUCED, UNEXPLAINED,
                                          Claim, Context, Goal, abort_items, campaign, f, run, sig_round)

def hybrid_claims(ctx: Context) -> list[Claim]:
    """hybrid-mpc-capture.md §VII: the capture / post-capture sequence of hybrid-capture and the
    50-run Monte Carlo (ours: the paper runs one case)."""
    out = ctx.sub("hybrid")
    s = run("hybrid-capture", out=out / "hybrid-capture" if out is not None else None)
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
        REPRODUCED if fc is not None and abs(fc - 11.0) <= 0.5 else EXPLAINED if fc is not None else UNEXPLAINED,
        "with eq. 78 as printed (p puts the chief's +y docking face towards -x_T, the deputy starts at +2 m x_T "
        "behind it) the approach speed of eq. 78 (-0.081 m/s) carries the deputy into the chief's back face "
        "before the +-1 N capture thrust can stop it: 10.84 s with no control (DOP853 + exact cuboid guard), "
        f"{fc if fc is not None else float('nan'):.2f} s under the capture MPC; e = 0.5 is our choice (the paper "
        "gives none) and cannot change the first impact time. Tolerance 0.5 s",
        data={"first_contact_s": fc, "contacts": s.get("contacts")}))
    rows.append(Claim(
        "hybrid", "Docking after the contacts (capture -> post-capture)", "docked (§VII, Figs. 6-7)",
        f"docked={s['docked']} at {s['dock_time_s']} s, {s['contacts_before_dock']} contacts before",
        REPRODUCED if s["docked"] else UNEXPLAINED, note_run))
    damped = s["chief_rate_final_deg_s"] < 0.1 * s["chief_rate_initial_deg_s"]
    rows.append(Claim(
        "hybrid", "Chief tumble damped after capture", "omega_c -> 0 (§VII, Fig. 7b)",
        f"|omega_c| {s['chief_rate_initial_deg_s']:.3f} -> {s['chief_rate_final_deg_s']:.3f} deg/s",
        REPRODUCED if damped else UNEXPLAINED, "criterion: final rate below 10 % of the initial"))
    trk = s.get("tracking_error_last_100s_max_m")
    rows.append(Claim(
        "hybrid", "Composite CoM orbit tracking", "millimetre-level error (§VII, Fig. 8)",
        f"max |rho_n - r_des| over the last 100 s: {trk:.2e} m; final {s['final_tracking_error_m']:.2e} m",
        REPRODUCED if s["docked"] and trk <= 5e-3 else UNEXPLAINED,
        "criterion: <= 5 mm over the last 100 s of the run (after the re-dock); ours is far below a millimetre "
        "because the truth has no noise and the pair's CoM obeys the same linear CW model as the MPC. The "
        "desired orbit is the chief's initial circular orbit (x_ref = 0, our choice: the paper gives no x_ref). "
        + note_run))
    rows.append(Claim(
        "hybrid", "Latch snap decouples the pair, then re-docking and tracking resume",
        "0.05 N s snap at ~593 s, capture MPC, re-dock (§VII, Fig. 9)",
        f"decoupled={s['decoupled']} at {s['decouple_time_s']} s, redocked={s['redocked']} at {s['redock_time_s']} s",
        REPRODUCED if s["decoupled"] and s["redocked"] else UNEXPLAINED,
        "snap at 593 s (scripted); the supervisor sees the open latch at the next expiry of its dwell timer tau "
        "(T_1 = 10 s) and the latch re-arms 10 s after the snap (our choices). " + note_run))
    rows.append(Claim(
        "hybrid", "Whole §VII run wall time", "goal < 20 s (issue 16; the paper gives none)",
        f"{s['wall_time_s']:.1f} s for {s['sim_time_s']:.0f} s simulated; MPC step median "
        f"{s['solve_time_ms']['median']:.2f} ms, p95 {s['solve_time_ms']['p95']:.2f} ms",
        REPRODUCED if s["wall_time_s"] < 20.0 else EXPLAINED,
        "wall time on the shared 2-core machine (load varies); the paper reports only that the MPC time grows "
        "linearly with the horizon (YALMIP + SDPT3)"))
    from proxops.analysis.hybrid_model_check import AGREEMENT_BLOCKS, block_maxima, relative_model_agreement

    ts, _, errors = relative_model_agreement()
    fixed, printed = block_maxima(errors[True]), block_maxima(errors[False])
    if out is not None:
        from proxops.plotting.hybrid import plot_model_agreement

        plot_model_agreement(ts, errors, AGREEMENT_BLOCKS, out / "relative_model_agreement.png")
    rows.append(Claim(
        "hybrid", "The relative model f_0 (eqs. 18-32) predicts the two-body motion",
        "f_0 as printed (§IV, eqs. 21-32)",
        f"100 s tumbling arc, max |error| corrected: rho {fixed['rho [m]']:.1e} m, rho_dot "
        f"{fixed['rho_dot [m/s]']:.1e} m/s, omega_c {fixed['omega_c [rad/s]']:.1e} rad/s; with eq. 21's printed G2: "
        f"rho {printed['rho [m]']:.2f} m, rho_dot {printed['rho_dot [m/s]']:.3f} m/s",
        EXPLAINED,
        "the printed G2 = (0, 0, 2 n0)^x has the wrong Coriolis sign (standard CW: x'' = 3n^2 x + 2n y'); with it "
        "corrected f_0 matches the direct truth to integration tolerance (DOP853 rtol 1e-11). Other corrections "
        "(eqs. 33, 38, 48, 49/51, 56-57, 78) are listed in dynamics/hybrid_relative.py",
        data={"corrected": fixed, "printed": printed}))
    runs = 4 if ctx.quick else 50
    res = campaign("hybrid-capture-mc", ctx, runs)
    t = res.table
    from proxops.systems.hybrid import is_true_column, outcome_table

    docked = int(is_true_column(t["metric.docked"]).sum()) if "metric.docked" in t else 0
    redocked = int(is_true_column(t["metric.redocked"]).sum()) if "metric.redocked" in t else 0
    rows.append(Claim(
        "hybrid", "Monte Carlo over the initial relative state and the chief's tumble",
        "none (the paper runs one case)",
        f"{len(t)} runs: docked {docked}, re-docked {redocked}, failed {int((~t['success'].astype(bool)).sum())}",
        EXPLAINED, "hybrid-capture-mc dispersions (ours): rho_0 +-0.1/0.2/0.2 m, rho_0_dot +-0.02/0.01/0.01 m/s, "
        "omega +-0.02 rad/s, omega_c +-0.0012 rad/s per axis, uniform",
        f"{runs} runs instead of 50" if ctx.quick else "", data={"table": outcome_table(t)}))
    return rows

