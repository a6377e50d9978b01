"""Passive safety of a free drift: the unforced trajectory after an impulse (or an abort) must stay
outside the keep-out zone (Silva et al. 2026 §4.3 passive abort; the CORTEX safe orbit, and any
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


# |h10|, |h11| <= 4/27 on [0, 1]: with h00 + h01 = 1, p(s) - p_k = h01 (p_k+1 - p_k) + dt (h10 v_k + h11 v_k+1),
# so every point of segment k is within D_k = |p_k+1 - p_k| + 4/27 dt (|v_k| + |v_k+1|) of both ends and
# its distance to the centre is at least max(|p_k|, |p_k+1|) - D_k (the segment's lower bound).
_H_BOUND = 4.0 / 27.0
# a segment is skipped only when its lower bound exceeds the threshold by this relative margin (the
# rounding of its 19 points is ~1e-15 relative): skipping never changes a result
_SKIP_MARGIN = 1e-9


@njit(cache=True)
def _segment_min(t, p, v, k, h00, h10, h01, h11) -> float:
    """Minimum |p| over samples k, k+1 and the 19 interior points of their cubic Hermite interpolant."""
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
    return best


@njit(cache=True)
def _segment_lower_bound(t, p, v, k) -> float:
    """A lower bound of :func:`_segment_min` of segment k from its two samples (see _H_BOUND)."""
    a = math.sqrt(p[k, 0] * p[k, 0] + p[k, 1] * p[k, 1] + p[k, 2] * p[k, 2])
    b = math.sqrt(p[k + 1, 0] * p[k + 1, 0] + p[k + 1, 1] * p[k + 1, 1] + p[k + 1, 2] * p[k + 1, 2])
    dx, dy, dz = p[k + 1, 0] - p[k, 0], p[k + 1, 1] - p[k, 1], p[k + 1, 2] - p[k, 2]
    va = math.sqrt(v[k, 0] * v[k, 0] + v[k, 1] * v[k, 1] + v[k, 2] * v[k, 2])
    vb = math.sqrt(v[k + 1, 0] * v[k + 1, 0] + v[k + 1, 1] * v[k + 1, 1] + v[k + 1, 2] * v[k + 1, 2])
    reach = math.sqrt(dx * dx + dy * dy + dz * dz) + _H_BOUND * (t[k + 1] - t[k]) * (va + vb)
    return max(a, b) - reach


@njit(cache=True)
def _range_min(t, p, v, lo, hi, h00, h10, h01, h11) -> float:
    """Minimum of :func:`_segment_min` over the segments of samples lo..hi (|p[lo]| if lo == hi): first
    the two segments at the closest sample, then only the segments whose lower bound does not clear
    the minimum so far (the minimum of every segment's value, in any order: skipping changes nothing)."""
    if hi <= lo:
        return math.sqrt(p[lo, 0] * p[lo, 0] + p[lo, 1] * p[lo, 1] + p[lo, 2] * p[lo, 2])
    k_near = lo
    r_near = math.inf
    for k in range(lo, hi + 1):
        r = math.sqrt(p[k, 0] * p[k, 0] + p[k, 1] * p[k, 1] + p[k, 2] * p[k, 2])
        if r < r_near:
            r_near, k_near = r, k
    best = math.inf
    for k in (k_near - 1, k_near):
        if lo <= k < hi:
            best = min(best, _segment_min(t, p, v, k, h00, h10, h01, h11))
    for k in range(lo, hi):
        if _segment_lower_bound(t, p, v, k) > best * (1.0 + _SKIP_MARGIN) + _SKIP_MARGIN:
            continue
        d = _segment_min(t, p, v, k, h00, h10, h01, h11)
        if d < best:
            best = d
    return best


@njit(cache=True)
def _min_range_kernel(t, p, v, h00, h10, h01, h11) -> float:
    """Minimum of :func:`_segment_min` over all segments (:func:`_range_min` of the whole drift)."""
    return _range_min(t, p, v, 0, p.shape[0] - 1, h00, h10, h01, h11)


@njit(cache=True)
def _first_dip_kernel(t, p, v, radius, h00, h10, h01, h11) -> int:
    """First segment whose :func:`_segment_min` is below ``radius`` (-1 if none); segments whose
    lower bound clears the radius are not evaluated."""
    for k in range(p.shape[0] - 1):
        if _segment_lower_bound(t, p, v, k) > radius * (1.0 + _SKIP_MARGIN) + _SKIP_MARGIN:
            continue
        if _segment_min(t, p, v, k, h00, h10, h01, h11) < radius:
            return k
    return -1


@njit(cache=True)
def _orbit_index(t, period, whole):
    """k_at[m] = np.argmin(np.abs(t - m period)) (its first minimum), m = 0..whole, for increasing t:
    |t - target| (rounded) does not increase before the first t >= target and does not decrease from it,
    so the minimum is at that index or at the one before it (the first of its equal values)."""
    n = t.shape[0]
    k_at = np.empty(whole + 1, dtype=np.int64)
    for m in range(whole + 1):
        target = m * period
        j = np.searchsorted(t, target)  # first t[j] >= target
        if j >= n:
            j = n - 1
        k = j
        if j > 0 and abs(t[j - 1] - target) <= abs(t[j] - target):
            k = j - 1
            while k > 0 and abs(t[k - 1] - target) == abs(t[k] - target):
                k -= 1
        k_at[m] = k
    return k_at


@njit(cache=True)
def _certificate_kernel(t, p, v, radius, k_at, h00, h10, h01, h11):
    """One pass over a drift relative to the KOZ centre (p, v): the minimum over every segment of each
    whole orbit k_at[m-1]..k_at[m] (:func:`hermite_min_range` of that slice) and over the whole drift (the
    minimum of the orbits' and the two ends' ranges, which cover every segment once), then the first-entry
    search of :func:`first_entry_time` (first sample inside, first segment dipping inside before it; -1 if
    none), skipped when that minimum is not below the radius (no sample or segment can then be inside)."""
    n = p.shape[0]
    whole = k_at.shape[0] - 1
    per = np.empty(whole)
    best = _range_min(t, p, v, 0, k_at[0], h00, h10, h01, h11)
    for m in range(1, whole + 1):
        per[m - 1] = _range_min(t, p, v, k_at[m - 1], k_at[m], h00, h10, h01, h11)
        best = min(best, per[m - 1])
    best = min(best, _range_min(t, p, v, k_at[whole], n - 1, h00, h10, h01, h11))
    k_in = -1
    hit = -1
    if best >= radius:  # every sample and every segment's minimum is >= best: nothing enters
        return k_in, hit, per, best
    for k in range(n):
        if math.sqrt(p[k, 0] * p[k, 0] + p[k, 1] * p[k, 1] + p[k, 2] * p[k, 2]) < radius:
            k_in = k
            break
    last = n - 1 if k_in < 0 else k_in
    if last >= 1:
        hit = _first_dip_kernel(t[:last + 1], p[:last + 1], v[:last + 1], radius, h00, h10, h01, h11)
    return k_in, hit, per, best


def _relative(t, x, center):
    t = np.ascontiguousarray(t, dtype=float)
    p = np.ascontiguousarray(x[:, :3] - center, dtype=float)
    v = np.ascontiguousarray(x[:, 3:6], dtype=float)
    return t, p, v


def hermite_min_range(t, x, center) -> float:
    """Minimum |p - c| along cubic Hermite interpolants between samples (positions + velocities):
    per segment the two samples and 19 interior points; one jitted pass that skips the segments
    a bound from their samples shows cannot hold the minimum (the result is the same)."""
    x = np.asarray(x, dtype=float)
    if len(x) < 2:
        return float(np.min(np.linalg.norm(x[:, :3] - center, axis=1)))
    return float(_min_range_kernel(*_relative(t, x, center), _H00, _H10, _H01, _H11))


def drift_safety(times, drift, koz: KeepOutSphere) -> dict:
    """Safety of one free drift: ``min_range_m`` (to the origin), ``min_koz_distance_m`` (to the KOZ
    surface, negative inside) along cubic Hermite interpolants of the samples, and ``safe``
    (the drift never enters the sphere)."""
    rng = hermite_min_range(times, drift, np.zeros(3))
    centred = not np.any(koz.center_m)  # a KOZ about the origin: the same minimum
    koz_d = (rng if centred else hermite_min_range(times, drift, koz.center_m)) - koz.radius_m
    return {"min_range_m": rng, "min_koz_distance_m": koz_d, "safe": bool(koz_d > 0.0)}


def first_entry_time(t, x, center, radius) -> float:
    """First sample time (s) of the segment where the drift enters the sphere (its Hermite
    interpolant dips inside; also a sample inside); inf if it never does. Segments up to the
    first sample inside are checked, in one jitted pass."""
    x = np.asarray(x, dtype=float)
    p = np.linalg.norm(x[:, :3] - center, axis=1)
    inside = np.nonzero(p < radius)[0]
    k_in = int(inside[0]) if inside.size else None
    last = len(t) - 1 if k_in is None else k_in  # segments ending at samples 1..last
    if last >= 1:
        tt, pp, vv = _relative(np.asarray(t)[:last + 1], x[:last + 1], center)
        hit = _first_dip_kernel(tt, pp, vv, float(radius), _H00, _H10, _H01, _H11)
        if hit >= 0:
            return float(t[hit])
    return float(t[k_in]) if k_in is not None else np.inf


def certify_free_drift(times, drift, koz: KeepOutSphere, period_s: float, window_orbits: float) -> dict:
    """The passive-safety certificate of one thrust-free drift (every system's abort or free-drift
    phase: one block, one verdict). ``times`` (s from the drift start, from 0, covering the window),
    ``drift`` (F, 6) Hill states (m, m/s) propagated by the caller with its truth, ``period_s`` the
    target orbit's period, ``window_orbits`` the window the verdict names.

    Per whole orbit k of the window (phase-aligned samples at (k-1) T and k T): ``min_range_per_orbit_m``
    (to the KOZ centre, along cubic Hermite interpolants), ``return_miss_per_orbit_m`` (|r(kT) - r((k-1)T)|)
    and ``along_track_drift_per_orbit_m``: the motion of the relative orbit's CENTRE, the change of the
    orbit-mean along-track position y_c(k) - y_c(k-1) (trapezoid mean over each whole orbit: W - 1 values
    for W whole orbits; one orbit: y(T) - y(0)), signed POSITIVE AWAY from the target (times sign(y_c - c_y),
    c the KOZ centre). The CW secular term of y is -3 (vy0 + 2 n x0) t and its periodic terms average out
    over T; unlike y(kT) - y((k-1)T) the centre does not confuse a phase shift of a large periodic motion
    (J2 changes the relative-motion frequencies by ~1e-3: a 500 m hop ellipse returns metres off in phase
    each orbit without moving) with a drift. ``first_koz_entry_s``
    (None if none in the window). Verdict: ``"enters KOZ at N orbits"`` (unsafe), else
    ``"indefinite: drift away from target"`` only when every orbit drifts away AND the whole last orbit
    lies on one side of the target along-track farther than the KOZ radius (|y - c_y| > r on every
    sample: with the CW periodic + secular motion moving away, |y| and so the range cannot fall below that
    minimum later), else ``"safe over W orbits"``."""
    return free_drift_checks(times, drift, koz, period_s, window_orbits)[0]


def free_drift_checks(times, drift, koz: KeepOutSphere, period_s: float, window_orbits: float) -> tuple[dict, dict]:
    """:func:`certify_free_drift` and, from the same pass, what a caller would otherwise recompute:
    ``{"first_entry_s": first_entry_time(...) (s, inf if none; not limited to the window),
    "safety": drift_safety(...), "orbit_index": the sample index at m whole orbits, m = 0..W}``.

    One jitted pass over the drift (:func:`_certificate_kernel`) gives the first entry, the minimum of
    every whole orbit and of the whole drift: the same segments and the same arithmetic as the separate
    functions, so the same numbers (tests/test_passive_certificate.py compares them bit for bit)."""
    t = np.asarray(times, dtype=float)
    x = np.asarray(drift, dtype=float)
    period = float(period_s)
    window = float(window_orbits)
    if t.size < 2 or t[-1] < window * period * (1 - 1e-9):
        raise ValueError(f"free drift covers {t[-1] if t.size else 0.0:g} s, the window needs {window * period:g} s")
    c = np.asarray(koz.center_m, dtype=float)
    r_koz = float(koz.radius_m)
    whole = int(math.floor(window + 1e-9))
    if np.any(c):
        tt, p, v = _relative(t, x, c)
    else:  # a KOZ about the origin: the drift's own columns (views, no copies; x - 0 = x)
        tt, p, v = np.ascontiguousarray(t), x[:, :3], x[:, 3:6]
    k_at_arr = _orbit_index(tt, period, whole)
    k_in, hit, per, best = _certificate_kernel(tt, p, v, r_koz, k_at_arr, _H00, _H10, _H01, _H11)
    k_at = [int(k) for k in k_at_arr]
    first_entry = float(t[hit]) if hit >= 0 else (float(t[k_in]) if k_in >= 0 else np.inf)
    entry = first_entry if first_entry <= window * period * (1 + 1e-12) else np.inf
    if np.any(c):  # drift_safety: the range to the origin, and the KOZ distance from the centred minimum
        rng = hermite_min_range(t, x, np.zeros(3))
    else:
        rng = float(best)
    base = {"min_range_m": rng, "min_koz_distance_m": float(best) - r_koz, "safe": bool(float(best) - r_koz > 0.0)}
    per_min = [float(d) for d in per]
    miss, along, centre = [], [], []
    # np.trapezoid(y[a:b+1], t[a:b+1]) of each orbit = sum of these terms over a..b-1 (same products, same sums)
    terms = np.diff(t) * (x[1:, 1] + x[:-1, 1]) / 2.0
    for m in range(1, whole + 1):
        a, b = k_at[m - 1], k_at[m]
        miss.append(float(np.linalg.norm(x[b, :3] - x[a, :3])))
        centre.append(float(terms[a:b].sum() / (t[b] - t[a])) - c[1])
    # W whole orbits give W - 1 centre steps (orbit k against k - 1); a one-orbit window: y(T) - y(0)
    if whole >= 2:
        for m in range(1, whole):
            along.append((1.0 if centre[m] >= 0.0 else -1.0) * (centre[m] - centre[m - 1]))
    elif whole == 1:
        along.append((1.0 if centre[0] >= 0.0 else -1.0) * float(x[k_at[1], 1] - x[k_at[0], 1]))
    safe = not math.isfinite(entry)
    indefinite = False
    if safe and along:
        a, b = k_at[-2], k_at[-1]
        dy = x[a:b + 1, 1] - c[1]
        one_side = bool(np.all(dy > r_koz) or np.all(dy < -r_koz))
        indefinite = one_side and all(d > 0.0 for d in along)
    if not safe:
        verdict = f"enters KOZ at {entry / period:.2f} orbits"
    elif indefinite:
        verdict = (f"indefinite: drift away from target ({float(np.median(along)):+.3g} m/orbit along-track, "
                   f"whole orbit beyond {r_koz:g} m)")
    else:
        verdict = f"safe over {window:g} orbits"
    cert = {
        "window_orbits": window, "verdict": verdict, "safe": safe, "indefinite": indefinite,
        "min_range_m": base["min_range_m"], "min_koz_distance_m": base["min_koz_distance_m"],
        "first_koz_entry_s": float(entry) if not safe else None,
        "first_koz_entry_orbits": float(entry / period) if not safe else None,
        "min_range_per_orbit_m": per_min, "return_miss_per_orbit_m": miss,
        "along_track_drift_per_orbit_m": along,
        "centre_along_track_m": centre,  # orbit-mean y - c_y per whole orbit (m, Hill +y: the raw centre positions)
        "drift_median_m_per_orbit": float(np.median(along)) if along else math.nan,
    }
    return cert, {"first_entry_s": first_entry, "safety": base, "orbit_index": k_at}
