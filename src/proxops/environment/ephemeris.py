"""Sun and Moon geocentric positions in ECI (GCRF axes, m).

Model: the IAU SOFA library through ``pyerfa`` -- the Sun from ``erfa.epv00`` (the Earth's
heliocentric position, a fit to JPL DE405 within 4.6 km over 1900-2100) and the Moon from
``erfa.moon98`` (Meeus' ELP-2000/82 truncation, a few arcsec). Measured against JPL DE421
(jplephem, geometric Earth->Sun / Earth->Moon) over 1980-2050, 300 random epochs
(``tests/test_environment_ephemeris.py`` repeats it when ``jplephem`` and ``de421`` are
installed): Sun direction <= 0.015 arcsec (was 39 arcsec with the analytic series below),
distance <= 4e-8; Moon direction <= 10 arcsec (was 317 arcsec), distance <= 3e-5.

Inside the numba propagation kernels (no Python calls per step) the positions are the
analytic series below plus a per-run cubic correction (:func:`third_body_fit`: erfa minus
series, fitted over the first :data:`FIT_DAYS` days of the run): within 0.01 arcsec (Sun)
and 0.2 arcsec (Moon) of erfa there; past :data:`FIT_DAYS` the correction is held at its
end value and the error grows back toward the series' own (Sun <= 39", Moon <= 317").

Analytic series (the kernels' base): Sun: the Astronomical Almanac's low-precision formula
(*Astronomical Almanac*, sec. C, "Low precision formulas for the Sun", 0.01 deg for 1950-2050)
for the ecliptic longitude of the mean equinox of date, the general precession in longitude
(1.3970 deg per Julian century; Montenbruck & Gill, *Satellite Orbits*, sec. 3.3.2) removed to
refer it to the J2000 equinox, rotated to the equator with the J2000 obliquity 23.43929111 deg.
Moon: Montenbruck & Gill (2000), sec. 3.3.2, eqs. 3.47-3.49 (Brown's lunar theory truncated;
longitude referred to the J2000 equinox by the -1.3972 T term), rotated the same way.

Time argument: TT (TDB - TT < 1.7 ms neglected); T = TT Julian centuries from J2000.0
(:mod:`proxops.environment.epochs`).
"""

from __future__ import annotations

import math
from functools import lru_cache

import erfa
import numpy as np
from numba import njit

from proxops.environment.disk_memo import digest, disk_get
from proxops.environment.epochs import Epoch, check_time_range, parse_epoch

AU = 149_597_870_700.0  # m (IAU 2012)
OBLIQUITY_J2000 = math.radians(23.43929111)  # rad, mean obliquity at J2000
R_SUN = 6.957e8  # m, nominal solar radius (IAU 2015 Resolution B3)
GM_SUN = 1.32712440018e20  # m^3/s^2 (DE421)
GM_MOON = 4.9028e12  # m^3/s^2 (DE421: 4902.800 km^3/s^2)
FIT_DAYS = 2.0  # span of the kernels' per-run correction (days)
N_FIT = 24  # correction coefficients: (Sun, Moon) x 4 powers x 3 axes


def _times(epoch: Epoch | str, t_s) -> tuple[Epoch, np.ndarray]:
    epoch = parse_epoch(epoch)
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    if t.size:
        check_time_range(epoch, float(np.max(t)), "t_s")
        check_time_range(epoch, float(np.min(t)), "t_s")
    return epoch, t


_CE = math.cos(OBLIQUITY_J2000)
_SE = math.sin(OBLIQUITY_J2000)
_DEG = math.pi / 180.0
_AS = math.pi / (180.0 * 3600.0)


@njit(cache=True, fastmath=False)
def _ecliptic_to_eci(lam: float, beta: float, r: float):
    """Equatorial J2000 vector from ecliptic longitude, latitude (rad) and distance (m)."""
    cb = math.cos(beta)
    x = r * cb * math.cos(lam)
    y = r * cb * math.sin(lam)
    z = r * math.sin(beta)
    return x, _CE * y - _SE * z, _SE * y + _CE * z


@njit(cache=True, fastmath=False)
def sun_eci_kernel(d: float):
    """Geocentric Sun (m, ECI J2000 axes) at ``d`` TT days from J2000 (Astronomical Almanac
    low-precision formula, referred to the J2000 equinox; see module doc)."""
    T = d / 36525.0
    L = (280.460 + 0.9856474 * d) * _DEG
    g = (357.528 + 0.9856003 * d) * _DEG
    lam = L + 1.915 * _DEG * math.sin(g) + 0.020 * _DEG * math.sin(2.0 * g)
    lam = lam - 1.3970 * _DEG * T  # mean equinox of date -> J2000 equinox
    r = AU * (1.00014 - 0.01671 * math.cos(g) - 0.00014 * math.cos(2.0 * g))
    return _ecliptic_to_eci(lam, 0.0, r)


