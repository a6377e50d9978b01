"""Campaign statistics: per-metric mean, std, quartiles and P99 (the layout of
Wijayatunga et al. Table 4), success / failure / violation counts.

Conventions: ``std`` is the sample standard deviation (ddof = 1; 0 for one run);
quantiles use numpy's default linear interpolation. Statistics are taken over the runs
that did not raise (``outcome != "error"``) unless ``subset="success"``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from proxops.analysis.formatting import format_number
from proxops.scenarios.loader import unit_of_metric

from proxops.analysis.campaign_worker import DISP_PREFIX, METRIC_PREFIX  # noqa: E402,F401 (one home)
STAT_COLUMNS = ("n", "mean", "std", "q1", "median", "q3", "p99", "min", "max")


def metric_columns(table: pd.DataFrame) -> list[str]:
    """Numeric metric columns of a campaign table (booleans excluded)."""
    out = []
    for col in table.columns:
        if not col.startswith(METRIC_PREFIX):
            continue
        s = table[col]
        if pd.api.types.is_numeric_dtype(s) and not pd.api.types.is_bool_dtype(s):
            out.append(col)
    return out


def describe(values) -> dict:
    """``{n, mean, std, q1, median, q3, p99, min, max}`` of finite values (NaN when empty)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"n": 0, **{k: math.nan for k in STAT_COLUMNS[1:]}}
    q1, q2, q3, p99 = np.percentile(v, [25, 50, 75, 99])
    return {
        "n": int(v.size),
        "mean": float(v.mean()),
        "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
        "q1": float(q1),
        "median": float(q2),
        "q3": float(q3),
        "p99": float(p99),
        "min": float(v.min()),
        "max": float(v.max()),
    }


def metric_statistics(table: pd.DataFrame, metrics: list[str] | None = None, subset: str = "completed",
                      by: str | list[str] | None = None) -> pd.DataFrame:
    """One row per metric (index = metric name without the ``metric.`` prefix).

    ``subset``: ``"completed"`` (every run that did not raise) or ``"success"``.
    ``by``: group by these columns first (e.g. a grid axis); the result then has a
    MultiIndex (group..., metric)."""
    if subset not in ("completed", "success", "all"):
        raise ValueError(f"subset = {subset!r}: allowed completed, success, all")
    rows = table
    if "outcome" in table and subset != "all":
        rows = table[table["outcome"] != "error"] if subset == "completed" else table[table["outcome"] == "success"]
    metrics = metric_columns(table) if metrics is None else [m if m.startswith(METRIC_PREFIX) else METRIC_PREFIX + m for m in metrics]
    if by is None:
        stats = {m[len(METRIC_PREFIX):]: describe(rows[m]) if m in rows else describe([]) for m in metrics}
        return pd.DataFrame.from_dict(stats, orient="index", columns=list(STAT_COLUMNS))
    parts = []
    for key, group in rows.groupby(by, sort=True):
        st = metric_statistics(group, metrics, subset="all")
        keys = key if isinstance(key, tuple) else (key,)
        st.index = pd.MultiIndex.from_tuples([(*keys, m) for m in st.index])
        parts.append(st)
    return pd.concat(parts) if parts else pd.DataFrame(columns=list(STAT_COLUMNS))


