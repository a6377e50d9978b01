"""Figures of a Monte Carlo campaign: Δv distributions, metric histograms, outcome maps over
parameter grids (or over the dispersed values) and trajectory overlays from saved series."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pandas as pd

from proxops.plotting.common import plt, save
from proxops.scenarios.loader import unit_of_metric

OUTCOME_COLORS = {"success": "tab:green", "failure": "tab:red", "error": "black"}
METRIC = "metric."


def _label(col: str) -> str:
    return col.removeprefix("disp.").removeprefix(METRIC)


def _short(col: str) -> str:
    """Last part of a key path: "disp.target.tumble_rate_deg_s" -> "tumble_rate_deg_s"."""
    return _label(col).split(".")[-1]


def axis_label(col: str) -> str:
    """A dispersed key as an axis label: ``disp.initial.position_m[0]`` -> ``initial position [0] [m]``."""
    key = _label(col)
    unit = unit_of_metric(key)
    section, _, name = key.rpartition(".")
    base, bracket, index = name.partition("[")
    for suffix in ("_deg_s", "_mps2", "_mps", "_deg", "_km", "_kg", "_m", "_s", "_N"):
        if base.endswith(suffix):
            base = base[: -len(suffix)]
            break
    text = " ".join(part for part in (section.replace(".", " "), base.replace("_", " ")) if part)
    if bracket:
        text += f" [{index}"
    return f"{text} [{unit}]" if unit else text


def plot_dv_distribution(table: pd.DataFrame, path: Path, metric: str = "metric.total_dv_mps") -> Path | None:
    """Histogram (by outcome) and empirical CDF of a campaign's total Δv."""
    if metric not in table or table[metric].dropna().empty:
        return None
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    data = table[[metric, "outcome"]].dropna()
    bins = np.histogram_bin_edges(data[metric], bins=min(40, max(5, int(math.sqrt(len(data))) * 2)))
    for outcome, grp in data.groupby("outcome"):
        ax1.hist(grp[metric], bins=bins, alpha=0.7, label=f"{outcome} ({len(grp)})", color=OUTCOME_COLORS.get(outcome))
    ax1.set_xlabel("total Δv [m/s]")
    ax1.set_ylabel("runs")
    ax1.legend(fontsize=8)
    v = np.sort(data[metric].to_numpy())
    ax2.step(v, np.arange(1, v.size + 1) / v.size, where="post")
    for q, ls in ((0.5, "--"), (0.99, ":")):
        ax2.axvline(np.quantile(v, q), color="gray", ls=ls, label=f"Q{int(q * 100)} = {np.quantile(v, q):.4g}")
    ax2.set_xlabel("total Δv [m/s]")
    ax2.set_ylabel("fraction of runs")
    ax2.legend(fontsize=8)
    for a in (ax1, ax2):
        a.grid(alpha=0.3)
    fig.suptitle(f"Δv distribution over {len(data)} runs")
    return save(fig, path)


def plot_metric_histograms(table: pd.DataFrame, path: Path, metrics: list[str]) -> Path | None:
    """One histogram per metric of ``metrics`` (up to 12; the report passes the informative ones in
    reading order, :func:`proxops.analysis.metric_order.ordered_metrics`: total Δv first, no timings)."""
    cols = list(metrics)[:12]
    if not cols:
        return None
    ncol = min(3, len(cols))
    nrow = math.ceil(len(cols) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.2 * nrow), squeeze=False)
    for ax, col in zip(axes.flat, cols):
        vals = table[col].dropna().to_numpy(dtype=float)
        ax.hist(vals, bins=min(40, max(5, int(math.sqrt(vals.size)) * 2)), color="tab:blue", alpha=0.8)
        ax.set_title(_label(col), fontsize=9)
        unit = unit_of_metric(col)
        ax.set_xlabel(f"{_short(col)} [{unit}]" if unit else _short(col), fontsize=8)
        ax.set_ylabel("runs", fontsize=8)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(cols):]:
        ax.set_visible(False)
    fig.tight_layout()
    return save(fig, path)


def _varying(table: pd.DataFrame, cols: list[str]) -> list[str]:
    return [c for c in cols if c in table and pd.api.types.is_numeric_dtype(table[c]) and table[c].nunique(dropna=True) > 1]


