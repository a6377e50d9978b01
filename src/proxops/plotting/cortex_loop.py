"""Figures of the CORTEX closed loop (Wijayatunga et al. Figs. 13-15): trajectories and
tracking errors over time (Fig. 13 low / Fig. 14 high error level) and the Monte Carlo
distributions of TOF, delta-v and terminal errors (Fig. 15)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxops.plotting.common import plt, save

PHASE_COLORS = {"flyaround": "#d8f0d8", "approach": "#d8e4f8", "null": "#f8d8d8", "abort_null": "#f8d8d8",
                "retreat": "#f8d8d8", "hold1": "#eeeeee", "hold2": "#eeeeee"}


PHASE_LABELS = {"flyaround": "fly-around", "approach": "final approach", "null": "recompute / abort",
                "abort_null": "recompute / abort", "retreat": "recompute / abort", "hold1": "eclipse hold",
                "hold2": "eclipse hold"}


def _spans(ax, result):
    """Shade each phase of the run; one legend entry per phase that occurs."""
    labelled: set[str] = set()
    modes = list(result.mode)
    t = result.t
    k0 = 0
    for k in range(1, len(modes) + 1):
        if k == len(modes) or modes[k] != modes[k0]:
            c = PHASE_COLORS.get(modes[k0])
            if c and k0 < len(t) - 1:
                label = PHASE_LABELS.get(modes[k0], modes[k0])
                ax.axvspan(t[k0], t[min(k, len(t) - 1)], color=c, lw=0, zorder=0,
                           label=None if label in labelled else label)
                labelled.add(label)
            k0 = k


def run_figure(sc, result, path: Path) -> Path:
    """One run: in-plane trajectory (x radial, y along-track) and tracking error over time."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.5))
    r = result.x_true[:, :3]
    a1.plot(r[:, 1], r[:, 0], lw=1, label="chaser")
    th = np.linspace(0, 2 * np.pi, 200)
    for rad, ls, label in ((sc.geometry.r_kos_m, "-", "keep-out sphere"),
                           (sc.geometry.r_kos_m * sc.margins.kos, "--", "KOS with margin")):
        a1.plot(rad * np.cos(th), rad * np.sin(th), "r" + ls, lw=0.8, label=label)
    a1.plot(r[0, 1], r[0, 0], "go", label="start")
    a1.plot(r[-1, 1], r[-1, 0], "r*", label="end")
    a1.legend(fontsize=7, loc="best")
    a1.set_xlabel("y along-track (m)")
    a1.set_ylabel("x radial (m)")
    a1.set_aspect("equal")
    a1.set_title(f"{sc.name}: {result.meta.get('outcome', '')}")
    err = result.info.get("track_err_m")
    _spans(a2, result)
    if err is not None:
        a2.semilogy(result.t, np.where(err > 0, err, np.nan), lw=0.8, color="k", label="|r - r_ref|")
    a2.set_xlabel("t (s)")
    a2.set_ylabel("|r - r_ref| (m)")
    a2.set_title("tracking error by phase")
    a2.legend(fontsize=7, loc="best")
    fig.tight_layout()
    return save(fig, path)


