"""Solve-time statistics: the one summary used by run results and system summaries."""

from __future__ import annotations

import numpy as np


def solve_time_stats(seconds) -> dict:
    """``{"median", "p95", "max"}`` of solve times given in s, reported in ms (all 0.0 when empty).

    p95 is numpy's linear-interpolation 95th percentile."""
    s = np.asarray(seconds, dtype=float).reshape(-1)
    if s.size == 0:
        return {"median": 0.0, "p95": 0.0, "max": 0.0}
    return {
        "median": float(np.median(s) * 1e3),
        "p95": float(np.percentile(s, 95) * 1e3),
        "max": float(np.max(s) * 1e3),
    }
