"""Classical orbital elements <-> ECI state (elliptic orbits), anomalies, circular orbits.

Angles in radians, lengths in metres. Conversions follow Vallado, *Fundamentals of
Astrodynamics and Applications*, 4th ed., algorithms 9 (RV2COE) and 10 (COE2RV), with
atan2 forms for robustness. Singular cases of :func:`eci_to_elements`:
circular (ecc < 1e-11): argp = 0 and ``true_anomaly`` is the argument of latitude;
equatorial (sin(inc) < 1e-11): raan = 0 and angles are measured from the ECI x axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxops.core.constants import MU_EARTH, R_EARTH
from proxops.errors import input_error

_CIRCULAR_TOL = 1e-11
_EQUATORIAL_TOL = 1e-11


@dataclass(frozen=True)
class OrbitalElements:
    """Osculating classical elements (SI): ``sma`` m, ``ecc`` -, ``inc``, ``raan``,
    ``argp``, ``true_anomaly`` rad. Elliptic orbits only (0 <= ecc < 1)."""

    sma: float
    ecc: float
    inc: float
    raan: float
    argp: float
    true_anomaly: float

    def __post_init__(self) -> None:
        for name in ("sma", "ecc", "inc", "raan", "argp", "true_anomaly"):
            value = getattr(self, name)
            if not math.isfinite(float(value)):
                raise input_error(name, value, "must be a finite number")
        if self.sma <= 0:
            raise input_error("sma", self.sma, "must be > 0 (elliptic orbit)", "m")
        if not 0.0 <= self.ecc < 1.0:
            raise input_error("ecc", self.ecc, "must satisfy 0 <= ecc < 1 (elliptic orbit)")
        if not 0.0 <= self.inc <= math.pi:
            raise input_error("inc", self.inc, "must be in [0, pi]", "rad")

    @classmethod
    def from_deg(
        cls, sma: float, ecc: float, inc_deg: float, raan_deg: float, argp_deg: float, true_anomaly_deg: float
    ) -> "OrbitalElements":
        """Build from angles in degrees (config edge); ``sma`` in m."""
        return cls(
            float(sma),
            float(ecc),
            math.radians(inc_deg),
            math.radians(raan_deg),
            math.radians(argp_deg),
            math.radians(true_anomaly_deg),
        )

    @property
    def perigee_radius(self) -> float:
        """a (1 - e), m."""
        return self.sma * (1.0 - self.ecc)

    @property
    def semi_latus_rectum(self) -> float:
        """p = a (1 - e^2), m."""
        return self.sma * (1.0 - self.ecc**2)


def check_perigee_above_surface(elements: OrbitalElements, r_earth: float = R_EARTH, name: str = "orbit") -> None:
    """Raise ProxopsInputError if the perigee is at or below the Earth's surface."""
    rp = elements.perigee_radius
    if rp <= r_earth:
        raise input_error(
            f"{name} perigee altitude",
            round((rp - r_earth) / 1e3, 3),
            "must be above the Earth's surface (> 0 km); raise sma or lower ecc",
            "km",
        )


def orbital_period(sma: float, mu: float = MU_EARTH) -> float:
    """Keplerian period 2 pi sqrt(a^3 / mu), s."""
    return 2.0 * math.pi * math.sqrt(sma**3 / mu)


def circular_orbit(
    *,
    altitude: float | None = None,
    sma: float | None = None,
    inc: float = 0.0,
    raan: float = 0.0,
    arg_lat: float = 0.0,
    r_earth: float = R_EARTH,
) -> OrbitalElements:
    """Circular orbit from ``altitude`` (m above ``r_earth``) or ``sma`` (m); argp = 0 and
    the true anomaly equals the argument of latitude ``arg_lat`` (rad)."""
    if (altitude is None) == (sma is None):
        raise input_error("circular_orbit", f"altitude={altitude}, sma={sma}", "give exactly one of altitude or sma")
    a = r_earth + float(altitude) if sma is None else float(sma)
    if altitude is not None and altitude <= 0:
        raise input_error("altitude", altitude, "must be > 0", "m")
    return OrbitalElements(a, 0.0, float(inc), float(raan), 0.0, float(arg_lat))