def campaign_figures(sc, results, out_dir: Path) -> list[Path]:
    """Fig. 13/14 (trajectories and tracking errors of the runs) and Fig. 15 (distributions)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    level = "high" if sc.errors.delta_r_m >= 0.5 else "low"
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.5))
    for res in results:
        r = res.x_true[:, :3]
        color = {"docked": "C0", "aborted": "C3"}.get(str(res.meta.get("outcome")), "C7")
        a1.plot(r[:, 1], r[:, 0], lw=0.5, color=color, alpha=0.6)
        err = res.info.get("track_err_m")
        if err is not None:
            a2.semilogy(res.t, np.where(err > 0, err, np.nan), lw=0.4, color=color, alpha=0.5)
    th = np.linspace(0, 2 * np.pi, 200)
    a1.plot(sc.geometry.r_kos_m * np.cos(th), sc.geometry.r_kos_m * np.sin(th), "k-", lw=0.8)
    a1.set_aspect("equal")
    a1.set_xlabel("y along-track (m)")
    a1.set_ylabel("x radial (m)")
    a1.set_title(f"{level} error: trajectories (blue docked, red aborted)")
    a2.set_xlabel("t (s)")
    a2.set_ylabel("|r - r_ref| (m)")
    a2.set_title("tracking error")
    fig.tight_layout()
    p1 = save(fig, out_dir / f"fig{13 if level == 'low' else 14}_tracking.png")
    rows = [res.meta.get("cortex_summary", {}) for res in results]
    keys = [("tof_s", "TOF (s)", 1.0), ("total_dv_mps", "Δv (m/s)", 1.0),
            ("terminal_position_error_m", "Δr(t_f) (mm)", 1e3), ("terminal_velocity_error_mps", "Δv_rel(t_f) (mm/s)", 1e3)]
    fig, axes = plt.subplots(1, 4, figsize=(14, 3.5))
    for ax, (k, label, scale) in zip(axes, keys):
        v = np.array([r.get(k, np.nan) for r in rows], float) * scale
        v = v[np.isfinite(v)]
        if v.size:
            ax.hist(v, bins=20)
        ax.set_xlabel(label)
    fig.suptitle(f"Fig. 15 ({level} error): {len(rows)} runs")
    fig.tight_layout()
    p2 = save(fig, out_dir / f"fig15_distributions_{level}.png")
    return [p1, p2]


def _trace_column(table, name):
    import json

    col = f"metric.trace.{name}"
    if col not in table:
        return None
    out = []
    for v in table[col]:
        try:
            out.append(np.array([np.nan if e is None else e for e in json.loads(v)], float))
        except (TypeError, ValueError):
            out.append(np.zeros(0))
    return out


# phase indices of proxops.control.cortex_supervisor.PHASE_INDEX
_PHASE_BG = {0: "#eeeeee", 1: "#d8f0d8", 2: "#eeeeee", 3: "#d8e4f8"}
_RED_PHASES = (4, 5, 6)  # null (recompute), retreat, abort_null


def table_figures(sc, table, out_dir: Path) -> list[Path]:
    """Figs. 13/14 and 15 from the campaign table alone (the per-run ``trace`` the summary keeps
    every ``guidance.trace_step_s``): no saved series needed. Fig. 13 (low) / 14 (high): in-plane
    trajectories (blue docked, red aborted, grey other) and the tracking error over time, red while
    nulling / retreating (recompute and abort extensions), background green fly-around / blue final
    approach of the nominal reference; Fig. 15: TOF, delta-v and terminal errors, docked vs aborted."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    done = table[table["outcome"] != "error"] if "outcome" in table else table
    level = "high" if sc.errors.delta_r_m >= 0.5 else "low"
    paths = []
    ts, xs, ys, errs, phases = (_trace_column(done, k) for k in ("t", "x", "y", "err", "phase"))
    status = done["status"].astype(str).tolist() if "status" in done else ["?"] * len(done)
    if ts is not None and len(ts):
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.8))
        # background: phases of the first run that neither recomputed nor aborted (the nominal timeline)
        ref = int(np.argmin([np.isin(p, _RED_PHASES).sum() + (0 if s == "docked" else len(p))
                             for p, s in zip(phases, status)]))
        t0, p0 = ts[ref], phases[ref]
        k0 = 0
        for k in range(1, len(t0) + 1):
            if k == len(t0) or p0[k] != p0[k0]:
                c = _PHASE_BG.get(int(p0[k0])) if np.isfinite(p0[k0]) else None
                if c:
                    a2.axvspan(t0[k0], t0[min(k, len(t0) - 1)], color=c, lw=0, zorder=0)
                k0 = k
        for t, x, y, e, ph, st in zip(ts, xs, ys, errs, phases, status):
            color = {"docked": "C0", "aborted": "C3"}.get(st, "C7")
            a1.plot(y, x, lw=0.5, color=color, alpha=0.6)
            if e.size:
                red = np.isin(ph, _RED_PHASES)
                a2.semilogy(t, np.where(~red & (e > 0), e, np.nan), lw=0.5, color="C0", alpha=0.5)
                a2.semilogy(t, np.where(red & (e > 0), e, np.nan), lw=0.6, color="C3", alpha=0.7)
        th = np.linspace(0, 2 * np.pi, 200)
        for rad, ls in ((sc.geometry.r_kos_m, "-"), (sc.geometry.r_kos_m * sc.margins.kos, "--")):
            a1.plot(rad * np.cos(th), rad * np.sin(th), "k" + ls, lw=0.8)
        a1.set_aspect("equal")
        a1.set_xlabel("y along-track (m)")
        a1.set_ylabel("x radial (m)")
        n_d = sum(s == "docked" for s in status)
        n_a = sum(s == "aborted" for s in status)
        a1.set_title(f"{level} error: {len(status)} runs ({n_d} docked blue, {n_a} aborted red)")
        a2.set_xlabel("t (s)")
        a2.set_ylabel("|r - r_ref| (m)")
        a2.set_ylim(bottom=1e-4)
        a2.set_title("tracking error (green fly-around, blue approach; red: null/retreat)")
        fig.tight_layout()
        paths.append(save(fig, out_dir / f"fig{13 if level == 'low' else 14}_tracking.png"))
    keys = [("metric.tof_s", "total TOF (s)", 1.0), ("metric.total_dv_mps", "total Δv (m/s)", 1.0),
            ("metric.terminal_position_error_m", "Δr_rel(t_f) (mm), docked", 1e3),
            ("metric.terminal_velocity_error_mps", "Δv_rel(t_f) (mm/s), docked", 1e3)]
    fig, axes = plt.subplots(1, 4, figsize=(15, 3.6))
    st = np.array(status)
    for ax, (col, label, scale) in zip(axes, keys):
        if col not in done:
            continue
        v = done[col].astype(float).to_numpy() * scale
        groups = [(v[(st == "docked") & np.isfinite(v)], "docked", "C0"),
                  (v[(st != "docked") & np.isfinite(v)], "aborted/failed", "C3")]
        groups = [g for g in groups if g[0].size]
        if groups:
            ax.hist([g[0] for g in groups], bins=20, stacked=True, color=[g[2] for g in groups],
                    label=[g[1] for g in groups])
            ax.legend(fontsize=7)
        ax.set_xlabel(label)
    axes[0].set_ylabel("runs")
    fig.suptitle(f"Fig. 15 ({level} error level, Table 3): {len(done)} runs")
    fig.tight_layout()
    paths.append(save(fig, out_dir / f"fig15_distributions_{level}.png"))
    return paths
