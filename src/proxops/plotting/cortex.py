"""CORTEX reference figures (Wijayatunga et al. Figs. 11-12): trajectories of both phases
around the keep-out sphere and the approach cone, and the histograms of compute time, TOF and delta-v."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from proxops.plotting.common import Drawing, draw_all, plt, save
from proxops.plotting.cortex_loop import campaign_figures, run_figure, table_figures


def _sphere(ax, radius: float, **kw) -> None:
    u, v = np.mgrid[0 : 2 * np.pi : 24j, 0 : np.pi : 12j]
    ax.plot_wireframe(radius * np.cos(u) * np.sin(v), radius * np.sin(u) * np.sin(v), radius * np.cos(v),
                      linewidth=0.3, **kw)


def _cone(ax, axis, half_angle: float, length: float, **kw) -> None:
    e = np.asarray(axis, float) / np.linalg.norm(axis)
    a = np.cross(e, [1.0, 0, 0]) if abs(e[0]) < 0.9 else np.cross(e, [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(e, a)
    phi = np.linspace(0, 2 * np.pi, 25)
    for s in (0.5 * length, length):
        rim = s * (e[None, :] + math.tan(half_angle) * (np.cos(phi)[:, None] * a + np.sin(phi)[:, None] * b))
        ax.plot(rim[:, 0], rim[:, 1], rim[:, 2], lw=0.5, **kw)
    for p in phi[::6]:
        tip = length * (e + math.tan(half_angle) * (np.cos(p) * a + np.sin(p) * b))
        ax.plot([0, tip[0]], [0, tip[1]], [0, tip[2]], lw=0.5, **kw)


def _label(ax) -> None:
    ax.set_xlabel("x radial [m]")
    ax.set_ylabel("y along-track [m]")
    ax.set_zlabel("z normal [m]")


def _geometry(sc):
    g, m = sc.geometry, sc.margins
    return g.r_kos_m * m.kos, math.radians(g.cone_half_angle_deg) * m.cone


def plan_figure(sc, plan, path: Path) -> Path:
    """3-D view of one plan: fly-around (blue) around the inflated KOS, final approach (red) in the cone."""
    traj = plan.trajectory()
    return _plan_figure(sc, traj["x"], traj["phase"], plan.axis, path,
                        f"tau1 {plan.tau1_s:.0f} s, tau2 {plan.tau2_s:.0f} s, dv {plan.dv_total_mps:.3f} m/s")


def plan_figure_from_result(sc, result, path: Path) -> Path:
    """:func:`plan_figure` of a plan stored as a SimResult (its docking axis in ``meta["axis"]``)."""
    return _plan_figure(sc, result.x_true, result.mode, np.asarray(result.meta["axis"], dtype=float), path, sc.name)


def _plan_figure(sc, x, phase, axis, path, title) -> Path:
    rho, alpha_c = _geometry(sc)
    phase = np.asarray(phase)
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    _sphere(ax, rho, color="0.6")
    _cone(ax, axis, alpha_c, rho, color="g")
    fly = phase != "approach"
    ax.plot(x[fly, 0], x[fly, 1], x[fly, 2], "b.-", lw=1, ms=3, label="fly-around (CP1)")
    ax.plot(x[~fly, 0], x[~fly, 1], x[~fly, 2], "r.-", lw=1, ms=3, label="final approach (CP2)")
    ax.plot(*x[0, :3], "go", label="start")
    _label(ax)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    return save(fig, path)


def fig11_trajectories(sc, results, path: Path) -> Path:
    """Fig. 11: (a) fly-around references around the inflated KOS, (b) final approaches with their cones.
    Each panel's trajectories are one line collection (the colours of the axes' colour cycle in plan order,
    as one line per plan would get them; ~2.5x cheaper to build and draw than 100 lines per panel)."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    rho, _ = _geometry(sc)
    fig = plt.figure(figsize=(13, 6))
    ax1 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2, projection="3d")
    _sphere(ax1, rho, color="r")
    cycle = plt.rcParams["axes.prop_cycle"].by_key().get("color") or ["C0"]
    for ax, approach in ((ax1, False), (ax2, True)):
        segs, colors = [], []
        for i, res in enumerate(results):
            x = np.asarray(res.x_true, float)
            keep = (np.asarray(res.mode) == "approach") == approach
            if keep.any():
                segs.append(x[keep, :3])
                colors.append(cycle[i % len(cycle)])
        if segs:
            ax.add_collection3d(Line3DCollection(segs, colors=colors, linewidths=0.7))
    for ax, title in ((ax1, f"(a) fly-around, {len(results)} axes, KOS r = {rho:.0f} m"), (ax2, "(b) final approach")):
        _label(ax)
        ax.set_title(title, fontsize=10)
    # fixed margins (every label inside the canvas: tested) instead of the tight crop, which draws the
    # figure twice (measured 0.66 -> 0.43 s for Figs. 11 and 12 of 100 plans)
    fig.subplots_adjust(left=0.0, right=0.96, bottom=0.02, top=0.93, wspace=0.08)
    return save(fig, path, tight=False)


