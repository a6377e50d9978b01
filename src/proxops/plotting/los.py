"""Figures of a ``los`` run: body-frame path inside the corridor, LVLH path, time histories."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxops.plotting.common import plt, save
from proxops.constraints.los_corridor import LosCorridor
from proxops.dynamics.tumbling_target import BodyFrameModel
from proxops.core.cw import mean_motion


def los_figures(sc, result, out_dir: Path) -> list[Path]:
    """Write los_body.png, los_lvlh.png and los_time.png into ``out_dir``; return their paths."""

    out_dir = Path(out_dir)
    t = result.t
    x_b = result.x_true
    p = x_b[:, :3]
    corridor = LosCorridor(np.radians(sc.target.corridor_half_angle_deg), sc.target.corridor_floor_m,
                           sc.target.corridor_faces)
    viol = np.asarray(corridor.violation_body(p))
    w_t = np.radians(sc.target.tumble_rate_deg_s)
    r_sync = 2 * sc.chaser.a_max_mps2 / w_t**2 if w_t > 0 else np.inf
    title = (f"{sc.name}: w_t = {sc.target.tumble_rate_deg_s:g} deg/s, a_max = {sc.chaser.a_max_mps2:g} m/s^2, "
             f"r_sync = {r_sync:.1f} m")
    paths = []

    # body frame (x_B, y_B) with the corridor's z_B = 0 section (faces at theta = 0, pi)
    fig, ax = plt.subplots(figsize=(6, 6))
    y_top = max(float(p[:, 1].max()), float(np.linalg.norm(p[0]))) * 1.1 + 1.0
    tan_a = np.tan(corridor.half_angle_rad)
    ys = np.array([corridor.y_min_m, y_top])
    ax.fill_betweenx(ys, -tan_a * ys, tan_a * ys, color="tab:green", alpha=0.12, label="corridor (z_B = 0)")
    ax.plot(p[:, 0], p[:, 1], lw=1.2, label="chaser")
    bad = viol > corridor.tolerance_m
    if bad.any():
        ax.plot(p[bad, 0], p[bad, 1], "r.", ms=3, label="violation > 1e-3 m")
    ax.plot(p[0, 0], p[0, 1], "go", label="start")
    ax.plot(p[-1, 0], p[-1, 1], "ks", label="end")
    ax.plot(0, 0, "k*", ms=12, label="target")
    if np.isfinite(r_sync) and r_sync < 2 * y_top:
        th = np.linspace(0, 2 * np.pi, 200)
        ax.plot(r_sync * np.cos(th), r_sync * np.sin(th), "k--", lw=0.8, label="r_sync")
    ax.set_xlabel("x_B [m]")
    ax.set_ylabel("y_B (docking axis) [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7, loc="best")
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=8)
    paths.append(save(fig, out_dir / "los_body.png"))

    # LVLH path (reconstructed with the circular-orbit attitude model)
    model = BodyFrameModel(mean_motion(sc.orbit.sma_m), w_t, 1.0, np.radians(sc.target.initial_angle_deg))
    hill = np.array([model.hill_from_body(tk, xk) for tk, xk in zip(t, x_b)])
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.plot(hill[:, 1], hill[:, 0], lw=1.2)
    ax.plot(hill[0, 1], hill[0, 0], "go", label="start")
    ax.plot(hill[-1, 1], hill[-1, 0], "ks", label="end")
    ax.plot(0, 0, "k*", ms=12, label="target")
    ax.set_xlabel("along-track y [m]")
    ax.set_ylabel("radial x [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    ax.set_title("LVLH path " + title, fontsize=8)
    paths.append(save(fig, out_dir / "los_lvlh.png"))

    # time histories
    fig, axes = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    axes[0].plot(t, np.linalg.norm(p, axis=1))
    if np.isfinite(r_sync):
        axes[0].axhline(r_sync, color="k", ls="--", lw=0.8, label="r_sync")
        axes[0].legend(fontsize=7)
    axes[0].set_ylabel("range [m]")
    axes[1].semilogy(t, np.maximum(viol, 1e-6), label="violation (floored at 1e-6 m)")
    axes[1].axhline(corridor.tolerance_m, color="r", ls="--", lw=0.8, label="tolerance")
    axes[1].legend(fontsize=7, loc="upper right")
    axes[1].set_ylabel("corridor violation [m]")
    for i, name in enumerate(("u_x (radial)", "u_y (along-track)", "u_z (normal)")[:result.u_cmd.shape[1]]):
        axes[2].plot(t, result.u_cmd[:, i], label=name)
    axes[2].legend(fontsize=7, loc="upper right", ncol=3)
    axes[2].set_ylabel("u (LVLH) [m/s^2]")
    modes = list(result.mode)
    names = sorted(set(m for m in modes if m))
    if names:
        idx = [names.index(m) if m in names else np.nan for m in modes]
        axes[3].step(t, idx, where="post")
        axes[3].set_yticks(range(len(names)))
        axes[3].set_yticklabels(names)
    axes[3].set_ylabel("regime")
    axes[3].set_xlabel("time [s]")
    for a in axes:
        a.grid(alpha=0.3)
    axes[0].set_title(title, fontsize=8)
    paths.append(save(fig, out_dir / "los_time.png"))
    return paths


def run_figures(sc, results, out_dir: Path) -> list[Path]:
    """``proxops run --out`` figures of a los run."""
    if isinstance(results, dict):  # runner passes {label: SimResult}
        results = next(iter(results.values()))
    return los_figures(sc, results, Path(out_dir))
