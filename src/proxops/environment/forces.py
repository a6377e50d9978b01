"""Perturbing accelerations that add up: atmospheric drag (NRLMSISE-00 via ``pymsis``),
Sun and Moon third body, cannonball solar radiation pressure. Each is a numba kernel on
plain floats (SI, ECI axes) behind a small friendly class (hapsira's pattern).

* Drag (Wijayatunga et al. eq. 5, with the co-rotating atmosphere):
  a = -1/2 rho (C_D A / m) |v_r| v_r,  v_r = v - w_E x r  (w_E along the Earth's pole).
* Third body (Montenbruck & Gill, *Satellite Orbits*, eq. 3.37):
  a = GM_b [(s - r)/|s - r|^3 - s/|s|^3],  s = geocentric body position.
* SRP, cannonball (M&G eq. 3.75 with a spherical spacecraft):
  a = -nu P_sun C_R (A / m) (AU / |s - r|)^2 (s - r)/|s - r|,  nu = shadow factor
  (:mod:`proxops.environment.eclipse`), P_sun = 4.56e-6 N/m^2 at 1 AU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from proxops.core.constants import OMEGA_EARTH
from proxops.environment.earth import EarthRotation, geodetic_many
from proxops.environment.epochs import Epoch, parse_epoch
from proxops.errors import input_error

P_SUN = 4.56e-6  # N/m^2, solar radiation pressure at 1 AU (M&G sec. 3.4)


# ----------------------------------------------------------------------------- kernels
@njit(cache=True, fastmath=False)
def accel_drag(
    rx: float, ry: float, rz: float, vx: float, vy: float, vz: float, rho: float, bc: float,
    wx: float, wy: float, wz: float,
):  # fmt: skip
    """Drag acceleration (m/s^2) with density ``rho`` (kg/m^3), ``bc = C_D A / m`` (m^2/kg)
    and the Earth's rotation vector ``w`` (rad/s, ECI) for the co-rotating atmosphere."""
    ux = vx - (wy * rz - wz * ry)
    uy = vy - (wz * rx - wx * rz)
    uz = vz - (wx * ry - wy * rx)
    k = -0.5 * rho * bc * math.sqrt(ux * ux + uy * uy + uz * uz)
    return k * ux, k * uy, k * uz


@njit(cache=True, fastmath=False)
def accel_third_body(rx: float, ry: float, rz: float, sx: float, sy: float, sz: float, gm: float):
    """Third-body perturbation (m/s^2) of a body GM (m^3/s^2) at geocentric ``s`` (m)."""
    dx, dy, dz = sx - rx, sy - ry, sz - rz
    d2 = dx * dx + dy * dy + dz * dz
    s2 = sx * sx + sy * sy + sz * sz
    kd = gm / (d2 * math.sqrt(d2))
    ks = gm / (s2 * math.sqrt(s2))
    return kd * dx - ks * sx, kd * dy - ks * sy, kd * dz - ks * sz


@njit(cache=True, fastmath=False)
def accel_srp(rx: float, ry: float, rz: float, sx: float, sy: float, sz: float, cr_am: float, nu: float, au: float):
    """Cannonball SRP (m/s^2): ``cr_am = C_R A / m`` (m^2/kg), shadow factor ``nu`` in [0, 1]."""
    dx, dy, dz = rx - sx, ry - sy, rz - sz  # Sun -> spacecraft
    d2 = dx * dx + dy * dy + dz * dz
    k = nu * P_SUN * cr_am * au * au / (d2 * math.sqrt(d2))
    return k * dx, k * dy, k * dz