def outcome_map_axes(table: pd.DataFrame, manifest: dict) -> tuple[str | None, str | None, list[str]]:
    """(x, y, facet columns) of the outcome map: the last gridded vector's two varying
    components or the last two gridded scalars; the other grid axes become facets. With a
    single gridded parameter: one panel per value, runs placed by their first two dispersed
    values. Without grids: the first two varying dispersed columns, no facets."""
    grid_axes = [list(a) for a in manifest.get("grid_axes", [])]
    if grid_axes:
        varying_axes = []
        for axis in grid_axes:
            cols = _varying(table, axis)
            if len({c.split("[")[0] for c in cols}) > 1:  # a group of keys varying together: one column stands for it
                cols = cols[:1]
            if cols:
                varying_axes.append(cols)
        grid_cols = {c for axis in grid_axes for c in axis}
        random_cols = _varying(table, [c for c in manifest.get("dispersion_columns", []) if c not in grid_cols])
        if len(varying_axes) == 1 and len(varying_axes[0]) == 1 and len(random_cols) >= 2:
            # one gridded parameter: a panel per grid value, runs placed by their dispersed values
            return random_cols[0], random_cols[1], varying_axes[0]
        vector = [a for a in varying_axes if len(a) >= 2]
        if vector:
            xy_axis = vector[-1]
            x, y = xy_axis[0], xy_axis[1]
            facets = [c for a in varying_axes if a is not xy_axis for c in a]
        else:
            flat = [a[0] for a in varying_axes]
            x = flat[-2] if len(flat) >= 2 else (flat[-1] if flat else None)
            y = flat[-1] if len(flat) >= 2 else None
            facets = flat[:-2]
        return x, y, facets
    disp = _varying(table, [c for c in manifest.get("dispersion_columns", []) if c in table])
    return (disp[0] if disp else None), (disp[1] if len(disp) > 1 else None), []


def plot_outcome_map(table: pd.DataFrame, manifest: dict, path: Path, max_facets: int = 20) -> Path | None:
    """Success fraction per parameter point (green = all runs succeeded, red = none); with
    more than two grid axes, one panel per combination of the other axes (e.g. the
    tumble rate x thrust authority panels of Iskender 2026 §9)."""
    x, y, facets = outcome_map_axes(table, manifest)
    if x is None:
        return None
    data = table.copy()
    data["success_f"] = data["success"].astype(float)
    if y is None:
        data["_zero"] = 0.0
        y = "_zero"
    combos = [()] if not facets else list(itertools.islice(
        data[facets].drop_duplicates().sort_values(facets).itertuples(index=False, name=None), max_facets))
    ncol = min(4, len(combos))
    nrow = math.ceil(len(combos) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.6 * nrow), squeeze=False)
    sc = None
    for ax, combo in zip(axes.flat, combos):
        sub = data
        title = ""
        if facets:
            key = combo
            mask = np.ones(len(data), bool)
            for col, val in zip(facets, key):
                mask &= (data[col] == val).to_numpy()
            sub = data[mask]
            title = "\n".join(f"{_short(c)} = {v:g}" if isinstance(v, (int, float)) else f"{_short(c)} = {v}"
                               for c, v in zip(facets, key))
        pts = sub.groupby([x, y], sort=False)["success_f"].agg(["mean", "size"]).reset_index()
        sc = ax.scatter(pts[x], pts[y], c=pts["mean"], cmap="RdYlGn", vmin=0.0, vmax=1.0,
                        s=max(8, 400 / max(1, math.sqrt(len(pts)))), edgecolors="none")
        ax.set_xlabel(axis_label(x), fontsize=8)
        ax.set_ylabel("" if y == "_zero" else axis_label(y), fontsize=8)
        ax.set_title(title, fontsize=8)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(combos):]:
        ax.set_visible(False)
    if sc is not None:
        fig.colorbar(sc, ax=axes.ravel().tolist(), label="success fraction", shrink=0.8)
    fig.suptitle(f"outcome map ({len(table)} runs)", y=1.0 + (0.06 if facets else 0.0) / nrow)
    return save(fig, path)


def plot_trajectory_overlay(series: list[tuple[object, str]], path: Path, title: str = "") -> Path | None:
    """Along-track vs radial trajectories of many runs ``[(SimResult, outcome), ...]``, and range vs time."""
    if not series:
        return None
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    seen = set()
    for res, outcome in series:
        pos = res.position
        color = OUTCOME_COLORS.get(outcome, "tab:blue")
        label = outcome if outcome not in seen else None
        seen.add(outcome)
        if pos.shape[1] >= 2:
            ax1.plot(pos[:, 1], pos[:, 0], lw=0.6, alpha=0.5, color=color, label=label)
        ax2.plot(res.t, res.range_m, lw=0.6, alpha=0.5, color=color)
    ax1.plot(0, 0, "k*", ms=10)
    ax1.set_xlabel("along-track y [m]")
    ax1.set_ylabel("radial x [m]")
    ax1.legend(fontsize=8)
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("range [m]")
    for a in (ax1, ax2):
        a.grid(alpha=0.3)
    fig.suptitle(title or f"{len(series)} trajectories")
    return save(fig, path)
