"""Figures of Silva et al. 2026 (Figs. 4-11) in the paper's LVLH (x = V-bar, z = R-bar,
drawn with +z down so the Earth is below).

* :func:`plot_trajectory` -- Figs. 4a/6a/9: trajectory, hop impulses (crosses), the free-drift
  horizon x_u from each hop impulse (CW prediction, fading with time), KOZ, approach axis.
* :func:`plot_dv` -- Figs. 4b/6b: impulses per LVLH axis over time (in orbital periods).
* :func:`plot_mc_overlay` -- Figs. 5/7/10: trajectories and cumulative dv of many runs.
* :func:`plot_fig8a` / :func:`plot_fig8b` -- hop-time expression analysis for rho = 0.7.
* :func:`plot_cbf_comparison` -- Fig. 11: without / with the CBF.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from proxops.plotting.common import plt, save
from proxops.frames.lvlh import hill_to_lvlh, hill_vector_to_lvlh, lvlh_vector_to_hill
from proxops.core.cw import cw_stm


def _lvlh(states_hill: np.ndarray) -> np.ndarray:
    return hill_to_lvlh(np.asarray(states_hill, dtype=float))


def _free_drift(x_post_hill: np.ndarray, n: float, span_s: float, samples: int = 241) -> np.ndarray:
    taus = np.linspace(0.0, span_s, samples)
    return np.array([cw_stm(n, t) @ x_post_hill for t in taus])


def _hop_impulses(result) -> list[int]:
    starts = [0.0] + list(result.meta.get("hop_node_times_s", []))[:-1]
    idx = []
    for t in starts:
        k = int(np.argmin(np.abs(result.t - t)))
        if abs(result.t[k] - t) < 1e-6 * max(1.0, t) + 1e-9 and np.linalg.norm(result.u_applied[k]) > 0:
            idx.append(k)
    return idx


def _draw_axes(ax, theta: float, extent: float, koz_radius: float, koz_center_lvlh=(0.0, 0.0, 0.0)) -> None:
    ax.plot([0, extent * math.cos(theta)], [0, extent * math.sin(theta)], ":", color="0.5", lw=1, label="approach axis")
    circle = plt.Circle((koz_center_lvlh[0], koz_center_lvlh[2]), koz_radius, color="tab:red", alpha=0.2, label="KOZ")
    ax.add_patch(circle)
    ax.plot(0, 0, "k*", ms=9, label="target")
    ax.set_xlabel("V-bar x [m]")
    ax.set_ylabel("R-bar z [m] (towards Earth)")
    ax.invert_yaxis()
    ax.set_aspect("equal", adjustable="box")
    ax.grid(alpha=0.3)


def plot_trajectory(result, path: Path, *, theta_deg: float, koz_radius_m: float, koz_center_lvlh=(0.0, 0.0, 0.0),
                    free_drift_orbits: float = 1.0, title: str = "", ax=None) -> Path | None:
    """Fig. 4a/6a/9: trajectory with hop markers, free-drift horizon and KOZ."""
    n = 2 * math.pi / float(result.meta["period_s"])
    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(7, 6))
    p = _lvlh(result.x_true)
    for m, k in enumerate(_hop_impulses(result)):
        x_post = result.x_true[k].copy()
        x_post[3:6] += result.u_applied[k]
        drift = _lvlh(_free_drift(x_post, n, free_drift_orbits * 2 * math.pi / n))
        seg = len(drift) - 1
        for j in range(0, seg, 4):
            ax.plot(drift[j:j + 5, 0], drift[j:j + 5, 2], color="tab:blue", lw=1,
                    alpha=max(0.08, 0.8 * (1 - j / seg)), label="free horizon x_u" if (m == 0 and j == 0) else None)
    ax.plot(p[:, 0], p[:, 2], color="tab:red", lw=1.2, label="chaser")
    hops = _hop_impulses(result)
    ax.plot(p[hops, 0], p[hops, 2], "kx", ms=8, mew=2, label="hop impulse")
    extent = 1.1 * float(np.max(np.linalg.norm(p[:, [0, 2]], axis=1)))
    _draw_axes(ax, math.radians(theta_deg), extent, koz_radius_m, koz_center_lvlh)
    lo = np.minimum(p[:, [0, 2]].min(axis=0), -koz_radius_m)
    hi = np.maximum(p[:, [0, 2]].max(axis=0), koz_radius_m)
    pad = 0.35 * float(np.max(hi - lo))
    lo, hi = lo - pad, hi + pad
    # an approach along one axis (R-bar) would make a sliver: keep the box at least 3:4 either way
    span = hi - lo
    want = np.maximum(span, 0.75 * span[::-1])
    lo, hi = (lo + hi) / 2 - want / 2, (lo + hi) / 2 + want / 2
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, borderaxespad=0.0)  # beside the data
    ax.set_title(title or "SRF trajectory")
    if own:
        return save(fig, path)
    return None


def plot_dv(result, path: Path, title: str = "", ax=None) -> Path | None:
    """Fig. 4b/6b: impulses per LVLH axis (stems) against time in orbital periods."""
    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(8, 4))

    dv = hill_vector_to_lvlh(result.u_applied)
    t = result.t / float(result.meta["period_s"])
    k = np.nonzero(np.linalg.norm(dv, axis=1) > 0)[0]
    for axis, (name, color) in enumerate((("x (V-bar)", "tab:blue"), ("y", "tab:green"), ("z (R-bar)", "tab:orange"))):
        if k.size:
            ax.vlines(t[k] + (axis - 1) * 0.004, 0, dv[k, axis], color=color, lw=2, label=f"Δv {name}")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel("time [t_orb]")
    ax.set_ylabel("Δv [m/s]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title or "impulses per axis")
    if own:
        return save(fig, path)
    return None


def plot_mc_overlay(results: list, path: Path, *, theta_deg: float, koz_radius_m: float, title: str = "") -> Path:
    """Figs. 5/7/10: trajectories of every run and their cumulative dv."""
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    extent = 0.0
    for res in results:
        p = _lvlh(res.x_true)
        axes[0].plot(p[:, 0], p[:, 2], lw=0.7, alpha=0.6)
        extent = max(extent, float(np.max(np.linalg.norm(p[:, [0, 2]], axis=1))))
        axes[1].plot(res.t / float(res.meta["period_s"]), res.dv_cum, lw=0.8, alpha=0.7)
    _draw_axes(axes[0], math.radians(theta_deg), 1.1 * extent, koz_radius_m)
    axes[0].set_title(f"{len(results)} runs: trajectories")
    axes[1].set_xlabel("time [t_orb]")
    axes[1].set_ylabel("cumulative Δv [m/s]")
    axes[1].grid(alpha=0.3)
    axes[1].set_title("Δv usage")
    fig.suptitle(title)
    return save(fig, path)


def plot_fig8a(path: Path, angles_deg: np.ndarray, period_fraction: np.ndarray, rho: float = 0.7) -> Path:
    """Fig. 8a: orbital-period fraction of the hop against the approach angle (eq. 25 solved for phi;
    data: :func:`proxops.guidance.hop_times.fig8a_curve`, NaN where no passively safe hop exists)."""
    angles, frac = np.asarray(angles_deg, dtype=float), np.asarray(period_fraction, dtype=float)
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(angles, frac, ".", ms=3, color="tab:blue", label=f"eq. (25), rho = {rho}")
    axes_pts = (angles % 90.0 == 0.0) & ~np.isnan(frac)
    ax.plot(angles[axes_pts], frac[axes_pts], "o", color="tab:red")
    bad = np.isnan(frac)
    ax.fill_between(angles, 0, 0.55, where=bad, color="0.85", step="mid", label="no passively safe hop")
    ax.axhline(0.21, ls="--", color="0.4", lw=0.8, label="0.21 t_orb")
    ax.set_xlabel("approach angle θ [deg]")
    ax.set_ylabel("hop time / t_orb")
    ax.set_xlim(0, 360)
    ax.set_ylim(0, 0.55)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Fig. 8a: hop duration against approach angle")
    return save(fig, path)


def plot_fig8b(path: Path, hops: list, rho: float = 0.7, d0: float = 1.0) -> Path:
    """Fig. 8b: single-hop CW trajectories (velocity of eq. 24) per angle over one orbit; crosses at
    the axis crossing. ``hops``: ``(angle deg, trajectory (n, 2), crossing (2,))`` in units of d0
    (:func:`proxops.guidance.hop_times.fig8b_hops`)."""
    fig, ax = plt.subplots(figsize=(7, 7))
    for a, traj, cross in hops:
        th = math.radians(a)
        red = a % 90 == 0
        ax.plot(traj[:, 0], traj[:, 1], color="tab:red" if red else "tab:blue", lw=1.4 if red else 0.8)
        ax.plot([0, 1.2 * d0 * math.cos(th)], [0, 1.2 * d0 * math.sin(th)], ":", color="0.6", lw=0.8)
        ax.plot(cross[0], cross[1], "kx")
    ax.plot(0, 0, "k*")
    ax.set_xlabel("V-bar x [d0]")
    ax.set_ylabel("R-bar z [d0]")
    ax.invert_yaxis()
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.set_title(f"Fig. 8b: single hops closing {100 * (1 - rho):.0f} % (CW, one orbit)")
    return save(fig, path)


def plot_cbf_comparison(no_cbf, with_cbf, path: Path, *, theta_deg: float, koz_radius_m: float,
                        free_drift_orbits: float = 2.0) -> Path:
    """Fig. 11: the same V-bar 0.6 t_orb case without and with the CBF (29j)."""
    fig, axes = plt.subplots(1, 2, figsize=(13, 6))
    plot_trajectory(no_cbf, None, theta_deg=theta_deg, koz_radius_m=koz_radius_m, free_drift_orbits=free_drift_orbits,
                    title="No CBF", ax=axes[0])
    plot_trajectory(with_cbf, None, theta_deg=theta_deg, koz_radius_m=koz_radius_m,
                    free_drift_orbits=free_drift_orbits, title="CBF (29j)", ax=axes[1])
    for ax in axes:
        ax.set_xlim(-200, 800)
        ax.set_ylim(250, -250)
    return save(fig, path)


def scenario_figures(sc, results: dict, out_dir: Path) -> list[Path]:
    """The figures of one ``proxops run`` of an srf scenario."""
    out_dir = Path(out_dir)
    theta = sc.approach.angle_deg
    r = sc.keep_out.radius_m
    # the keep-out centre the run used (Hill, as proxops.systems.srf.keep_out_hill builds it), drawn in LVLH
    center = tuple(hill_vector_to_lvlh(np.asarray(lvlh_vector_to_hill(np.array(sc.keep_out.center_m)), dtype=float)))
    paths = []
    if "no_cbf" in results:
        paths.append(plot_cbf_comparison(results["no_cbf"], results["cbf"], out_dir / "fig11_cbf.png",
                                         theta_deg=theta, koz_radius_m=r,
                                         free_drift_orbits=sc.keep_out.free_drift_orbits))
    for label, res in results.items():
        paths.append(plot_trajectory(res, out_dir / f"trajectory_{label}.png", theta_deg=theta, koz_radius_m=r,
                                     koz_center_lvlh=center, free_drift_orbits=sc.keep_out.free_drift_orbits,
                                     title=f"{sc.name} ({label})"))
        paths.append(plot_dv(res, out_dir / f"dv_{label}.png", title=f"{sc.name} ({label}): Δv per axis"))
    return paths


run_figures = scenario_figures


def mc_figures(sc, results: list, out_dir: Path) -> list[Path]:
    """Monte Carlo overlay (Figs. 5/7/10) from a campaign's saved series."""
    return [plot_mc_overlay(results, Path(out_dir) / "srf_mc_overlay.png", theta_deg=sc.approach.angle_deg,
                            koz_radius_m=sc.keep_out.radius_m, title=f"{sc.name}: Monte Carlo")]