def outcome_counts(table: pd.DataFrame) -> dict:
    """``runs, succeeded, failed, errors, with_violations`` and violation runs per constraint.

    ``failed`` counts every run that did not succeed (``errors`` of them raised)."""
    n = int(len(table))
    if n == 0:
        return {"runs": 0, "succeeded": 0, "failed": 0, "errors": 0, "with_violations": 0, "violations_by_constraint": {}}
    outcome = table["outcome"]
    succeeded = int((outcome == "success").sum())
    errors = int((outcome == "error").sum())
    by_con: dict[str, int] = {}
    any_violation = np.zeros(n, dtype=bool)
    for col in table.columns:
        if col.startswith(METRIC_PREFIX + "max_violation."):
            hit = table[col].fillna(0.0).to_numpy(dtype=float) > 0.0
            by_con[col[len(METRIC_PREFIX + "max_violation."):]] = int(hit.sum())
            any_violation |= hit
    ev = METRIC_PREFIX + "events.violation"
    if ev in table:
        any_violation |= table[ev].fillna(0).to_numpy(dtype=float) > 0
    return {
        "runs": n,
        "succeeded": succeeded,
        "failed": n - succeeded,
        "errors": errors,
        "with_violations": int(any_violation.sum()),
        "violations_by_constraint": by_con,
    }


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (95 % for the default z): the interval a
    success rate of ``successes`` out of ``n`` runs is quoted with (E. B. Wilson, JASA 22 (1927)
    209-212). Unlike the normal approximation it stays inside [0, 1] and is not empty at 0 or n."""
    if n <= 0:
        return (math.nan, math.nan)
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def statistics_dict(stats: pd.DataFrame) -> dict:
    """``{metric: {n, mean, std, q1, median, q3, p99, min, max}}`` for JSON (NaN -> None)."""
    out = {}
    for metric, row in stats.iterrows():
        out[str(metric)] = {k: (None if isinstance(v, float) and not math.isfinite(v) else (int(v) if k == "n" else float(v)))
                            for k, v in row.items()}
    return out


def format_table4(stats: pd.DataFrame, digits: int | None = None) -> str:
    """Markdown table in the layout of Wijayatunga et al. Table 4:
    ``| metric | unit | n | mu | sigma | [Q1, Q2, Q3, P99] |``, each value rounded to the
    resolution of the metric's unit (:func:`proxops.analysis.formatting.format_number`; m to
    1 mm, m/s to 0.1 mm/s, ...). statistics.csv and summary.json keep full precision."""
    lines = ["| metric | unit | n | μ | σ | [Q1, Q2, Q3, P99] |", "| --- | --- | --- | --- | --- | --- |"]
    for metric, r in stats.iterrows():
        unit = unit_of_metric(metric)
        f = _formatter(unit)
        lines.append(
            f"| {metric} | {unit or '-'} | {int(r['n'])} | {f(r['mean'])} | {f(r['std'])} | "
            f"[{f(r['q1'])}, {f(r['median'])}, {f(r['q3'])}, {f(r['p99'])}] |"
        )
    return "\n".join(lines)


def format_text_table(stats: pd.DataFrame, digits: int | None = None) -> str:
    """Fixed-width text version of :func:`format_table4` for the terminal."""
    rows = []
    for m, r in stats.iterrows():
        unit = unit_of_metric(m)
        f = _formatter(unit)
        rows.append((str(m), unit or "-", f(r["mean"]), f(r["std"]),
                     f"[{f(r['q1'])}, {f(r['median'])}, {f(r['q3'])}, {f(r['p99'])}]"))
    head = ("metric", "unit", "mean", "std", "[Q1, Q2, Q3, P99]")
    widths = [max(len(x[i]) for x in rows + [head]) for i in range(5)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    return "\n".join([fmt.format(*head).rstrip()] + [fmt.format(*r).rstrip() for r in rows])


def _formatter(unit: str):
    def f(x):
        return "nan" if not math.isfinite(x) else format_number(float(x), unit)

    return f


NAV_KEYS = ("nav_position_error_m", "nav_velocity_error_mps")
GUIDANCE_KEYS = ("total_dv_mps", "terminal_position_error_m", "terminal_velocity_error_mps", "arrival_error_m")  # srf: arrival


def navigation_consistency(table: pd.DataFrame, probability: float = 0.95, max_outside: float = 0.10) -> dict | None:
    """Consistency of a campaign's navigation filter, or None when no run recorded a NEES.

    For the NEES (dimension d) and the NIS (m), over the N runs that did not raise and report one:
    ``mean`` = the mean of the runs' time-mean values, ``band`` = its two-sided ``probability`` band
    chi^2(N d) / N (:func:`proxops.navigation.consistency.mean_band`: the N runs are independent; the
    epochs of one run are correlated and the band is the one of N single-epoch values, whose variance
    bounds that of N time means -- derivation in that module), ``epochs_in_band`` = the fraction of all
    epochs of all runs inside their per-epoch chi^2(d) band, and the verdict ``consistent`` = mean inside
    its band and at most ``max_outside`` of the epochs outside theirs."""
    if METRIC_PREFIX + "nav_nees_mean" not in table:
        return None
    # Kept local and after the test above: the navigation package's __init__ imports numba
    # (core.quaternion), which a campaign's parent process (it imports this module) must not load
    # for a campaign without a filter (0.25-0.4 s after the last run, measured)
    from proxops.navigation.consistency import chi2_band, mean_band

    rows = table[table["outcome"] != "error"] if "outcome" in table else table
    out = {}
    for name in ("nees", "nis"):
        col = METRIC_PREFIX + f"nav_{name}_mean"
        if col not in rows:
            continue
        means = rows[col].astype(float).to_numpy()
        ok = np.isfinite(means)
        dims = rows[METRIC_PREFIX + f"nav_{name}_dim"].astype(float).to_numpy()[ok]
        epochs = rows[METRIC_PREFIX + f"nav_{name}_epochs"].astype(float).to_numpy()[ok]
        inside = rows[METRIC_PREFIX + f"nav_{name}_in_band"].astype(float).to_numpy()[ok]
        n = int(ok.sum())
        if n == 0:
            continue
        d = int(dims[0])
        mean = float(means[ok].mean())
        lo, hi = mean_band(n, d, probability)
        frac = float((inside * epochs).sum() / epochs.sum()) if epochs.sum() > 0 else math.nan
        out[name] = {"runs": n, "dim": d, "mean": mean, "band": [lo, hi], "epoch_band": list(chi2_band(d, probability)),
                     "epochs_in_band": frac, "epochs": int(epochs.sum()),
                     "consistent": bool(lo <= mean <= hi and frac >= 1.0 - max_outside)}
    col = METRIC_PREFIX + "nav_overconfident_windows"
    if col in rows:
        flagged = rows[col].astype(float).to_numpy()
        out["runs_flagged_overconfident"] = int(np.sum(flagged[np.isfinite(flagged)] > 0))
    if "nees" in out:
        out["consistent"] = out["nees"]["consistent"]
    return out or None


def format_navigation_consistency(nc: dict | None) -> str:
    """Text lines of :func:`navigation_consistency` ('' when None)."""
    if not nc:
        return ""
    lines = []
    for name in ("nees", "nis"):
        c = nc.get(name)
        if c is None:
            continue
        lines.append(f"{name.upper():<14}mean {c['mean']:.3g} over {c['runs']} runs (dim {c['dim']}; 95 % band of the "
                     f"campaign mean {c['band'][0]:.3g}-{c['band'][1]:.3g}), {100 * c['epochs_in_band']:.1f} % of "
                     f"{c['epochs']} epochs in the per-epoch band {c['epoch_band'][0]:.3g}-{c['epoch_band'][1]:.3g}: "
                     f"{'consistent' if c['consistent'] else 'NOT consistent'}")
    if "runs_flagged_overconfident" in nc:
        lines.append(f"{'whiteness':<14}{nc['runs_flagged_overconfident']} runs with a window flagged overconfident "
                     "(innovations not white)")
    return "\n".join(lines)


def navigation_table(table: pd.DataFrame) -> str:
    """Markdown: the estimation error of a campaign on the navigation filter beside its guidance
    statistics, or '' when no run used the filter. Each row is one per-run quantity
    (Δv, terminal or arrival errors; the run's median / p95 / max estimation error |r_est - r_true| and
    |v_est - v_true|; rejected measurements; re-initialisations); the columns are its median, p95
    and max over the runs that did not raise (terminal errors: over the runs that report one)."""
    if METRIC_PREFIX + NAV_KEYS[0] + ".median" not in table:
        return ""
    rows = table[table["outcome"] != "error"] if "outcome" in table else table
    names = [k for k in GUIDANCE_KEYS if METRIC_PREFIX + k in rows]
    names += [f"{k}.{s}" for k in NAV_KEYS for s in ("median", "p95", "max")]
    names += [k for k in ("nav_rejected", "nav_reinits", "nav_nees_mean", "nav_nees_in_band", "nav_nis_mean",
                          "nav_nis_in_band", "nav_whiteness_z", "nav_overconfident_windows") if METRIC_PREFIX + k in rows]
    n_ok = int(rows["success"].astype(bool).sum()) if "success" in rows else None
    lines = ([f"Runs: {len(rows)} completed, {n_ok} succeeded." if n_ok is not None else f"Runs: {len(rows)}.", ""]
             + ["| per-run quantity | unit | runs | median | p95 | max |", "| --- | --- | --- | --- | --- | --- |"])
    for name in names:
        v = rows[METRIC_PREFIX + name].astype(float).to_numpy()
        v = v[np.isfinite(v)]
        unit = unit_of_metric(name)
        f = _formatter(unit)
        if v.size:
            med, p95 = np.percentile(v, [50, 95])
            lines.append(f"| {name} | {unit or '-'} | {v.size} | {f(med)} | {f(p95)} | {f(v.max())} |")
        else:
            lines.append(f"| {name} | {unit or '-'} | 0 | - | - | - |")
    nc = format_navigation_consistency(navigation_consistency(table))
    if nc:
        lines += ["", "Filter consistency (proxops.analysis.statistics.navigation_consistency):", "", "```", nc, "```"]
    return "\n".join(lines)
