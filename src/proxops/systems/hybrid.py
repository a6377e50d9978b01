"""System ``hybrid``: hybrid MPC capture and post-capture of a tumbling chief
(Basu et al.).

Scenarios (src/proxops/scenarios/builtin/hybrid-capture*.toml)::

    proxops run hybrid-capture --json            # §VII: contact(s), dock, snap at 593 s, re-dock (MEKF + noise)
    proxops run hybrid-capture-exact --json      # the same on exact states (labelled variant)
    proxops run hybrid-redock --json             # a 5 N s snap that leaves the capture envelope, re-capture
    proxops mc hybrid-envelope --workers 2 --report   # capture envelope grid (offset x tumble x thrust)
    proxops run hybrid-capture-no-snap --json    # §VII without the latch snap
    proxops run hybrid-capture-gentle --json     # a slower, aligned approach: no contact
    proxops mc hybrid-capture-mc --runs 50 --workers 2 --report

Plant: :class:`proxops.propagation.hybrid_plant.HybridCapturePlant` (two rigid bodies in
the target orbit frame, cuboid contacts with restitution, eq. 81 latch, latch snap).
Controller: :class:`proxops.control.hybrid_supervisor.HybridSupervisor` (Cases 1-4, eq. 17,
dwell timer tau / T_1) over the capture MPC (Problem 2) and the post-capture MPC (Problem 3)
of :mod:`proxops.control.hybrid_mpc`.

Truth and navigation: each CoM and the desired orbit move under exact two-body +
J2 gravity ([truth]); both MPCs keep their CW models and see :class:`proxops.navigation.hybrid.HybridNavigation`
(MEKF of the chief attitude and rate, noisy relative pose and composite CoM; [estimation]).

Status (judged at the END of the run, [success]): ``docked`` / ``redocked`` only if the pair is
latched with |rho|, |rho_dot| inside the capture envelope, the chief tumble |omega_c| below
``chief_rate_max_deg_s`` and |rho_n - r_des| below ``tracking_error_max_m``; otherwise
``failed: <reason>`` (not docked; separated after docking, not latched at the end; latched
outside the envelope; spinning; tracking error). A run whose port range, relative rate or chief
tumble passes its divergence bound is stopped there (:class:`Divergence`, stop reason
``diverged: ...``, status ``failed: diverged: ... at t s``).

Run summary keys (besides the engine's): ``docked``, ``dock_time_s``, ``contacts``
([{t_s, impulse_Ns}]), ``mode_changes`` ([{t_s, from, to}]), ``decoupled``,
``decouple_time_s``, ``redocked``, ``redock_time_s``, ``final_tracking_error_m``,
``max_tracking_error_after_dock_m`` (|rho_n - r_des| over the post-capture samples after
the first dock), ``tracking_error_last_100s_max_m``, chief rate at start and end,
``solve_time_ms`` (median, p95, max of the controller step).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from proxops.control.hybrid_mpc import CaptureMPC, CaptureMPCConfig, PostCaptureMPC, PostCaptureMPCConfig
from proxops.control.hybrid_supervisor import HybridModeRule, HybridSupervisor
from proxops.dynamics.hybrid_relative import composite_inertia
from proxops.errors import input_error
from proxops.navigation.hybrid import HybridNavigation
from proxops.navigation.mekf import attitude_error
from proxops.propagation.hybrid_plant import (M_LATCHED, N_MEASURED, HybridCapturePlant, contact_impulses,
                                              overlap_from_relative)
from proxops.scenarios.registry import register_system
from proxops.sim.engine import Setup
from proxops.solvers.stats import solve_time_stats
from proxops.systems.base import SystemBase
from proxops.systems.common import navigation_model
from proxops.systems.schema.hybrid import HybridScenario, model_objects


def _mpc_config(cls, **wanted):
    """A default MPC config with the wanted fields that it has (dataclasses.replace)."""
    cfg = cls()
    names = {f.name for f in dataclasses.fields(cfg)}
    return dataclasses.replace(cfg, **{k: v for k, v in wanted.items() if k in names})


def measured_sigma(position_sigma_m: float, velocity_sigma_mps: float) -> np.ndarray:
    """Navigation 1-sigma per measured-state entry: rho and rho_dot only (the rest exact)."""
    sigma = np.zeros(N_MEASURED)
    sigma[0:3], sigma[3:6] = position_sigma_m, velocity_sigma_mps
    return sigma


def build_setup(sc: HybridScenario):
    params, _, x0, envelope = model_objects(sc)
    if sc.estimation.model == "mekf" and sc.navigation.model != "noise":
        raise input_error("navigation.model", sc.navigation.model, "hybrid runs on [estimation] (model = mekf); "
                          "set estimation.model = \"exact\" to use [navigation]")
    plant = HybridCapturePlant(params, x0, envelope, x_ref0=list(sc.reference.position_m) + list(sc.reference.velocity_mps),
                               snap_enabled=sc.latch.snap, max_substep_s=sc.contact.max_substep_s,
                               collision_gap_s=sc.contact.collision_gap_s, rearm_delay_s=sc.latch.rearm_delay_s,
                               gravity=sc.truth.gravity, inclination_deg=sc.truth.inclination_deg)
    cm = sc.capture_mpc
    capture = CaptureMPC(params, _mpc_config(CaptureMPCConfig, horizon_s=sc.control.horizon_capture_s,
                                             period_s=cm.period_s, R_force=cm.R_force, R_torque=cm.R_torque,
                                             approach_guidance=cm.approach_guidance, solver=cm.solver))
    post = PostCaptureMPC(params, _mpc_config(PostCaptureMPCConfig, period_s=cm.period_s, solver=cm.solver))
    rule = HybridModeRule(envelope, sc.docking.release_distance_m, sc.docking.min_dwell_s)
    supervisor = HybridSupervisor(capture, post, rule)
    if sc.estimation.model == "mekf":
        e = sc.estimation
        x_dock = np.zeros(32)
        x_dock[12] = x_dock[16] = 1.0
        arm = params.mass_chief_kg / params.mass_total_kg * (params.P_c - params.P_d)
        navigation = HybridNavigation(params.J_c, params.mean_motion_rad_s, composite_inertia(x_dock, params), arm,
                                      e.position_sigma_m, e.velocity_sigma_mps,
                                      e.attitude_sigma_deg, e.rate_sigma_deg_s, e.chief_attitude_sigma_deg,
                                      e.com_position_sigma_m, e.com_velocity_sigma_mps)
    else:
        navigation = navigation_model(sc.navigation, per_state_sigma=measured_sigma, system="hybrid")
    return Setup(plant=plant, controller=supervisor, duration_s=sc.sim.duration_s, navigation=navigation,
                 stop_condition=Divergence.of(sc, plant.relative_state(plant.initial_state())),
                 meta={"system": "hybrid", "control": "thrust N + torque N m in D"})


def _norm3(v) -> float:
    """|v| of a float64 vector as np.linalg.norm computes it (sqrt of v.dot(v)), without its checks."""
    return math.sqrt(v.dot(v))


class Divergence:
    """Stop condition: the run is ended with reason ``diverged: ...`` as soon as the true port
    range |rho| (m), the deputy's rate relative to the chief |omega| or the chief tumble
    |omega_c| (rad/s) passes its bound ([success] section)."""

    def __init__(self, range_m: float, rate_rad_s: float, chief_rate_rad_s: float):
        self.range_m, self.rate_rad_s, self.chief_rate_rad_s = range_m, rate_rad_s, chief_rate_rad_s

    @classmethod
    def of(cls, sc: HybridScenario, x0_rel) -> "Divergence":
        x0 = np.asarray(x0_rel, float)
        s = sc.success
        rng = s.divergence_range_m if s.divergence_range_m is not None else 2.0 * float(np.linalg.norm(x0[0:3])) + 2.0
        wc = (s.divergence_chief_rate_deg_s if s.divergence_chief_rate_deg_s is not None
              else 2.0 * math.degrees(float(np.linalg.norm(x0[17:20]))) + 2.0)
        return cls(rng, math.radians(s.divergence_rate_deg_s), math.radians(wc))

    def __call__(self, t: float, x) -> str | None:
        r = _norm3(x[0:3])
        if r > self.range_m:
            return f"diverged: port range {r:.3g} m > {self.range_m:.3g} m"
        w = _norm3(x[6:9])
        if w > self.rate_rad_s:
            return f"diverged: relative rate {math.degrees(w):.3g} deg/s > {math.degrees(self.rate_rad_s):.3g} deg/s"
        wc = _norm3(x[17:20])
        if wc > self.chief_rate_rad_s:
            return (f"diverged: chief tumble {math.degrees(wc):.3g} deg/s > "
                    f"{math.degrees(self.chief_rate_rad_s):.3g} deg/s")
        return None


def summarize_result(sc: HybridScenario, result) -> dict:
    """The hybrid keys of one run (module doc)."""
    t = result.t
    modes = list(result.mode)
    changes = []
    for tt, kind, msg in result.events:
        if kind == "mode" and " -> " in msg:
            a, b = msg.split(" -> ", 1)
            changes.append({"t_s": float(tt), "from": a, "to": b})
    docks = [c["t_s"] for c in changes if c["to"] == "post-capture"]
    undocks = [c["t_s"] for c in changes if c["from"] == "post-capture"]
    if modes and modes[0] == "post-capture":
        docks = [float(t[0])] + docks
    docked = bool(docks)
    dock_time = docks[0] if docked else None
    decoupled = bool(undocks)
    redock = [d for d in docks if decoupled and d > undocks[0]]
    x = result.x_true
    err = np.linalg.norm(x[:, 20:23] - x[:, 26:29], axis=1)
    post = np.array([m == "post-capture" for m in modes])
    after = post & (t >= dock_time) if docked else np.zeros(len(t), bool)
    last = t >= t[-1] - 100.0
    wc = np.linalg.norm(x[:, 17:20], axis=1)
    contacts = contact_impulses(result.events)
    solved = result.solve_time_s[result.solve_time_s > 0]
    summary = {
        "docked": docked,
        "dock_time_s": dock_time,
        "contacts": contacts,
        "contacts_before_dock": sum(1 for c in contacts if dock_time is None or c["t_s"] < dock_time),
        "first_contact_s": contacts[0]["t_s"] if contacts else None,
        "peak_contact_impulse_Ns": max((c["impulse_Ns"] for c in contacts), default=0.0),
        "mode_changes": changes,
        "decoupled": decoupled,
        "decouple_time_s": undocks[0] if decoupled else None,
        "redocked": bool(redock),
        "redock_time_s": redock[0] if redock else None,
        "final_mode": modes[-1] if modes else "",
        "final_tracking_error_m": float(err[-1]),
        "max_tracking_error_after_dock_m": float(err[after].max()) if after.any() else None,
        "tracking_error_last_100s_max_m": float(err[last].max()),
        "chief_rate_initial_deg_s": float(np.degrees(wc[0])),
        "chief_rate_final_deg_s": float(np.degrees(wc[-1])),
        "chief_rate_peak_deg_s": float(np.degrees(wc.max())),
        "chief_rate_peak_time_s": float(t[int(np.argmax(wc))]),
        "solve_time_ms": solve_time_stats(solved),
    }
    snaps = [tt for tt, k, m in result.events if k == "snap" and not m.startswith("skipped")]
    if snaps:
        end = summary["redock_time_s"] if redock else t[-1]
        win = (t >= snaps[0]) & (t <= end)
        summary["snap_time_s"] = float(snaps[0])
        summary["max_separation_after_snap_m"] = float(np.linalg.norm(x[win, 0:3], axis=1).max())
        free = win & (x[:, 33] < 0.5)
        summary["unlatched_after_snap_s"] = float(free.sum() * (t[1] - t[0])) if len(t) > 1 else 0.0
    xe = getattr(result, "x_est", None)
    if xe is not None and len(xe) == len(t):
        att = np.array([np.degrees(np.linalg.norm(attitude_error(a, b))) for a, b in zip(xe[:, 13:17], x[:, 13:17])])
        summary["chief_attitude_est_error_deg"] = {"final": float(att[-1]), "max_after_60s": float(
            att[t >= 60.0].max()) if (t >= 60.0).any() else float(att.max())}
        summary["chief_rate_est_error_deg_s_final"] = float(np.degrees(np.linalg.norm(xe[-1, 17:20] - x[-1, 17:20])))
    summary["estimation"] = sc.estimation.model  # "mekf": the MPCs ran on estimates; "exact": on the truth
    summary["sequence"] = sequence_text(contacts, changes, result.events)
    summary.update(final_verdict(sc, result, x, err, wc, docked, decoupled, bool(redock)))
    return summary


def final_verdict(sc: HybridScenario, result, x, err, wc, docked: bool, decoupled: bool, redocked: bool) -> dict:
    """Status of a run judged on its END state (module doc): success = latched, |rho| and
    |rho_dot| inside the capture envelope, chief tumble and tracking error below the [success]
    thresholds; otherwise ``failed: <reason>`` (a divergence stop names its bound)."""
    params, _, _, env = model_objects(sc)
    xf = x[-1]
    latched = bool(xf[M_LATCHED] > 0.5)
    rho, rhod = float(np.linalg.norm(xf[0:3])), float(np.linalg.norm(xf[3:6]))
    wc_end = float(np.degrees(wc[-1]))
    s = sc.success
    lat = x[:, M_LATCHED] > 0.5
    overlap = [max(-overlap_from_relative(xx, params), 0.0) for xx in x[lat]]
    outcome = str(result.meta.get("outcome", "completed"))
    if outcome.startswith("diverged"):
        status = f"failed: {outcome} at {float(result.t[-1]):.1f} s"
    elif not docked:
        status = "failed: not docked"
    elif not latched:
        status = "failed: separated after docking, not latched at the end"
    elif rho > env.position_m or rhod > env.velocity_mps:
        status = f"failed: latched outside the envelope (|rho| {rho:.3g} m, |rho_dot| {rhod:.3g} m/s)"
    elif wc_end > s.chief_rate_max_deg_s:
        status = f"failed: spinning (chief tumble {wc_end:.3g} deg/s > {s.chief_rate_max_deg_s:g} deg/s)"
    elif float(err[-1]) > s.tracking_error_max_m:
        status = f"failed: tracking error {float(err[-1]):.3g} m > {s.tracking_error_max_m:g} m"
    else:
        status = "redocked" if redocked else "docked"
    return {"status": status, "latched_at_end": latched, "final_port_range_m": rho, "final_port_speed_mps": rhod,
            "latched_samples": int(lat.sum()),
            "max_latched_overlap_m": float(max(overlap, default=0.0)),
            "latched_samples_overlap_over_1mm": int(sum(o > 1e-3 for o in overlap))}


def sequence_text(contacts: list, changes: list, events) -> str:
    """One readable line of the run's sequence: contacts (count, first), mode changes, snap."""
    parts = []
    if contacts:
        parts.append(f"{len(contacts)} contact(s) from {contacts[0]['t_s']:.1f} s")
    snaps = [t for t, k, m in events if k == "snap" and not m.startswith("skipped")]
    items = [(c["t_s"], f"{c['from']} -> {c['to']} {c['t_s']:.1f} s") for c in changes]
    items += [(t, f"snap {t:.1f} s") for t in snaps]
    parts += [text for _, text in sorted(items)]
    return "; ".join(parts) or "no contact, no mode change"


