"""Figures of the CORTEX closed loop (cortex-convex-guidance.md Figs. 13-15): trajectories and
tracking errors over time (Fig. 13 low / Fig. 14 high error level) and the Monte Carlo
distributions of TOF, delta-v and terminal errors (Fig. 15)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxops.plotting.common import plt, save

PHASE_COLORS = {"flyaround": "#d8f0d8", "approach": "#d8e4f8", "null": "#f8d8d8", "abort_null": "#f8d8d8",
                "retreat": "#f8d8d8", "hold1": "#eeeeee", "hold2": "#eeeeee"}


def _spans(ax, result):
    modes = list(result.mode)
    t = result.t
    k0 = 0
    for k in range(1, len(modes) + 1):
        if k == len(modes) or modes[k] != modes[k0]:
            c = PHASE_COLORS.get(modes[k0])
            if c and k0 < len(t) - 1:
                ax.axvspan(t[k0], t[min(k, len(t) - 1)], color=c, lw=0, zorder=0)
            k0 = k


def run_figure(sc, result, path: Path) -> Path:
    """One run: in-plane trajectory (x radial, y along-track) and tracking error over time."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.5))
    r = result.x_true[:, :3]
    a1.plot(r[:, 1], r[:, 0], lw=1)
    th = np.linspace(0, 2 * np.pi, 200)
    for rad, ls in ((sc.geometry.r_kos_m, "-"), (sc.geometry.r_kos_m * sc.margins.kos, "--")):
        a1.plot(rad * np.cos(th), rad * np.sin(th), "r" + ls, lw=0.8)
    a1.plot(r[0, 1], r[0, 0], "go")
    a1.plot(r[-1, 1], r[-1, 0], "r*")
    a1.set_xlabel("y along-track (m)")
    a1.set_ylabel("x radial (m)")
    a1.set_aspect("equal")
    a1.set_title(f"{sc.name}: {result.meta.get('outcome', '')}")
    err = result.info.get("track_err_m")
    _spans(a2, result)
    if err is not None:
        a2.semilogy(result.t, np.where(err > 0, err, np.nan), lw=0.8)
    a2.set_xlabel("t (s)")
    a2.set_ylabel("|r - r_ref| (m)")
    a2.set_title("tracking error (green: fly-around, blue: approach, red: recompute/abort)")
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
