"""Campaign metrics in the order a reader looks for them, without the noise.

A campaign table holds every number a run's summary has (40 or more): the headline (Δv, how
the run ended), terminal accuracy, safety, navigation, the system's own quantities, timings,
and also constants of the scenario (``period_s``) and bookkeeping (``steps``, ``seed``).
:func:`ordered_metrics` puts them in that order of meaning and leaves out what does not
inform: columns constant over the runs (relative spread below 1e-9: a period differing in
the 13th digit is a constant), bookkeeping, and columns that repeat another column exactly.
"""

from __future__ import annotations

import fnmatch

import numpy as np
import pandas as pd

from proxops.analysis.statistics import METRIC_PREFIX, metric_columns

# (group title, name patterns) in reading order; the first matching group wins
GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("delta-v", ("total_dv_mps", "*dv*")),
    ("terminal accuracy", ("final_*", "terminal_*", "arrival_*", "*tracking_error*", "*docking*")),
    ("safety", ("min_range_m", "*kos*", "*koz*", "*safe*", "*passive*", "*abort*", "max_violation*", "*violation*")),
    ("navigation", ("nav_*", "att_*")),
    ("mission", ("*",)),
    ("timing", ("wall_time_s", "*solve_time*", "*_ms.*", "*_ms")),
)
HIDDEN = ("steps", "seed", "solver_failures_total")  # bookkeeping, not a result
TIMING_GROUP = "timing"


def metric_group(name: str) -> str:
    """Group title of a metric name (without the ``metric.`` prefix)."""
    timing = dict(GROUPS)[TIMING_GROUP]
    if any(fnmatch.fnmatchcase(name, p) for p in timing):  # a solve time is a timing, not "mission"
        return TIMING_GROUP
    for title, patterns in GROUPS:
        if any(fnmatch.fnmatchcase(name, p) for p in patterns):
            return title
    return "mission"


def _constant(values: np.ndarray) -> bool:
    v = values[np.isfinite(values)]
    if v.size <= 1:
        return True
    spread = float(v.max() - v.min())
    return spread <= 1e-9 * max(1.0, float(np.abs(v).max()))


def ordered_metrics(table: pd.DataFrame, include_timing: bool = True) -> list[str]:
    """Metric columns (with the ``metric.`` prefix) by meaning (:data:`GROUPS`), each group in
    its own order (patterns first, then alphabetical); constants, bookkeeping and exact
    duplicates of an earlier column left out."""
    order = {title: i for i, (title, _) in enumerate(GROUPS)}
    keep, seen = [], []
    for col in metric_columns(table):
        name = col[len(METRIC_PREFIX):]
        if name in HIDDEN:
            continue
        values = table[col].to_numpy(dtype=float)
        if _constant(values):
            continue
        keep.append(col)

    def rank(col: str):
        name = col[len(METRIC_PREFIX):]
        group = metric_group(name)
        patterns = dict(GROUPS)[group]
        first = next((i for i, p in enumerate(patterns) if fnmatch.fnmatchcase(name, p)), len(patterns))
        return (order[group], first, name)

    out = []
    for col in sorted(keep, key=rank):
        if not include_timing and metric_group(col[len(METRIC_PREFIX):]) == TIMING_GROUP:
            continue
        values = table[col].to_numpy(dtype=float)
        if any(np.array_equal(values, prev, equal_nan=True) for prev in seen):
            continue  # e.g. mpc_solve_ms.* repeating solve_time_ms.*
        seen.append(values)
        out.append(col)
    return out