@register_system("hybrid")
class HybridSystem(SystemBase):
    Scenario = HybridScenario

    def build(self, sc: HybridScenario):
        return build_setup(sc)

    def summarize(self, sc: HybridScenario, result) -> dict:
        return summarize_result(sc, result)

    def success(self, sc: HybridScenario, summary: dict) -> bool:
        return not str(summary.get("status", "")).startswith("failed")

    def campaign_table(self, sc: HybridScenario, table) -> str:
        """Outcome table of a hybrid campaign: docked / re-docked / failed counts, contacts per
        run and peak contact impulse; for the envelope grid (hybrid-envelope) also one row per cell."""
        env = envelope_table(sc, table)
        return outcome_table(table) + ("\n\n" + env if env else "")


ENVELOPE_COLUMNS = ("disp.initial.rho0_m[1]", "disp.initial.omega_c_rad_s[2]", "disp.control.force_max_capture_N")


def envelope_cells(sc: HybridScenario, table):
    """Rows of the capture-envelope grid (hybrid-envelope): (offset of the deputy port from the
    chief's port along the docking axis m, tumble deg/s, thrust bound N, status, thrust the deputy
    needs to co-rotate on the docking axis at the docked CoM distance r_dock = |P_c - P_d|
    (m_d omega^2 r_dock, N: necessary to dock at all), the same at its start distance (N)).
    None if the campaign is not that grid."""
    if not all(c in table.columns for c in ENVELOPE_COLUMNS):
        return None
    params = model_objects(sc)[0]
    r_dock = float(np.linalg.norm(params.P_c - params.P_d))
    gap = 0.5 * (sc.chief.dims_m[1] + sc.deputy.dims_m[1])
    status = table["status"] if "status" in table.columns else table["outcome"]
    rows = []
    for r_y, w, f, st in zip(table[ENVELOPE_COLUMNS[0]], table[ENVELOPE_COLUMNS[1]], table[ENVELOPE_COLUMNS[2]],
                             status):
        m_w2 = sc.deputy.mass_kg * float(w) ** 2
        rows.append((float(r_y) - gap, math.degrees(float(w)), float(f), str(st), m_w2 * r_dock, m_w2 * float(r_y)))
    return sorted(rows)