def true_to_mean_anomaly(true_anomaly: float, ecc: float) -> float:
    """Mean anomaly M (rad, wrapped to [0, 2 pi)) from the true anomaly (elliptic)."""
    half = 0.5 * true_anomaly
    E = 2.0 * math.atan2(math.sqrt(1.0 - ecc) * math.sin(half), math.sqrt(1.0 + ecc) * math.cos(half))
    return (E - ecc * math.sin(E)) % (2.0 * math.pi)


def mean_to_true_anomaly(mean_anomaly: float, ecc: float, tol: float = 1e-14) -> float:
    """True anomaly (rad, in [0, 2 pi)) from the mean anomaly: Kepler's equation by Newton."""
    if not 0.0 <= ecc < 1.0:
        raise input_error("ecc", ecc, "must satisfy 0 <= ecc < 1")
    M = mean_anomaly % (2.0 * math.pi)
    E = M if ecc < 0.8 else math.pi
    for _ in range(50):
        dE = (E - ecc * math.sin(E) - M) / (1.0 - ecc * math.cos(E))
        E -= dE
        if abs(dE) < tol:
            break
    half = 0.5 * E
    nu = 2.0 * math.atan2(math.sqrt(1.0 + ecc) * math.sin(half), math.sqrt(1.0 - ecc) * math.cos(half))
    return nu % (2.0 * math.pi)


def _rot3(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot1(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def elements_to_eci(elements: OrbitalElements, mu: float = MU_EARTH) -> np.ndarray:
    """ECI state ``[r, v]`` (m, m/s) of osculating elements (Vallado alg. 10, COE2RV)."""
    el = elements
    p = el.semi_latus_rectum
    nu = el.true_anomaly
    r_pf = p / (1.0 + el.ecc * math.cos(nu)) * np.array([math.cos(nu), math.sin(nu), 0.0])
    v_pf = math.sqrt(mu / p) * np.array([-math.sin(nu), el.ecc + math.cos(nu), 0.0])
    R = _rot3(el.raan) @ _rot1(el.inc) @ _rot3(el.argp)
    return np.concatenate([R @ r_pf, R @ v_pf])


def eci_to_elements(state: np.ndarray, mu: float = MU_EARTH) -> OrbitalElements:
    """Osculating elements of an ECI state (Vallado alg. 9, RV2COE; see module doc for
    the circular/equatorial conventions). Raises ProxopsInputError for non-elliptic states."""
    s = np.asarray(state, dtype=float)
    if s.shape != (6,) or not np.all(np.isfinite(s)):
        raise input_error("state", s.tolist(), "must be a finite ECI state of length 6", "m, m/s")
    r, v = s[:3], s[3:]
    rn = float(np.linalg.norm(r))
    h = np.cross(r, v)
    hn = float(np.linalg.norm(h))
    if rn == 0.0 or hn == 0.0:
        raise input_error("state", s.tolist(), "needs r != 0 and r x v != 0 (rectilinear orbits unsupported)")
    energy = 0.5 * float(v @ v) - mu / rn
    if energy >= 0.0:
        raise input_error("state specific energy", energy, "must be < 0 (elliptic orbit)", "J/kg")
    sma = -mu / (2.0 * energy)
    e_vec = ((float(v @ v) - mu / rn) * r - float(r @ v) * v) / mu
    ecc = float(np.linalg.norm(e_vec))
    h_hat = h / hn
    inc = math.acos(max(-1.0, min(1.0, h_hat[2])))
    node = np.array([-h[1], h[0], 0.0])
    node_n = float(np.linalg.norm(node))
    equatorial = node_n <= _EQUATORIAL_TOL * hn
    if equatorial:
        raan = 0.0
        ref = np.array([1.0, 0.0, 0.0])
    else:
        raan = math.atan2(node[1], node[0]) % (2.0 * math.pi)
        ref = node / node_n

    def angle_from(a: np.ndarray, b: np.ndarray) -> float:
        """Angle from unit a to b measured about h_hat, in [0, 2 pi)."""
        return math.atan2(float(np.cross(a, b) @ h_hat), float(a @ b)) % (2.0 * math.pi)

    r_hat = r / rn
    if ecc < _CIRCULAR_TOL:
        ecc = 0.0
        argp = 0.0
        nu = angle_from(ref, r_hat)
    else:
        e_hat = e_vec / np.linalg.norm(e_vec)
        argp = angle_from(ref, e_hat)
        nu = angle_from(e_hat, r_hat)
    return OrbitalElements(sma, ecc, inc, raan, argp, nu)
