"""Passive safety of a free drift: the unforced trajectory after an impulse (or an abort) must stay
outside the keep-out zone (srf-hopping-mpc.md §4.3 passive abort; the CORTEX safe orbit, and any
system whose abort is "stop thrusting"). The caller propagates the drift with its own truth or
model (``times`` s, states (F, 6) m, m/s); these checks are numpy only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from proxops.constraints.keep_out import KeepOutSphere


_S = np.linspace(0.0, 1.0, 21)[1:-1]  # 19 interior points of each segment
_H00, _H10 = 2 * _S**3 - 3 * _S**2 + 1, _S**3 - 2 * _S**2 + _S  # cubic Hermite basis at those points
_H01, _H11 = -2 * _S**3 + 3 * _S**2, _S**3 - _S**2


@njit(cache=True)
def _segment_min_kernel(t, p, v, h00, h10, h01, h11):
    n = p.shape[0]
    out = np.empty(n - 1)
    for k in range(n - 1):
        a = math.sqrt(p[k, 0] * p[k, 0] + p[k, 1] * p[k, 1] + p[k, 2] * p[k, 2])
        b = math.sqrt(p[k + 1, 0] * p[k + 1, 0] + p[k + 1, 1] * p[k + 1, 1] + p[k + 1, 2] * p[k + 1, 2])
        best = min(a, b)
        dt = t[k + 1] - t[k]
        for j in range(h00.size):
            c10, c11 = h10[j] * dt, h11[j] * dt
            x = h00[j] * p[k, 0] + c10 * v[k, 0] + h01[j] * p[k + 1, 0] + c11 * v[k + 1, 0]
            y = h00[j] * p[k, 1] + c10 * v[k, 1] + h01[j] * p[k + 1, 1] + c11 * v[k + 1, 1]
            z = h00[j] * p[k, 2] + c10 * v[k, 2] + h01[j] * p[k + 1, 2] + c11 * v[k + 1, 2]
            d = math.sqrt(x * x + y * y + z * z)
            if d < best:
                best = d
        out[k] = best
    return out


def _segment_min_ranges(t, x, center) -> np.ndarray:
    """Per segment k (between samples k and k+1): minimum |p - c| over both samples and 19
    interior points of the cubic Hermite interpolant (positions + velocities), shape (n - 1,);
    one jitted pass (no (19, n, 3) temporaries)."""
    t = np.ascontiguousarray(t, dtype=float)
    p = np.ascontiguousarray(x[:, :3] - center, dtype=float)
    v = np.ascontiguousarray(x[:, 3:6], dtype=float)
    return _segment_min_kernel(t, p, v, _H00, _H10, _H01, _H11)


def hermite_min_range(t, x, center) -> float:
    """Minimum |p - c| along cubic Hermite interpolants between samples (positions + velocities)."""
    x = np.asarray(x, dtype=float)
    if len(x) < 2:
        return float(np.min(np.linalg.norm(x[:, :3] - center, axis=1)))
    return float(np.min(_segment_min_ranges(t, x, center)))


def drift_safety(times, drift, koz: KeepOutSphere) -> dict:
    """Safety of one free drift: ``min_range_m`` (to the origin), ``min_koz_distance_m`` (to the KOZ
    surface, negative inside) along cubic Hermite interpolants of the samples, and ``safe``
    (the drift never enters the sphere)."""
    rng = hermite_min_range(times, drift, np.zeros(3))
    koz_d = hermite_min_range(times, drift, koz.center_m) - koz.radius_m
    return {"min_range_m": rng, "min_koz_distance_m": koz_d, "safe": bool(koz_d > 0.0)}


def first_entry_time(t, x, center, radius) -> float:
    """First sample time (s) of the segment where the drift enters the sphere (its Hermite
    interpolant dips inside; also a sample inside); inf if it never does. Segments up to the
    first sample inside are checked, all at once."""
    x = np.asarray(x, dtype=float)
    p = np.linalg.norm(x[:, :3] - center, axis=1)
    inside = np.nonzero(p < radius)[0]
    k_in = int(inside[0]) if inside.size else None
    last = len(t) - 1 if k_in is None else k_in  # segments ending at samples 1..last
    if last >= 1:
        hit = np.nonzero(_segment_min_ranges(np.asarray(t)[:last + 1], x[:last + 1], center) < radius)[0]
        if hit.size:
            return float(t[hit[0]])
    return float(t[k_in]) if k_in is not None else np.inf