def envelope_table(sc: HybridScenario, table) -> str:
    """Markdown table of :func:`envelope_cells`: cells that cannot succeed for a physical reason
    (thrust bound below m_d omega^2 r_dock) named with the number, and the success region."""
    cells = envelope_cells(sc, table)
    if not cells:
        return ""
    lines = ["| port offset m | tumble deg/s | thrust bound N | status | m_d w^2 r_dock N | m_d w^2 r_start N | physics |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for d, w, f, st, need, need0 in cells:
        if need > f:
            phys = f"cannot dock: co-rotating at the docked radius needs {need:.3g} N > {f:g} N"
        elif need0 > f:
            phys = f"cannot hold the start on the turning axis ({need0:.3g} N > {f:g} N)"
        else:
            phys = ""
        lines.append(f"| {d:g} | {w:g} | {f:g} | {st} | {need:.3g} | {need0:.3g} | {phys} |")
    ok = [c for c in cells if not c[3].startswith("fail")]
    lines += ["", f"success in {len(ok)} of {len(cells)} cells: "
              + ("; ".join(f"({c[0]:g} m, {c[1]:g} deg/s, {c[2]:g} N)" for c in ok) or "none")]
    return "\n".join(lines)


def is_true_column(values) -> np.ndarray:
    """True where a campaign column holds True (None / NaN of a run that raised count as False)."""
    return np.array([v is True or (isinstance(v, np.bool_) and bool(v)) for v in values], dtype=bool)


def outcome_table(table) -> str:
    """Markdown outcome table from campaign rows (``metric.*`` columns of the run summaries)."""
    n = len(table)
    if n == 0:
        return ""

    def col(name, default=np.nan):
        c = f"metric.{name}"
        return table[c] if c in table.columns else np.full(n, default)

    docked = is_true_column(col("docked", False))
    redocked = is_true_column(col("redocked", False))
    decoupled = is_true_column(col("decoupled", False))
    errors = np.asarray(table["outcome"] == "error") if "outcome" in table.columns else np.zeros(n, bool)
    failed = ~np.asarray(table["success"], dtype=bool) if "success" in table.columns else ~docked
    before = np.asarray(col("contacts_before_dock", 0), dtype=float)
    peak = np.asarray(col("peak_contact_impulse_Ns", 0.0), dtype=float)
    n_contacts = np.array([len(__import__("json").loads(v)) if isinstance(v, str) else 0
                           for v in col("contacts", "[]")], dtype=float)
    lines = ["| outcome | runs |", "| --- | --- |",
             f"| docked | {int(docked.sum())} |",
             f"| decoupled by the snap | {int(decoupled.sum())} |",
             f"| re-docked | {int(redocked.sum())} |",
             f"| failed | {int(failed.sum())} (of which raised: {int(errors.sum())}) |",
             f"| total | {n} |", "",
             "| per run | mean | median | max |", "| --- | --- | --- | --- |"]
    for label, v in (("contacts", n_contacts), ("contacts before dock", before), ("peak contact impulse N s", peak)):
        v = v[np.isfinite(v)]
        if v.size:
            lines.append(f"| {label} | {v.mean():.3g} | {np.median(v):.3g} | {v.max():.3g} |")
    return "\n".join(lines)