def fig12_histograms(table, path: Path, paper: dict) -> Path:
    """Fig. 12: histograms of compute time, TOF (tau_1 + tau_2) and delta-v of the successful plans;
    ``paper``: the §5.1.1 medians (:data:`proxops.systems.cortex.PAPER_5_1_1`)."""
    ok = table[table["success"].astype(bool)] if "success" in table else table
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    items = (("metric.plan_wall_time_s", 1.0, "compute time per plan [s]", "compute_median_s"),
             ("metric.tof_s", 1 / 60, "TOF tau_1 + tau_2 [min]", "tof_median_min"),
             ("metric.dv_total_mps", 1.0, "delta-v [m/s]", "dv_median_mps"))
    for ax, (col, scale, label, key) in zip(axes, items):
        v = ok[col].astype(float).to_numpy() * scale
        ax.hist(v, bins=20, color="C0", alpha=0.8, histtype="stepfilled")  # one polygon, not 20 bars: same look
        ax.axvline(np.median(v), color="k", lw=1.2, label=f"median {np.median(v):.3g}")
        if key != "compute_median_s":
            ax.axvline(paper[key], color="r", ls="--", lw=1.2, label=f"paper {paper[key]:g}")
        else:
            ax.set_title(f"paper median {paper[key]:g} s (off scale)", fontsize=9)
        ax.set_xlabel(label)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("plans")
    fig.subplots_adjust(left=0.05, right=0.99, bottom=0.13, top=0.92, wspace=0.2)  # fixed margins (see Fig. 11)
    return save(fig, path, tight=False)


def references_figures(camp, sc, paper: dict, out: Path) -> list[Path]:
    """Figs. 11-12 of a ``proxops cortex references`` campaign (``camp``: its loaded
    :class:`proxops.analysis.campaign.CampaignResult`, ``sc`` its scenario, ``paper`` the §5.1.1
    medians) into the folder ``out``."""
    table = camp.table
    results = plan_traces(table[table["success"].astype(bool)])
    for rid in ([] if results else table[table["success"].astype(bool)]["run_id"].tolist()):  # older campaigns
        try:
            results.append(camp.series(int(rid)))
        except Exception:  # a campaign without series: Fig. 12 only
            break
    fig12 = Drawing(fig12_histograms, Path(out) / "fig12_histograms.png", table, paper=paper)
    if not results:
        return [fig12()]
    return draw_all([Drawing(fig11_trajectories, Path(out) / "fig11_trajectories.png", sc, results), fig12])


def plan_traces(table) -> list:
    """The plans' node positions from the campaign rows (``metric.trace.*`` of
    :func:`proxops.systems.cortex.plan_trace`) as objects with ``x_true`` (n, 3) and ``mode`` (flyaround /
    approach) for :func:`fig11_trajectories`; [] when the table has no traces (then saved series are read)."""
    import json
    from types import SimpleNamespace

    if "metric.trace.x" not in table or "metric.trace.approach_from" not in table:
        return []
    out = []
    for xs, ys, zs, k in zip(table["metric.trace.x"], table["metric.trace.y"], table["metric.trace.z"],
                             table["metric.trace.approach_from"]):
        try:
            x = np.column_stack([json.loads(xs), json.loads(ys), json.loads(zs)]).astype(float)
            k = int(k)
        except (TypeError, ValueError):
            continue
        out.append(SimpleNamespace(x_true=x, mode=["flyaround"] * k + ["approach"] * (len(x) - k)))
    return out


def run_figures(sc, results, out_dir: Path) -> list[Path]:
    """``proxops run --out`` figure: the planned reference in 3-D (closed loop: trajectory and tracking error)."""
    if sc.guidance.closed_loop:
        return [run_figure(sc, next(iter(results.values())), Path(out_dir) / "tracking.png")]
    result = next(iter(results.values())) if isinstance(results, dict) else results
    return [plan_figure_from_result(sc, result, Path(out_dir) / "reference_3d.png")]


def mc_figures(sc, results, out_dir: Path) -> list[Path]:
    """Campaign figure: Fig. 11 trajectories (closed loop: Figs. 13/14 and 15)."""
    if sc.guidance.closed_loop:
        return campaign_figures(sc, results, Path(out_dir))
    return [fig11_trajectories(sc, results, Path(out_dir) / "fig11_trajectories.png")]


def mc_table_figures(sc, table, out_dir: Path) -> list[Path]:
    """Closed loop: Figs. 13/14 and 15 from the campaign table (no saved series needed)."""
    if sc.guidance.closed_loop:
        return table_figures(sc, table, out_dir)
    return []
