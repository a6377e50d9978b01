"""Figures of the underactuated-docking system (Aborizk et al. Figs. 2-9).

- :func:`plot_trajectory` — Figs. 2 / 6 / 8: Hill-plane path with the body x axis (docking
  port, black) and the thrust direction (red) drawn every few steps.
- :func:`plot_value_function` — Fig. 3: V_H per step and the eq. 14 bound (average of the
  previous N values).
- :func:`plot_states` — Figs. 7 / 9: state and control histories.
- :func:`plot_comparison` — Figs. 4-5: trajectories and value functions of several runs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxops.plotting.common import plt, save


def _label(result, fallback: str) -> str:
    run = result.meta.get("run") or {}
    return str(run.get("label", fallback))


def plot_trajectory(result, path: Path, title: str = "", arrows: int = 25) -> Path:
    """Path in the Hill plane (x radial horizontal, y along-track vertical, so theta is the
    drawn angle of the body axis) with body-axis and thrust arrows at ``arrows`` samples."""
    s = result.x_true
    u = result.u_applied
    fig, ax = plt.subplots(figsize=(6.5, 6))
    ax.plot(s[:, 0], s[:, 1], "k-", lw=1.0, label="trajectory")
    ax.plot(s[0, 0], s[0, 1], "o", color="tab:green", ms=9, label="start")
    ax.plot(0.0, 0.0, "o", color="gold", mec="k", ms=9, label="docking point")
    span = max(np.ptp(s[:, 0]), np.ptp(s[:, 1]), 1.0)
    length = 0.05 * span
    n = len(s) - 1
    idx = np.unique(np.linspace(0, max(n - 1, 0), min(arrows, max(n, 1))).astype(int))
    theta = s[idx, 2]
    ax.quiver(s[idx, 0], s[idx, 1], np.cos(theta) * length, np.sin(theta) * length, angles="xy",
              scale_units="xy", scale=1.0, color="k", width=0.004, label="docking port (body x)")
    fmax = max(np.max(np.abs(u[:n, 0])) if n else 0.0, 1e-12)
    thrust = u[idx, 0] / fmax
    ax.quiver(s[idx, 0], s[idx, 1], np.cos(theta) * thrust * length, np.sin(theta) * thrust * length,
              angles="xy", scale_units="xy", scale=1.0, color="tab:red", width=0.004, label="thrust")
    ax.set_xlabel("x (radial) [m]")
    ax.set_ylabel("y (along-track) [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title)
    return save(fig, path)


def plot_value_function(result, path: Path, title: str = "") -> Path:
    """V_H per step (blue) and the averaged-value bound of eq. 14 (orange)."""
    value = result.info.get("value_function")
    bound = result.info.get("value_bound")
    fig, ax = plt.subplots(figsize=(7, 4))
    if value is not None:
        ax.semilogy(result.t, value, color="tab:blue", label="value function $V_H$")
    if bound is not None and np.any(np.isfinite(bound)):
        ax.semilogy(result.t, bound, color="tab:orange", label="bound: mean of previous N $V_H$ (eq. 14)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("value")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title)
    return save(fig, path)


def plot_states(result, path: Path, title: str = "") -> Path:
    """x, y, theta, vx, vy, omega and the two controls against time."""
    s, u, t = result.x_true, result.u_applied, result.t
    n = len(t) - 1
    panels = [
        (s[:, 0], "x [m]"), (s[:, 1], "y [m]"), (np.degrees(np.unwrap(s[:, 2])), "θ (unwrapped) [deg]"),
        (s[:, 3], "ẋ [m/s]"), (s[:, 4], "ẏ [m/s]"), (np.degrees(s[:, 5]), "θ̇ [deg/s]"),
    ]
    fig, axes = plt.subplots(4, 2, figsize=(10, 9), sharex=True)
    for ax, (data, label) in zip(axes[:3].T.ravel(), panels):
        ax.plot(t, data, lw=1.0)
        ax.set_ylabel(label)
    axes[3, 0].step(t[:n], u[:n, 0], where="post", lw=1.0, color="tab:red")
    axes[3, 0].set_ylabel("thrust $f_x$ [N]")
    axes[3, 1].step(t[:n], np.degrees(u[:n, 1]), where="post", lw=1.0, color="tab:purple")
    axes[3, 1].set_ylabel("wheel accel. [deg/s²]")
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    for ax in axes[3]:
        ax.set_xlabel("time [s]")
    fig.suptitle(title)
    fig.tight_layout()
    return save(fig, path)


def plot_comparison(results: dict, path_traj: Path, path_value: Path, title: str = "") -> list[Path]:
    """Figs. 4-5: trajectories and value functions of several runs on common axes."""
    fig, ax = plt.subplots(figsize=(6.5, 6))
    for label, res in results.items():
        s = res.x_true
        ax.plot(s[:, 0], s[:, 1], lw=1.2, label=f"{label} ({len(s) - 1} steps)")
    first = next(iter(results.values())).x_true
    ax.plot(first[0, 0], first[0, 1], "o", color="tab:green", ms=9, label="start")
    ax.plot(0.0, 0.0, "o", color="gold", mec="k", ms=9, label="docking point")
    ax.set_xlabel("x (radial) [m]")
    ax.set_ylabel("y (along-track) [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title)
    paths = [save(fig, path_traj)]
    fig, ax = plt.subplots(figsize=(7, 4))
    for label, res in results.items():
        value = res.info.get("value_function")
        if value is not None:
            ax.semilogy(res.t, value, lw=1.2, label=label)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("value function $V_H$")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title)
    paths.append(save(fig, path_value))
    return paths


def scenario_figures(sc, results: dict, out_dir: Path) -> list[Path]:
    """All figures of a scenario run into ``out_dir``."""
    out_dir = Path(out_dir)
    paths: list[Path] = []
    for label, res in results.items():
        name = f"{sc.name} — {label}"
        paths.append(plot_trajectory(res, out_dir / f"trajectory_{label}.png", title=name))
        paths.append(plot_value_function(res, out_dir / f"value_function_{label}.png", title=name))
        paths.append(plot_states(res, out_dir / f"states_{label}.png", title=name))
    if len(results) > 1:
        paths += plot_comparison(results, out_dir / "comparison_trajectories.png",
                                 out_dir / "comparison_value_functions.png", title=sc.name)
    return paths


run_figures = scenario_figures
