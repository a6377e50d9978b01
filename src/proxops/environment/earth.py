"""Earth orientation (ECI = GCRF/J2000 axes -> Earth-fixed) and WGS-84 geodetic coordinates.

Rotation model (Vallado, *Fundamentals of Astrodynamics and Applications*, 4th ed.,
sec. 3.7, the IAU-76/FK5 reduction, truncated):

    r_ecef = R3(theta(t)) N P r_eci,     theta(t) = GAST(epoch) + w_sid t

* P: IAU 1976 precession (Lieske's zeta, theta, z; Vallado eq. 3-88).
* N: IAU 1980 nutation, the four largest terms (Meeus, *Astronomical Algorithms*, ch. 22:
  |error| < 0.5" in longitude, < 0.1" in obliquity), with the mean obliquity of date.
* GAST = GMST (IAU 1982, Vallado eq. 3-47, UT1 ~ UTC) + dpsi cos(eps).
* P and N are frozen at the epoch for a run (they drift by < 0.2" per day); the Earth
  turns at the mean sidereal rate w_sid = 1.00273781191135448 * 2 pi / 86400 rad/s about
  the frozen pole, so theta(t) equals GMST(t) + equation of equinoxes exactly.
* Neglected: polar motion (< 0.5" = 2.4e-6 rad); UT1 - UTC (< 0.9 s = 6.6e-5 rad about the
  pole; it only moves tesseral terms and the atmosphere, common to both spacecraft) unless
  given (``ut1_utc_s``; ``truth.earth_orientation = "iers"`` takes it from the shipped IERS table).

Size of what is left out for the gravity field at LEO: a tilt of the pole by 2.4e-6 rad
changes the J2 acceleration by ~4e-8 m/s^2 absolute and ~1e-11 m/s^2 between two
spacecraft 2 km apart (< 0.1 mm after one orbit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from proxops.environment.epochs import Epoch, parse_epoch

ARCSEC = math.pi / (180.0 * 3600.0)
OMEGA_SIDEREAL = 1.00273781191135448 * 2.0 * math.pi / 86400.0  # rad/s, GMST rate per UT1 second
WGS84_A = 6378137.0  # m
WGS84_F = 1.0 / 298.257223563


def _r1(a: float) -> np.ndarray:
    """Frame rotation about x (Vallado ROT1)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])


