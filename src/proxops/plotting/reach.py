"""Figures of the safe-start analysis (Iskender 2026 Figs. 1-3, §8.4, §11.2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.colors import ListedColormap

from proxops.plotting.common import plt, save

NOMINAL_COLOR = "#2ca02c"  # green
STOCH_COLOR = "#1f77b4"  # blue
ROBUST_COLOR = "#7b3294"  # purple
MC_COLOR = "#d9d9d9"  # light grey
LAYER_CMAP = ListedColormap(["white", MC_COLOR, NOMINAL_COLOR, STOCH_COLOR, ROBUST_COLOR])


def _layers(grid, *masks) -> np.ndarray:
    """Image with value k+1 where the k-th (nested, outermost first) mask holds, NaN outside the corridor."""
    img = np.zeros(grid.points.shape[0])
    for k, m in enumerate(masks):
        if m is not None:
            img[m] = k + 1
    img[~grid.inside] = np.nan
    return img.reshape(grid.shape)


def _corridor(ax, grid, half_angle_rad=np.radians(30.0)):
    y = np.array([0.0, grid.y_m[-1]])
    t = np.tan(half_angle_rad)
    ax.plot(t * y, y, "k-", lw=0.6)
    ax.plot(-t * y, y, "k-", lw=0.6)


def _show(ax, grid, img, vmax=4):
    extent = (grid.x_m[0], grid.x_m[-1], grid.y_m[0], grid.y_m[-1])
    ax.imshow(img, origin="lower", extent=extent, cmap=LAYER_CMAP, vmin=0, vmax=vmax, interpolation="nearest",
              aspect="equal")
    _corridor(ax, grid)


def hierarchy_figure(results, grid, path: Path) -> Path:
    """Fig. 1: nominal ⊇ stochastic ⊇ robust for every (w_t, a_max), backward kernel outlined."""
    omegas = sorted({r.omega_deg_s for r in results})
    amaxs = sorted({r.a_max_mps2 for r in results}, reverse=True)
    fig, axes = plt.subplots(len(omegas), len(amaxs), figsize=(3.0 * len(amaxs), 2.9 * len(omegas)), squeeze=False)
    for r in results:
        ax = axes[omegas.index(r.omega_deg_s)][amaxs.index(r.a_max_mps2)]
        _show(ax, grid, _layers(grid, None, r.nominal, r.stochastic, r.robust))
        if r.backward is not None:
            ax.contour(grid.x_m, grid.y_m, r.backward.reshape(grid.shape).astype(float), levels=[0.5], colors="k",
                       linewidths=0.8, linestyles="--")
        ax.set_title(f"{r.omega_deg_s:g} deg/s, {r.a_max_mps2:g} m/s²\nnom {r.pct['nominal']:.1f}%"
                     f"  rob {r.pct['robust']:.1f}%", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("x_B [m]", fontsize=8)
    for row in axes:
        row[0].set_ylabel("y_B [m]", fontsize=8)
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in (NOMINAL_COLOR, STOCH_COLOR, ROBUST_COLOR)]
    handles.append(plt.Line2D([0], [0], color="k", ls="--"))
    fig.legend(handles, ["nominal", "stochastic", "robust", "backward kernel (N=20)"], loc="lower center", ncol=4)
    fig.suptitle("Nested feasibility hierarchy (Fig. 1)")
    fig.tight_layout(rect=(0, 0.03, 1, 0.97))
    return save(fig, path)


def mc_sweep_figure(outcomes, path: Path, half_angle_rad=np.radians(30.0)) -> Path:
    """Fig. 2: the 195 ICs of every combination, green feasible / red infeasible."""
    omegas = sorted(outcomes["omega_deg_s"].unique())
    amaxs = sorted(outcomes["a_max_mps2"].unique(), reverse=True)
    fig, axes = plt.subplots(len(omegas), len(amaxs), figsize=(3.0 * len(amaxs), 2.9 * len(omegas)), squeeze=False)
    y_top = float(outcomes["y_m"].max()) * 1.05
    t = np.tan(half_angle_rad)
    for i, w in enumerate(omegas):
        for j, a in enumerate(amaxs):
            ax = axes[i][j]
            sel = outcomes[(outcomes["omega_deg_s"] == w) & (outcomes["a_max_mps2"] == a)]
            ok = sel["feasible"].to_numpy(bool)
            ax.scatter(sel["x_m"][ok], sel["y_m"][ok], s=6, c="tab:green")
            ax.scatter(sel["x_m"][~ok], sel["y_m"][~ok], s=6, c="tab:red")
            ax.plot([0, t * y_top], [0, y_top], "k-", lw=0.6)
            ax.plot([0, -t * y_top], [0, y_top], "k-", lw=0.6)
            # y given: the title sits at the top of the axes (where matplotlib puts it when nothing is
            # above the axes) without measuring the tick labels to check (0.4 s for 20 panels)
            ax.set_title(f"{w:g} deg/s, {a:g} m/s²: {100 * ok.mean():.0f}% feasible", fontsize=8, y=1.0)
            ax.set_aspect("equal")
            ax.tick_params(labelsize=7)
    fig.suptitle("Monte Carlo feasibility sweep, 195 ICs per combination (Fig. 2)")
    # fixed margins instead of tight_layout + bbox_inches="tight": both measure every tick label
    # (2.2 of the 2.5 s this figure took); the grid of equal panels needs no measuring
    fig.subplots_adjust(left=0.04, right=0.99, bottom=0.025, top=0.95, wspace=0.22, hspace=0.28)
    return save(fig, path, tight=False)


def overlay_figure(result, fmap, grid, path: Path) -> Path:
    """Fig. 3: MC (interpolated) ⊇ nominal ⊇ stochastic ⊇ robust for one combination."""
    fig, ax = plt.subplots(figsize=(6, 6))
    _show(ax, grid, _layers(grid, fmap.mask, result.nominal, result.stochastic, result.robust))
    mc = np.where(grid.inside, fmap.mask, False).reshape(grid.shape).astype(float)
    ax.contour(grid.x_m, grid.y_m, mc, levels=[0.5], colors="k", linewidths=1.2)
    ok = fmap.feasible
    ax.scatter(fmap.sites[ok, 0], fmap.sites[ok, 1], s=8, c="tab:green", edgecolors="k", linewidths=0.3,
               label="MC feasible IC")
    ax.scatter(fmap.sites[~ok, 0], fmap.sites[~ok, 1], s=8, c="tab:red", edgecolors="k", linewidths=0.3,
               label="MC infeasible IC")
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in (MC_COLOR, NOMINAL_COLOR, STOCH_COLOR, ROBUST_COLOR)]
    handles.append(plt.Line2D([0], [0], color="k"))
    ax.legend(handles + ax.get_legend_handles_labels()[0],
              ["MC (natural neighbour)", "nominal", "stochastic", "robust", "MC boundary"]
              + ax.get_legend_handles_labels()[1],
              loc="upper left", fontsize=8)
    ax.set_xlabel("x_B [m]")
    ax.set_ylabel("y_B [m]")
    ax.set_title(f"Overlay {result.omega_deg_s:g} deg/s, {result.a_max_mps2:g} m/s² (Fig. 3)")
    return save(fig, path)


def combo_map_figure(result, grid, path: Path, fmap=None) -> Path:
    """One combination: the certified layers (and the MC map when given), backward kernel dashed."""
    if fmap is not None:
        return overlay_figure(result, fmap, grid, path)
    fig, ax = plt.subplots(figsize=(6, 6))
    _show(ax, grid, _layers(grid, None, result.nominal, result.stochastic, result.robust))
    if result.backward is not None:
        ax.contour(grid.x_m, grid.y_m, result.backward.reshape(grid.shape).astype(float), levels=[0.5], colors="k",
                   linewidths=1.0, linestyles="--")
    ax.set_xlabel("x_B [m]")
    ax.set_ylabel("y_B [m]")
    ax.set_title(f"Safe starts at {result.omega_deg_s:g} deg/s, {result.a_max_mps2:g} m/s²", fontsize=10)
    region_legend(ax, result.pct, backward=result.backward is not None)
    return save(fig, path)


def region_legend(ax, pct: dict, backward: bool = False):
    """Legend of the four regions of a safe-start map inside the corridor (nested: robust ⊆ stochastic
    ⊆ nominal; percentages of the corridor area are of each whole set), plus the outlines."""
    def share(key):
        return f" {pct[key]:.1f} %" if key in pct else ""

    handles = [plt.Rectangle((0, 0), 1, 1, fc=c, ec="k", lw=0.5)
               for c in (ROBUST_COLOR, STOCH_COLOR, NOMINAL_COLOR, "white")]
    labels = [f"robust{share('robust')}", f"stochastic{share('stochastic')} (adds to robust)",
              f"nominal{share('nominal')} (adds to stochastic)", "not certified"]
    handles.append(plt.Line2D([0], [0], color="k", lw=0.6))
    labels.append("LOS corridor")
    if backward:
        handles.append(plt.Line2D([0], [0], color="k", ls="--"))
        labels.append(f"backward kernel{share('backward')}")
    return ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8,
                     title="% of the corridor area", title_fontsize=8, frameon=False)


def double_integrator_figure(polygons: dict, path: Path, case=None) -> Path:
    """§8.4: nominal (green) ⊇ stochastic (blue) ⊇ robust (purple) backward-reachable sets."""
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for kind, color in (("nominal", NOMINAL_COLOR), ("stochastic", STOCH_COLOR), ("robust", ROBUST_COLOR)):
        v = polygons[kind].ordered_vertices()
        if len(v) >= 3:
            ax.fill(v[:, 0], v[:, 1], fc=color, alpha=1.0, label=kind, lw=1.0, ec="k")
    if case is not None:
        x1, x2, tw = case.x1_max, case.x2_max, case.target_half_width
        ax.plot([-x1, x1, x1, -x1, -x1], [-x2, -x2, x2, x2, -x2], "k-", lw=0.8, label="state constraints")
        ax.plot([-tw, tw, tw, -tw, -tw], [-tw, -tw, tw, tw, -tw], "r--", lw=1.0, label="target set")
    ax.set_xlabel("x1 (position)")
    ax.set_ylabel("x2 (velocity)")
    ax.set_title("Double integrator: N-step backward reachable sets (§8.4)")
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)
    return save(fig, path)


def scaling_figure(results, path: Path) -> Path:
    """§11.2: safe fractions against a_max / w_t^2 (all combinations collapse onto one curve)."""
    ratio = np.array([r.a_max_mps2 / np.radians(r.omega_deg_s) ** 2 for r in results])
    fig, ax = plt.subplots(figsize=(6, 4))
    for key, color, marker in (("nominal", NOMINAL_COLOR, "o"), ("stochastic", STOCH_COLOR, "s"),
                               ("robust", ROBUST_COLOR, "^"), ("backward", "k", "x")):
        vals = [r.pct.get(key) for r in results]
        if any(v is None for v in vals):
            continue
        ax.semilogx(ratio, vals, marker, color=color, label=key, ms=5, mfc="none" if key != "backward" else None)
    ax.set_xlabel("a_max / ω_t² [m]")
    ax.set_ylabel("safe fraction of the corridor [%]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title("Universal scaling parameter (§11.2)")
    return save(fig, path)
