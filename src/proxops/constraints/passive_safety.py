"""Passive safety of a free drift: the unforced trajectory after an impulse (or an abort) must stay
outside the keep-out zone (srf-hopping-mpc.md §4.3 passive abort; the CORTEX safe orbit, and any
system whose abort is "stop thrusting"). The caller propagates the drift with its own truth or
model (``times`` s, states (F, 6) m, m/s); these checks are numpy only.
"""

from __future__ import annotations

import numpy as np

from proxops.constraints.keep_out import KeepOutSphere


def _segment_min_ranges(t, x, center) -> np.ndarray:
    """Per segment k (between samples k and k+1): minimum |p - c| over both samples and 19
    interior points of the cubic Hermite interpolant (positions + velocities), shape (n - 1,)."""
    t = np.asarray(t, dtype=float)
    p = x[:, :3] - center
    v = x[:, 3:6]
    ends = np.linalg.norm(p, axis=1)
    s = np.linspace(0.0, 1.0, 21)[1:-1, None, None]
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    dt = np.diff(t)[None, :, None]
    seg = h00 * p[:-1] + h10 * dt * v[:-1] + h01 * p[1:] + h11 * dt * v[1:]
    return np.minimum(np.minimum(ends[:-1], ends[1:]), np.min(np.linalg.norm(seg, axis=2), axis=0))


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
