"""Earth orientation (ECI = GCRF axes -> Earth-fixed ITRF) and WGS-84 geodetic coordinates.

Rotation model (IERS Conventions 2010, ch. 5, the equinox-based form, through ``pyerfa``,
the IAU SOFA library; nothing hand-written):

    r_itrf = W R3(theta(t)) NPB r_gcrf,     theta(t) = GAST(epoch) + w_era t

* NPB: frame bias, IAU 2006 precession and IAU 2000A nutation (``erfa.pnm06a``; 1365 terms;
  the celestial pole offsets dX, dY, < 0.5 mas, are not applied).
* GAST: Greenwich apparent sidereal time, IAU 2006 (``erfa.gst06``) from UT1 = UTC + (UT1 - UTC).
* W: polar motion (x_p, y_p) with the TIO locator s' (``erfa.pom00``, ``erfa.sp00``).
* UT1 - UTC and x_p, y_p: 0 (UT1 = UTC, CIP = ITRF pole) unless given; ``truth.earth_orientation
  = "iers"`` takes them from the shipped IERS table (:func:`proxops.environment.spaceweather.eop_at`).
* NPB and W are frozen at the epoch for a run and the Earth turns at the rate of the Earth
  rotation angle, w_era = 1.00273781191135448 * 2 pi / 86400 rad/s, about the frozen pole:
  with NPB = R3(-EO) C (C: GCRS -> CIRS, no rotation about the pole), R3(GAST + w_era t) NPB =
  R3(ERA(t)) C, so what is left out is the motion of the pole in the sky (precession and
  nutation, < 0.15 arcsec per day; tests/test_earth_orientation.py measures it over 3 h and 1 day)
  and of the polar motion (< 2 mas per day).

Size of what is left out for the gravity field at LEO: a tilt of the pole by 0.15" (7e-7 rad)
changes the J2 acceleration by ~1e-8 m/s^2 absolute and ~3e-12 m/s^2 between two
spacecraft 2 km apart (< 0.1 mm after one day).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import erfa
import numpy as np
from numba import njit

from proxops.environment.epochs import SECONDS_PER_DAY, Epoch, parse_epoch

ARCSEC = math.pi / (180.0 * 3600.0)
OMEGA_SIDEREAL = 1.00273781191135448 * 2.0 * math.pi / 86400.0  # rad/s, Earth rotation angle rate per UT1 second
WGS84_A = 6378137.0  # m
WGS84_F = 1.0 / 298.257223563


def _r3(a: float) -> np.ndarray:
    """Frame rotation about z (Vallado ROT3)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def gmst(days_ut1: float) -> float:
    """Greenwich mean sidereal time (rad, [0, 2 pi)), IAU 1982; ``days_ut1`` from J2000 (UT1)."""
    Tu = days_ut1 / 36525.0
    sec = 67310.54841 + (876600.0 * 3600.0 + 8640184.812866) * Tu + 0.093104 * Tu**2 - 6.2e-6 * Tu**3
    return (sec % 86400.0) / 86400.0 * 2.0 * math.pi


@dataclass(frozen=True)
class EarthRotation:
    """Frozen bias-precession-nutation ``npm`` (3, 3) (GCRF -> true of date), GAST at the epoch
    ``theta0`` (rad), the rotation rate ``omega`` (rad/s) and the polar motion ``polar`` (3, 3)
    (true of date Earth-fixed -> ITRF): r_itrf = polar R3(theta0 + omega t) npm r."""

    npm: np.ndarray
    theta0: float
    omega: float = OMEGA_SIDEREAL
    polar: np.ndarray = field(default_factory=lambda: np.eye(3))

    @property
    def pole_eci(self) -> np.ndarray:
        """Unit vector of the Earth's rotation axis (celestial intermediate pole of date) in ECI."""
        return self.npm[2].copy()

    def matrix(self, t_s: float) -> np.ndarray:
        """ECI -> Earth-fixed (ITRF) rotation matrix at ``t_s`` s after the epoch."""
        return self.polar @ _r3(self.theta0 + self.omega * float(t_s)) @ self.npm

    def to_ecef(self, t_s, r_eci: np.ndarray) -> np.ndarray:
        """Earth-fixed positions (n, 3) of ECI positions (n, 3) at times ``t_s`` (n,) or scalar."""
        r = np.atleast_2d(np.asarray(r_eci, dtype=float))
        t = np.broadcast_to(np.asarray(t_s, dtype=float), (r.shape[0],))
        q = r @ self.npm.T
        th = self.theta0 + self.omega * t
        c, s = np.cos(th), np.sin(th)
        return np.stack([c * q[:, 0] + s * q[:, 1], -s * q[:, 0] + c * q[:, 1], q[:, 2]], axis=-1) @ self.polar.T

    def to_eci(self, t_s, r_ecef: np.ndarray) -> np.ndarray:
        """ECI vectors (n, 3) of Earth-fixed vectors (n, 3) at times ``t_s`` (n,) or scalar (the
        inverse of :meth:`to_ecef`)."""
        v = np.atleast_2d(np.asarray(r_ecef, dtype=float)) @ self.polar
        t = np.broadcast_to(np.asarray(t_s, dtype=float), (v.shape[0],))
        th = self.theta0 + self.omega * t
        c, s = np.cos(th), np.sin(th)
        return np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]], -1) @ self.npm


def earth_rotation(epoch: Epoch | str, ut1_utc_s: float = 0.0, xp_arcsec: float = 0.0,
                   yp_arcsec: float = 0.0) -> EarthRotation:
    """Earth orientation at ``epoch`` (see module doc for the model and what it neglects):
    ``ut1_utc_s`` UT1 - UTC (s), ``xp_arcsec``, ``yp_arcsec`` the pole coordinates (arcsec), all
    0 by default; the IERS values from :func:`proxops.environment.spaceweather.eop_at` with
    ``truth.earth_orientation = "iers"``."""
    epoch = parse_epoch(epoch)
    tt1, tt2 = epoch.jd_utc_day, epoch.jd_utc_frac + epoch.tt_minus_utc_s / SECONDS_PER_DAY
    ut2 = epoch.jd_utc_frac + float(ut1_utc_s) / SECONDS_PER_DAY
    npb = erfa.pnm06a(tt1, tt2)
    gast = float(erfa.gst06(epoch.jd_utc_day, ut2, tt1, tt2, npb))
    polar = erfa.pom00(float(xp_arcsec) * ARCSEC, float(yp_arcsec) * ARCSEC, float(erfa.sp00(tt1, tt2)))
    return EarthRotation(np.ascontiguousarray(npb), gast % (2.0 * math.pi), OMEGA_SIDEREAL, np.ascontiguousarray(polar))


def teme_to_eci_matrix(epoch: Epoch | str) -> np.ndarray:
    """Rotation (3, 3) from TEME of ``epoch`` (the frame of SGP4 states: true equator, mean
    equinox of date) to this module's ECI (GCRF axes):

        r_eci = NPB^T R3(-(GAST - GMST82)) r_teme

    (Vallado 4th ed. sec. 3.7.4, eqs. 3-90/3-91, with this module's NPB and GAST). It follows from
    the two routes to the pseudo-Earth-fixed frame, r_pef = R3(GMST82) r_teme (the SGP4 convention,
    GMST of IAU 1982 with UT1 = UTC) and r_pef = R3(GAST) NPB r_eci (:func:`earth_rotation`
    without polar motion): a TLE state keeps its Earth-fixed position exactly. TEME is taken as
    inertial at the epoch: v_eci = M v_teme (tests/test_tle.py compares with astropy's TEME -> GCRS)."""
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
