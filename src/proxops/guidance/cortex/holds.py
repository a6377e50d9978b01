"""Sunlight-aware hold times of CORTEX (Wijayatunga et al. §3.1, eqs. 13-15, Algorithm 1).

The eclipse profile is a sampled time grid ``t_ecl`` (s, increasing) with a sunlight
flag ``eta`` per sample (1 = sunlit); sample ``i`` stands for ``[t_i, t_{i+1})``.
Any source works: :func:`sunlit_flags` turns an illumination fraction in [0, 1]
(e.g. a conical umbra/penumbra model) into flags, so the logic is testable with
synthetic profiles.

Corrections to the printed equations (noted here and in the report):

* eq. (14) sums ``j = i .. k-1`` after already counting ``t_{i+1} - t``: interval ``i``
  would be counted twice. The contiguous sunlit time from ``t`` to the first eclipse
  sample ``k`` is ``(t_{i+1} - t) + sum_{j=i+1}^{k-1} (t_{j+1} - t_j) = t_k - t``.
* eq. (15) then gives ``t_wait = t_rem + (t_m - t_k) = t_m - t`` (next sunrise sample m).
* Algorithm 1 uses eq. (15) when the CSO is in sunlight at the start of the fly-around
  (lines 2-3) but at the start of the final approach it uses eq. (15) when in *eclipse*
  (lines 8-9), the opposite of the text; the text's rule is used for both holds.
* eq. (13) alone waits until sunrise without checking that the sunlit window is long
  enough for the transfer; here the eq.-(15) test is applied again at that sunrise, so
  the whole transfer is in sunlight (the text's goal), repeated until a window fits.
"""

from __future__ import annotations

import math

import numpy as np

from proxops.errors import input_error


def sunlit_flags(illumination, threshold: float = 1.0) -> np.ndarray:
    """eta = 1 where the illuminated fraction >= ``threshold`` (1.0: penumbra counts as eclipse)."""
    illum = np.asarray(illumination, dtype=float)
    if not (0.0 < threshold <= 1.0):
        raise input_error("sunlit threshold", threshold, "must satisfy 0 < threshold <= 1")
    return (illum >= threshold - 1e-12).astype(np.int8)


def check_profile(t_ecl, eta) -> tuple[np.ndarray, np.ndarray]:
    """Validated (t, eta) arrays: same length >= 2, t strictly increasing and finite, eta in {0, 1}."""
    t = np.asarray(t_ecl, dtype=float)
    e = np.asarray(eta)
    if t.ndim != 1 or t.shape != e.shape or t.size < 2:
        raise input_error("eclipse profile", f"t {t.shape}, eta {e.shape}", "need two 1-D arrays of equal length >= 2")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise input_error("eclipse profile t_s", "not increasing", "sample times must be finite and strictly increasing", "s")
    if not np.all(np.isin(e, (0, 1))):
        raise input_error("eclipse profile eta", "values", "flags must be 0 (eclipse) or 1 (sunlit)")
    return t, e.astype(np.int8)


def _index(t_ecl: np.ndarray, t: float) -> int:
    """i with t_i <= t < t_{i+1}; -1 when t is outside the profile."""
    if not (t_ecl[0] <= t < t_ecl[-1]):
        return -1
    return int(np.searchsorted(t_ecl, t, side="right") - 1)


def _first(eta: np.ndarray, start: int, value: int) -> int:
    """First index j >= start with eta_j == value, or -1."""
    hits = np.flatnonzero(eta[start:] == value)
    return int(start + hits[0]) if hits.size else -1


def sunrise_wait(t_ecl, eta, t: float) -> float:
    """Eq. (13): time from t (in eclipse) to the first sunlit sample after it (s); inf if none."""
    i = _index(t_ecl, t)
    if i < 0:
        return math.inf
    k = _first(eta, i + 1, 1)
    return math.inf if k < 0 else float(t_ecl[k] - t)


def remaining_sunlight(t_ecl, eta, t: float) -> float:
    """Eq. (14), corrected sum (see module doc): sunlit time left from t (sunlit) to the first
    eclipse sample k > i, t_k - t (s); inf when the profile ends sunlit (no eclipse seen)."""
    i = _index(t_ecl, t)
    if i < 0:
        return math.nan
    k = _first(eta, i + 1, 0)
    return math.inf if k < 0 else float(t_ecl[k] - t)


def hold_time(t_ecl, eta, t: float, tau: float, max_windows: int = 100) -> float:
    """Hold before a transfer of ``tau`` s that may start at ``t`` so that it runs in sunlight
    (Algorithm 1 with eqs. 13-15, corrected as in the module doc). Returns the hold (s), or inf
    when the profile does not reach far enough to decide (extend the profile)."""
    t_ecl, eta = np.asarray(t_ecl, float), np.asarray(eta)
    start = float(t)
    for _ in range(max_windows):
        i = _index(t_ecl, start)
        if i < 0:
            return math.inf
        if eta[i] != 1:  # eq. (13): wait for the sunrise
            w = sunrise_wait(t_ecl, eta, start)
            if not math.isfinite(w):
                return math.inf
            start += w
            continue
        t_rem = remaining_sunlight(t_ecl, eta, start)
        if t_rem >= tau:  # eq. (15), first case
            if not math.isfinite(t_rem) and start + tau > t_ecl[-1]:
                return math.inf  # the profile ends before the transfer does
            return start - float(t)
        k = _index(t_ecl, start + t_rem)  # eq. (15), second case: t_wait = t_rem + (t_m - t_k)
        m = _first(eta, k, 1)
        if m < 0:
            return math.inf
        start = float(t_ecl[m])
    return math.inf


def transfer_in_sunlight(t_ecl, eta, t_start: float, tau: float) -> bool:
    """True when every profile sample overlapping [t_start, t_start + tau] is sunlit (a check
    independent of the hold logic above)."""
    t_ecl, eta = np.asarray(t_ecl, float), np.asarray(eta)
    i0 = _index(t_ecl, t_start)
    i1 = _index(t_ecl, t_start + tau)
    if i0 < 0 or i1 < 0:
        return False
    # samples i0..i1 cover the interval; the last one only if t_start + tau > t_{i1}
    last = i1 if t_start + tau > t_ecl[i1] else i1 - 1
    return bool(np.all(eta[i0 : max(last, i0) + 1] == 1))