@njit(cache=True, fastmath=False)
def moon_eci_kernel(d: float):
    """Geocentric Moon (m, ECI J2000 axes) at ``d`` TT days from J2000 (Montenbruck & Gill
    eqs. 3.47-3.49)."""
    T = d / 36525.0
    L0 = (218.31617 + 481267.88088 * T - 1.3972 * T) * _DEG
    l = (134.96292 + 477198.86753 * T) * _DEG  # noqa: E741  (Moon's mean anomaly)
    lp = (357.52543 + 35999.04944 * T) * _DEG  # Sun's mean anomaly
    F = (93.27283 + 483202.01873 * T) * _DEG  # mean argument of latitude
    D = (297.85027 + 445267.11135 * T) * _DEG  # mean elongation
    lam = L0 + _AS * (
        22640.0 * math.sin(l)
        + 769.0 * math.sin(2 * l)
        - 4586.0 * math.sin(l - 2 * D)
        + 2370.0 * math.sin(2 * D)
        - 668.0 * math.sin(lp)
        - 412.0 * math.sin(2 * F)
        - 212.0 * math.sin(2 * l - 2 * D)
        - 206.0 * math.sin(l + lp - 2 * D)
        + 192.0 * math.sin(l + 2 * D)
        - 165.0 * math.sin(lp - 2 * D)
        + 148.0 * math.sin(l - lp)
        - 125.0 * math.sin(D)
        - 110.0 * math.sin(l + lp)
        - 55.0 * math.sin(2 * F - 2 * D)
    )
    beta = _AS * (
        18520.0 * math.sin(F + lam - L0 + _AS * (412.0 * math.sin(2 * F) + 541.0 * math.sin(lp)))
        - 526.0 * math.sin(F - 2 * D)
        + 44.0 * math.sin(l + F - 2 * D)
        - 31.0 * math.sin(-l + F - 2 * D)
        - 25.0 * math.sin(-2 * l + F)
        - 23.0 * math.sin(lp + F - 2 * D)
        + 21.0 * math.sin(-l + F)
        + 11.0 * math.sin(-lp + F - 2 * D)
    )
    r = 1e3 * (
        385000.0
        - 20905.0 * math.cos(l)
        - 3699.0 * math.cos(2 * D - l)
        - 2956.0 * math.cos(2 * D)
        - 570.0 * math.cos(2 * l)
        + 246.0 * math.cos(2 * l - 2 * D)
        - 205.0 * math.cos(lp - 2 * D)
        - 171.0 * math.cos(l + 2 * D)
        - 152.0 * math.cos(l + lp - 2 * D)
    )
    return _ecliptic_to_eci(lam, beta, r)


@njit(cache=True)
def _many(which: int, d0: float, t: np.ndarray) -> np.ndarray:
    out = np.empty((t.size, 3))
    for k in range(t.size):
        d = d0 + t[k] / 86400.0
        x, y, z = sun_eci_kernel(d) if which == 0 else moon_eci_kernel(d)
        out[k, 0] = x
        out[k, 1] = y
        out[k, 2] = z
    return out


def _erfa_positions(epoch: Epoch, t: np.ndarray, which: tuple[int, ...] = (0, 1)) -> list[np.ndarray]:
    """Geocentric positions (n, 3) m from erfa at ``t`` s after ``epoch`` (TT) of the Sun (0,
    ``erfa.epv00``) and/or the Moon (1, ``erfa.moon98``), in the order of ``which``."""
    tt = epoch.jd_utc_frac + (epoch.tt_minus_utc_s + t) / 86400.0
    day = epoch.jd_utc_day + np.floor(tt)
    frac = tt - np.floor(tt)
    return [-erfa.epv00(day, frac)[0]["p"] * AU if w == 0 else erfa.moon98(day, frac)["p"] * AU for w in which]


def sun_position_eci(epoch: Epoch | str, t_s) -> np.ndarray:
    """Geocentric Sun position (n, 3) m in ECI (GCRF axes) at ``t_s`` s after ``epoch``:
    erfa (``epv00``; <= 0.015 arcsec from DE421), through the kernels' fitted series when all
    times are in [0, FIT_DAYS] (the same numbers the propagation sees; <= 0.01" from erfa)."""
    return _position(0, epoch, t_s)


