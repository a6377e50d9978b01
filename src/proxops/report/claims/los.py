"""Iskender 2026 §10.6: closed-loop approach through the rotating LOS corridor."""

from __future__ import annotations

import math

import numpy as np

from proxops.report.claims.common import EXPLAINED, REPRODUCED, UNEXPLAINED, Claim, Context
from proxops.analysis.los_boundary import boundary_fraction, open_loop_boundary
from proxops.control.los_regimes import sync_range
from proxops.systems.los import PAPER_TABLE3, SWEEP_A_MAX_MPS2, SWEEP_RATES_DEG_S, run_case


def los_claims(ctx: Context) -> list[Claim]:
    rows: list[Claim] = []
    combos = [(w, a) for w in SWEEP_RATES_DEG_S for a in SWEEP_A_MAX_MPS2]
    sel = [(2.0, 0.10), (5.0, 0.02), (1.0, 0.05)] if ctx.quick else combos
    red = f"{len(sel)} of 15 combinations" if ctx.quick else ""
    b_body = [boundary_fraction(w, a, "body", horizon=None if w >= 2 else 80) for w, a in sel]
    b_lvlh = [boundary_fraction(w, a, "lvlh", horizon=None if w >= 2 else 80) for w, a in sel]
    lp_body = open_loop_boundary(2.0, 0.10, "body", lo=0.6, hi=1.0, tol=0.02)
    lp_lvlh = open_loop_boundary(2.0, 0.10, "lvlh", lo=0.5, hi=0.9, tol=0.02)
    fb = [b.fraction for b in b_body]
    fl = [b.fraction for b in b_lvlh]
    rows.append(Claim(
        "los", "Starts inside r_sync = 2 a_max / w_t^2 achieve zero violations", "inside r_sync: 0 violations (§10.6, eq. 14)",
        f"zero-violation boundary (hard constraints, 600 s, J2): co-rotating starts up to {min(fb):.2f}-{max(fb):.2f} r_sync, "
        f"inertially-at-rest (Hill) starts up to {min(fl):.2f}-{max(fl):.2f} r_sync; at 2 deg/s, 0.10 m/s^2 no input at "
        f"all keeps a start beyond {lp_body[1]:.2f} (co-rotating) / {lp_lvlh[1]:.2f} (Hill-at-rest) r_sync in the corridor (LP)",
        EXPLAINED,
        "the gap to r_sync is physical, not the controller's. (1) In units of r_sync the body-frame problem has no free "
        "parameter when n << w_t: the same 0.82 for every rate >= 2 deg/s. (2) A longer horizon stops helping: N_p 40 "
        "-> 80 -> 160 keeps 0.82 at 2-5 deg/s (1 deg/s needs N_p = 80). (3) An LP over ALL box-bounded input sequences "
        "on the MPC's own CW body-frame model (HiGHS, 600 s, 2 s ZOH) is infeasible just above the closed loop's "
        "boundary (measured at 1, 2 and 5 deg/s: 0.825-0.834 co-rotating; 0.67-0.75 Hill-at-rest, closed loop within "
        "0.02). Why not r_sync: holding still on the rotating axis needs w_t^2 r <= a_max, i.e. 0.5 r_sync, with the "
        "input box on the body axes; beyond that only Coriolis from a tangential velocity pulls the chaser in before "
        "it leaves the 30 deg corridor. r_sync = 2 a_max / w_t^2 (eq. 14) is not a zero-violation bound",
        red, data={"body": [b.as_dict() for b in b_body], "lvlh": [b.as_dict() for b in b_lvlh],
                   "open_loop_2deg_0.1": {"body": lp_body, "lvlh": lp_lvlh}}))
    spread = max(fb) - min(fb)
    rows.append(Claim(
        "los", "a_max / w_t^2 is the single parameter of feasibility (results collapse on it)",
        "collapse on a_max / w_t^2 (contribution 3, §11.2, conclusion 2; its Table 2 has equal cells at equal ratio: "
        "(1 deg/s, 0.05) = (2 deg/s, 0.20) = 45.0 %, (2, 0.05) = (4, 0.20) = 2.8 %)",
        "closed-loop zero-violation boundary in units of r_sync = 2 a_max / w_t^2: "
        + ", ".join(f"({w:g} deg/s, {a:g}) {x:.2f}" for (w, a), x in zip(sel, fb)) + f"; spread {spread:.2f}",
        REPRODUCED if spread <= 0.04 else UNEXPLAINED,
        "J2 truth, hard constraints, the MPC of the sweep, co-rotating starts on the docking axis; each fraction is a "
        "bisection (boundary_fraction, tol 0.02) over whole closed loops, so the collapse is measured, not built in "
        "(the orbit rate n enters the truth and the MPC model). 1 deg/s uses N_p = 80 (see the row above)",
        red, data={"fractions": {f"{w:g},{a:g}": x for (w, a), x in zip(sel, fb)}, "spread": spread},
        tolerance="spread <= 0.04 r_sync: two bisection brackets (each fraction is known to 0.02)"))
    outside = [run_case(w, a, [0.0, 1.5 * sync_range(a, math.radians(w)), 0.0], mpc_config="single",
                        constraint_mode="soft") for w, a in sel]
    n_out = sum(o["los_violations"] > 0 for o in outside)
    rows.append(Claim(
        "los", "Starts outside r_sync violate the corridor", "15/15 violate (§10.6)",
        f"{n_out}/{len(sel)} violate from 1.5 r_sync (soft constraints)", REPRODUCED if n_out == len(sel) else UNEXPLAINED,
        "co-rotating start on the docking axis, 600 s, J2 truth", red, tolerance="every combination (the paper's 15/15)"))
    # Table 3 at the 150 m start: hold and r_min, hard and soft constraints
    hard = {k: run_case(k[0], k[1], [0.0, 150.0, 0.0], mpc_config="single", constraint_mode="hard") for k in sel}
    soft = {k: run_case(k[0], k[1], [0.0, 150.0, 0.0], mpc_config="single", constraint_mode="soft") for k in sel}
    bnd = float(np.median(fb))
    inside = [k for k in sel if 150.0 <= bnd * sync_range(k[1], math.radians(k[0]))]
    hold_in = sum(bool(hard[k]["hold_reached"]) for k in inside)
    out_inf = [k for k in sel if k not in inside]
    n_inf = sum(hard[k]["outcome"] == "qp_infeasible" for k in out_inf)
    slow = [k for k in out_inf if PAPER_TABLE3[k][2] >= 138.0]
    d_slow = [abs(hard[k]["r_min_m"] - PAPER_TABLE3[k][2]) for k in slow]
    fast = [k for k in out_inf if PAPER_TABLE3[k][2] < 138.0]
    rows.append(Claim(
        "los", "Table 3 (150 m start): Hold column and r_min", "Hold: none of 15; r_min 0-145 m (Table 3)",
        f"150 m lies inside the measured boundary ({bnd:.2f} r_sync) for {len(inside)} of {len(sel)} combinations: "
        f"{hold_in} of them reach the hold; the other {len(out_inf)} start beyond it and {n_inf} are QP-infeasible at once "
        f"with hard constraints (r_min {min((hard[k]['r_min_m'] for k in out_inf), default=math.nan):.0f}-150 m"
        + (f"; paper's r_min >= 138 m rows within {max(d_slow):.0f} m" if d_slow else "") + ")",
        UNEXPLAINED if fast else EXPLAINED,
        "the paper does not state Table 3's start: 150 m co-rotating on the docking axis is our documented choice (its "
        "r_min of 143-145 m at the slow rates suggests it). The measured boundary explains which rows can work at all: "
        "beyond it the hard-constraint QP is infeasible from the first steps, so r_min stays near the start, as in the "
        "paper's slow-rate rows. Not explained: the paper's Hold = False for the rows inside the boundary (it does not "
        "define its hold criterion; ours: reaching the hold range) and its smaller r_min (51-113 m) at the fast rates, "
        "which neither our hard runs (they stop) nor our soft runs (r_min "
        f"{min(soft[k]['r_min_m'] for k in sel):.1f}-{max(soft[k]['r_min_m'] for k in sel):.0f} m, drifting through the "
        "corridor wall) reproduce", red,
        data={"boundary_fraction": bnd, "rows": {f"{k[0]:g},{k[1]:g}": {
            "hard": {"outcome": hard[k]["outcome"], "hold": bool(hard[k]["hold_reached"]), "r_min_m": hard[k]["r_min_m"]},
            "soft": {"hold": bool(soft[k]["hold_reached"]), "r_min_m": soft[k]["r_min_m"],
                     "violations": soft[k]["los_violations"]},
            "paper": {"hold": PAPER_TABLE3[k][1], "r_min_m": PAPER_TABLE3[k][2]}} for k in sel}}))
    return rows