# ----------------------------------------------------------------------------- friendly layer
@dataclass(frozen=True)
class Spacecraft:
    """Drag and SRP properties: ``mass_kg`` > 0, ``area_m2`` >= 0 (cross-section),
    ``cd`` in (0, 5], ``cr`` in [0, 2] (1 absorbing, 2 specular mirror)."""

    mass_kg: float = 500.0
    area_m2: float = 2.0
    cd: float = 2.2
    cr: float = 1.3
    name: str = "spacecraft"

    def __post_init__(self) -> None:
        p = f"{self.name}."
        for key in ("mass_kg", "area_m2", "cd", "cr"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise input_error(p + key, value, "must be a finite number")
        if not self.mass_kg > 0:
            raise input_error(p + "mass_kg", self.mass_kg, "must be > 0", "kg")
        if not self.area_m2 >= 0:
            raise input_error(p + "area_m2", self.area_m2, "must be >= 0", "m^2")
        if not 0 < self.cd <= 5:
            raise input_error(p + "cd", self.cd, "drag coefficient must be in (0, 5]")
        if not 0 <= self.cr <= 2:
            raise input_error(p + "cr", self.cr, "radiation-pressure coefficient must be in [0, 2]")

    @property
    def ballistic(self) -> float:
        """C_D A / m (m^2/kg)."""
        return self.cd * self.area_m2 / self.mass_kg

    @property
    def srp_factor(self) -> float:
        """C_R A / m (m^2/kg)."""
        return self.cr * self.area_m2 / self.mass_kg


@dataclass(frozen=True)
class SpaceWeather:
    """NRLMSISE-00 drivers: daily F10.7 of the previous day and its 81-day mean (sfu) and
    the daily Ap (the 3-hour Ap history is taken equal to it). Defaults: moderate activity."""

    f107: float = 150.0
    f107a: float = 150.0
    ap: float = 15.0

    def __post_init__(self) -> None:
        for key, lo, hi, unit in (("f107", 50.0, 400.0, "sfu"), ("f107a", 50.0, 400.0, "sfu"), ("ap", 0.0, 400.0, "")):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
                raise input_error(f"truth.{key}", value, f"must be in [{lo:g}, {hi:g}] (NRLMSISE-00 inputs)", unit)

    def drivers(self, dates: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(f107 (n,), f107a (n,), ap (n, 7)) at ``dates`` (n,): the constants (time-varying:
        :class:`proxops.environment.spaceweather.WeatherHistory`)."""
        n = np.size(dates)
        return np.full(n, self.f107), np.full(n, self.f107a), np.full((n, 7), self.ap)


class Atmosphere:
    """NRLMSISE-00 mass density (kg/m^3) through ``pymsis`` (offline; ``version=0``)."""

    def __init__(self, epoch: Epoch | str, rotation: EarthRotation, weather=None) -> None:
        """``weather``: :class:`SpaceWeather` (constants) or anything with its ``drivers(dates)``."""
        self.epoch = parse_epoch(epoch)
        self.rotation = rotation
        self.weather = weather or SpaceWeather()
        self._t0 = np.datetime64(_iso_no_zone(self.epoch.iso), "ns")

    def density(self, t_s: np.ndarray, r_eci: np.ndarray) -> np.ndarray:
        """Density (n,) at ECI positions (n, 3) m and times ``t_s`` (n,) s after the epoch."""
        r = np.atleast_2d(np.asarray(r_eci, dtype=float))
        t = np.broadcast_to(np.asarray(t_s, dtype=float), (r.shape[0],))
        return self.density_geodetic(t, geodetic_many(self.rotation.to_ecef(t, r)))

    def density_geodetic(self, t_s: np.ndarray, geo: np.ndarray) -> np.ndarray:
        """Density (n,) at WGS-84 geodetic points ``geo`` (n, 3) [lat rad, lon rad, h m] and times ``t_s`` (n,)
        s after the epoch (one pymsis call)."""
        import pymsis

        dates = self.dates(t_s)
        n = geo.shape[0]
        out = pymsis.calculate(dates, np.degrees(geo[:, 1]), np.degrees(geo[:, 0]), geo[:, 2] / 1e3,
                               *self.weather.drivers(dates), version=0)  # fmt: skip
        return np.asarray(out[..., 0], dtype=float).reshape(n)

    def dates(self, t_s) -> np.ndarray:
        """UTC dates (datetime64[ns]) of the times ``t_s`` (s after the epoch)."""
        return self._t0 + (np.asarray(t_s, dtype=float) * 1e9).astype("timedelta64[ns]")

    @property
    def omega_eci(self) -> np.ndarray:
        """Earth rotation vector (rad/s) in ECI, along the true pole of date."""
        return OMEGA_EARTH * self.rotation.pole_eci


def _iso_no_zone(iso: str) -> str:
    text = iso.replace(" ", "T")
    for suffix in ("Z", "+00:00", "+0000", "UTC"):
        if text.endswith(suffix):
            text = text[: -len(suffix)]
    return text