def _r2(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def _r3(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def precession_matrix(T: float) -> np.ndarray:
    """IAU 1976 precession, J2000 mean equator/equinox -> mean of date; T = TT centuries."""
    zeta = (2306.2181 * T + 0.30188 * T**2 + 0.017998 * T**3) * ARCSEC
    theta = (2004.3109 * T - 0.42665 * T**2 - 0.041833 * T**3) * ARCSEC
    z = (2306.2181 * T + 1.09468 * T**2 + 0.018203 * T**3) * ARCSEC
    return _r3(-z) @ _r2(theta) @ _r3(-zeta)


def nutation(T: float) -> tuple[float, float, float]:
    """(dpsi, deps, mean obliquity) in rad: IAU 1980, four largest terms (Meeus ch. 22)."""
    eps0 = (84381.448 - 46.8150 * T - 0.00059 * T**2 + 0.001813 * T**3) * ARCSEC
    om = math.radians(125.04452 - 1934.136261 * T)
    L = math.radians(280.4665 + 36000.7698 * T)
    Lp = math.radians(218.3165 + 481267.8813 * T)
    dpsi = (-17.20 * math.sin(om) - 1.32 * math.sin(2 * L) - 0.23 * math.sin(2 * Lp) + 0.21 * math.sin(2 * om)) * ARCSEC
    deps = (9.20 * math.cos(om) + 0.57 * math.cos(2 * L) + 0.10 * math.cos(2 * Lp) - 0.09 * math.cos(2 * om)) * ARCSEC
    return dpsi, deps, eps0


def gmst(days_ut1: float) -> float:
    """Greenwich mean sidereal time (rad, [0, 2 pi)), IAU 1982; ``days_ut1`` from J2000 (UT1)."""
    Tu = days_ut1 / 36525.0
    sec = 67310.54841 + (876600.0 * 3600.0 + 8640184.812866) * Tu + 0.093104 * Tu**2 - 6.2e-6 * Tu**3
    return (sec % 86400.0) / 86400.0 * 2.0 * math.pi


@dataclass(frozen=True)
class EarthRotation:
    """Frozen precession-nutation ``npm`` (3, 3) (ECI -> true of date), GAST at the epoch
    ``theta0`` (rad) and the rotation rate ``omega`` (rad/s): r_ecef = R3(theta0 + omega t) npm r."""

    npm: np.ndarray
    theta0: float
    omega: float = OMEGA_SIDEREAL

    @property
    def pole_eci(self) -> np.ndarray:
        """Unit vector of the Earth's rotation axis (true pole of date) in ECI."""
        return self.npm[2].copy()

    def matrix(self, t_s: float) -> np.ndarray:
        """ECI -> Earth-fixed rotation matrix at ``t_s`` s after the epoch."""
        return _r3(self.theta0 + self.omega * float(t_s)) @ self.npm

    def to_ecef(self, t_s, r_eci: np.ndarray) -> np.ndarray:
        """Earth-fixed positions (n, 3) of ECI positions (n, 3) at times ``t_s`` (n,) or scalar."""
        r = np.atleast_2d(np.asarray(r_eci, dtype=float))
        t = np.broadcast_to(np.asarray(t_s, dtype=float), (r.shape[0],))
        q = r @ self.npm.T
        th = self.theta0 + self.omega * t
        c, s = np.cos(th), np.sin(th)
        return np.stack([c * q[:, 0] + s * q[:, 1], -s * q[:, 0] + c * q[:, 1], q[:, 2]], axis=-1)


def earth_rotation(epoch: Epoch | str, ut1_utc_s: float = 0.0) -> EarthRotation:
    """Earth orientation at ``epoch`` (see module doc for the model and what it neglects);
    ``ut1_utc_s``: UT1 - UTC (s) at the epoch (0: UT1 = UTC; the IERS value from
    :func:`proxops.environment.spaceweather.eop_at` with ``truth.earth_orientation = "iers"``)."""
    epoch = parse_epoch(epoch)
    T = epoch.days_tt_since_j2000() / 36525.0
    dpsi, deps, eps0 = nutation(T)
    N = _r1(-(eps0 + deps)) @ _r3(-dpsi) @ _r1(eps0)
    gast = gmst(epoch.days_ut1_since_j2000() + float(ut1_utc_s) / 86400.0) + dpsi * math.cos(eps0 + deps)
    return EarthRotation(N @ precession_matrix(T), gast % (2.0 * math.pi))


def teme_to_eci_matrix(epoch: Epoch | str) -> np.ndarray:
    """Rotation (3, 3) from TEME of ``epoch`` (the frame of SGP4 states: true equator, mean
    equinox of date) to this module's ECI, in the Earth model above:

        r_eci = (N P)^T R3(-eqeq) r_teme,    eqeq = GAST - GMST = dpsi cos(eps)

    (Vallado 4th ed. sec. 3.7.4, eq. 3-91, with this module's truncated N and P). It follows from
    the two routes to the Earth-fixed frame, r_pef = R3(GMST) r_teme (the SGP4 convention,
    Vallado eq. 3-90) and r_ecef = R3(GAST) N P r_eci (:func:`earth_rotation`): a TLE state keeps
    its Earth-fixed position (and so its latitude, longitude and height) exactly, and its
    orientation to the truth's equator. Against the full IAU-80 nutation the rotation differs
    by the truncation of N (< 1.3 arcsec, ~40 m at 7000 km; tests/test_tle.py compares with
    astropy's TEME -> GCRS). TEME is taken as inertial at the epoch: v_eci = M v_teme."""
    epoch = parse_epoch(epoch)
    rot = earth_rotation(epoch)
    eqeq = rot.theta0 - gmst(epoch.days_ut1_since_j2000())
    return rot.npm.T @ _r3(-eqeq)


@njit(cache=True, fastmath=False)
def _latitude_height(x: float, y: float, z: float, passes: int):
    """WGS-84 geodetic (latitude rad, height m) by ``passes`` of the fixed-point iteration
    lat = atan2(z + e^2 N sin(lat), p) (contraction ~e^2 per pass), then
    h = p cos(lat) + z sin(lat) - a sqrt(1 - e^2 sin^2(lat))."""
    a = WGS84_A
    e2 = WGS84_F * (2.0 - WGS84_F)
    p = math.sqrt(x * x + y * y)
    lat = math.atan2(z, p * (1.0 - e2))
    for _ in range(passes):
        s = math.sin(lat)
        N = a / math.sqrt(1.0 - e2 * s * s)
        lat = math.atan2(z + e2 * N * s, p)
    s = math.sin(lat)
    return lat, p * math.cos(lat) + z * s - a * math.sqrt(1.0 - e2 * s * s)


@njit(cache=True, fastmath=False)
def geodetic(x: float, y: float, z: float):
    """WGS-84 geodetic (latitude rad, longitude rad, height m) of an Earth-fixed position:
    6 passes of the latitude iteration (< 1e-12 rad)."""
    lat, h = _latitude_height(x, y, z, 6)
    return lat, math.atan2(y, x), h


@njit(cache=True, fastmath=False)
def geodetic_height(x: float, y: float, z: float) -> float:
    """WGS-84 geodetic height (m) of an Earth-fixed position: :func:`geodetic`'s iteration
    with 2 passes instead of 6 and no longitude (the drag's hot path: twice per right-hand
    side). The height is stationary in the latitude (it is the distance along the normal), so
    its error is ~ r dlat^2 / 2: after 2 passes (dlat ~ e^4 * 3e-4 rad at 500 km) < 1e-8 m
    from 0 to 2000 km height (tests/test_environment_forces.py)."""
    return _latitude_height(x, y, z, 2)[1]


def geodetic_many(r_ecef: np.ndarray) -> np.ndarray:
    """(n, 3) geodetic [lat rad, lon rad, h m] of Earth-fixed positions (n, 3)."""
    r = np.atleast_2d(np.asarray(r_ecef, dtype=float))
    return np.array([geodetic(p[0], p[1], p[2]) for p in r])


def geodetic_to_ecef(lat: float, lon: float, h: float) -> np.ndarray:
    """Earth-fixed position (m) of WGS-84 geodetic coordinates (closed form)."""
    e2 = WGS84_F * (2.0 - WGS84_F)
    N = WGS84_A / math.sqrt(1.0 - e2 * math.sin(lat) ** 2)
    return np.array(
        [(N + h) * math.cos(lat) * math.cos(lon), (N + h) * math.cos(lat) * math.sin(lon), (N * (1 - e2) + h) * math.sin(lat)]
    )