def moon_position_eci(epoch: Epoch | str, t_s) -> np.ndarray:
    """Geocentric Moon position (n, 3) m in ECI (GCRF axes) at ``t_s`` s after ``epoch``:
    erfa (``moon98``; <= 10 arcsec from DE421), through the kernels' fitted series when all
    times are in [0, FIT_DAYS] (<= 0.2" from erfa)."""
    return _position(1, epoch, t_s)


def _position(which: int, epoch: Epoch | str, t_s) -> np.ndarray:
    epoch, t = _times(epoch, t_s)
    if t.size and 0.0 <= float(np.min(t)) and float(np.max(t)) <= FIT_DAYS * 86400.0:
        return _fitted_many(which, epoch.days_tt_since_j2000(0.0), np.ascontiguousarray(t), _cached_fit(epoch.iso))
    return np.ascontiguousarray(_erfa_positions(epoch, t, (which,))[0])


def cached_third_body_fit(epoch: Epoch | str) -> np.ndarray:
    """:func:`third_body_fit` of ``epoch`` (the same bits), memoised per epoch in the process and on
    disk (:mod:`proxops.environment.disk_memo`): the 49 erfa evaluations cost ~4 ms per run set-up."""
    return _cached_fit(parse_epoch(epoch).iso)


@lru_cache(maxsize=16)
def _cached_fit(iso: str) -> np.ndarray:
    key = digest("third_body_fit", iso, erfa.__version__)
    return disk_get("sunmoon", key, (N_FIT,), lambda: third_body_fit(iso))  # shared: callers only read it


@njit(cache=True)
def _fitted_many(which: int, d0: float, t: np.ndarray, c: np.ndarray) -> np.ndarray:
    out = np.empty((t.size, 3))
    for k in range(t.size):
        out[k, 0], out[k, 1], out[k, 2] = fitted_position(which, d0 + t[k] / 86400.0, t[k] / 86400.0, c, 0)
    return out


def third_body_fit(epoch: Epoch | str) -> np.ndarray:
    """Per-run correction (N_FIT,) of the kernels' analytic series to erfa: for the Sun
    (entries 0-11) and the Moon (12-23) the cubic c0 + c1 tau + c2 tau^2 + c3 tau^3 (m, tau in
    days from the epoch, entries [4 powers x 3 axes]) least-squares fitted to (erfa - series) at
    the FIT_NODES Chebyshev nodes of [0, FIT_DAYS] (:func:`fitted_position`). (Until 2026-11-28: 49
    equally spaced nodes, 6x the erfa calls; the fits differ by <= 0.0001" (Sun) and 0.14" (Moon),
    and the Chebyshev fit's worst error against erfa over 23 epochs 1980-2050 is lower: Moon 0.24"
    instead of 0.38", Sun 0.006" both.)"""
    epoch = parse_epoch(epoch)
    sun, moon = _erfa_positions(epoch, _FIT_T)
    d0 = epoch.days_tt_since_j2000(0.0)
    out = []
    for which, exact in ((0, sun), (1, moon)):
        corr = exact - _many(which, d0, _FIT_T)
        out.append((_FIT_SOLVE @ corr).ravel())
    return np.concatenate(out)


FIT_NODES = 6  # erfa calls per fit (Chebyshev nodes; 6, 8 and 12 give the same worst error against erfa)
_FIT_T = 0.5 * FIT_DAYS * 86400.0 * (1.0 - np.cos(np.pi * (np.arange(FIT_NODES) + 0.5) / FIT_NODES))  # s
_FIT_SOLVE = np.linalg.pinv(np.vander(_FIT_T / 86400.0, 4, increasing=True))  # (4, FIT_NODES): least squares


@njit(cache=True, fastmath=False)
def fitted_position(which: int, d: float, tau: float, c: np.ndarray, k0: int):
    """Sun (``which`` = 0) or Moon (1) at ``d`` TT days from J2000, ``tau`` days after the
    run's epoch: the analytic series plus the cubic correction stored at c[k0:k0 + N_FIT]
    (:func:`third_body_fit`; all zeros: the series alone); tau clamped to [0, FIT_DAYS]."""
    x, y, z = sun_eci_kernel(d) if which == 0 else moon_eci_kernel(d)
    tau = min(max(tau, 0.0), FIT_DAYS)
    k = k0 + 12 * which
    x += c[k] + tau * (c[k + 3] + tau * (c[k + 6] + tau * c[k + 9]))
    y += c[k + 1] + tau * (c[k + 4] + tau * (c[k + 7] + tau * c[k + 10]))
    z += c[k + 2] + tau * (c[k + 5] + tau * (c[k + 8] + tau * c[k + 11]))
    return x, y, z
