"""Earth's shadow: fraction of the solar disc visible from a spacecraft, and eclipse profiles.

Conical model (Montenbruck & Gill, *Satellite Orbits*, sec. 3.4.2): seen from the
spacecraft at ``r``, the Sun (radius R_S, at ``s = r_sun - r``) has apparent radius
a = asin(R_S/|s|) and the Earth (a sphere of radius R_E) b = asin(R_E/|r|); their
centres are c = angle(-r, s) apart. Then

* c >= a + b: full sunlight, 1;
* c <= b - a: umbra, 0;
* c <= a - b (a > b, only far from Earth): annular, 1 - b^2/a^2;
* otherwise penumbra: the overlap area of two discs in the small-angle (flat) geometry,
  x = (c^2 + a^2 - b^2) / (2c), y = sqrt(a^2 - x^2),
  A = a^2 acos(x/a) + b^2 acos((c - x)/b) - c y, fraction 1 - A / (pi a^2).

Cylindrical model: 0 when r . s_hat < 0 and the distance from the Sun line
|r - (r . s_hat) s_hat| < R_E, else 1 (no penumbra).

The Earth is a sphere of the equatorial radius (its oblateness moves LEO shadow
boundaries by up to ~ 2 s); atmospheric refraction and dimming are not modelled.
One kernel (:func:`shadow_factor`) on plain floats serves SRP inside the integrator;
:func:`illumination` is its vectorised numpy form. :func:`shadow_boundaries` gives the
signed distances to the boundaries where the factor stops being smooth (the event functions
at which the integrators restart: the conical factor is continuous with unbounded
derivatives there, the overlap area growing like depth^(3/2); the cylindrical one jumps).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from proxops.core.constants import J2_EARTH, MU_EARTH, R_EARTH
from proxops.environment.ephemeris import R_SUN, sun_position_eci
from proxops.environment.epochs import Epoch, parse_epoch
from proxops.environment.gravity import j2_argp_rate, j2_raan_rate
from proxops.errors import input_error
from proxops.frames.elements import OrbitalElements, mean_to_true_anomaly, orbital_period, true_to_mean_anomaly

MODELS = ("conical", "cylindrical")


@njit(cache=True, fastmath=False)
def _disc_angles(rx: float, ry: float, rz: float, sx: float, sy: float, sz: float, r_earth: float, r_sun: float):
    """Apparent radii of the Sun ``a`` and of the Earth ``b`` and the angle ``c`` between
    their centres (rad), seen from ``r`` (m) with the Sun at ``s`` (m) (module doc)."""
    dx, dy, dz = sx - rx, sy - ry, sz - rz
    dn = math.sqrt(dx * dx + dy * dy + dz * dz)
    rn = math.sqrt(rx * rx + ry * ry + rz * rz)
    a = math.asin(min(1.0, r_sun / dn))
    b = math.asin(min(1.0, r_earth / rn))
    cosc = -(rx * dx + ry * dy + rz * dz) / (rn * dn)
    c = math.acos(max(-1.0, min(1.0, cosc)))
    return a, b, c


@njit(cache=True, fastmath=False)
def _cylinder_distance(rx: float, ry: float, rz: float, sx: float, sy: float, sz: float, r_earth: float) -> float:
    """Cylindrical shadow: distance (m) from the shadow cylinder's wall, < 0 inside (behind
    the Earth, closer than ``r_earth`` to the Sun line), > 0 outside (r_earth when sunward)."""
    sn = math.sqrt(sx * sx + sy * sy + sz * sz)
    proj = (rx * sx + ry * sy + rz * sz) / sn
    if proj >= 0.0:
        return r_earth
    px = rx - proj * sx / sn
    py = ry - proj * sy / sn
    pz = rz - proj * sz / sn
    return math.sqrt(px * px + py * py + pz * pz) - r_earth


@njit(cache=True, fastmath=False)
def shadow_boundaries(
    rx: float, ry: float, rz: float, sx: float, sy: float, sz: float, r_earth: float, r_sun: float, conical: bool
):
    """Event functions of the shadow at ECI position ``r`` (m), Sun at ``s`` (m): the pair
    ``(g_penumbra, g_umbra)``, each changing sign exactly where :func:`shadow_factor` stops
    being smooth. Conical (rad): g_penumbra = c - (a + b) (> 0: full sunlight),
    g_umbra = c - (b - a) (> 0: outside the umbra; the annular branch needs a > b, i.e. more
    than ~1.4e9 m from the Earth, and has no event). Cylindrical (m): both the signed
    distance from the shadow cylinder's wall (> 0: lit)."""
    if not conical:
        g = _cylinder_distance(rx, ry, rz, sx, sy, sz, r_earth)
        return g, g
    a, b, c = _disc_angles(rx, ry, rz, sx, sy, sz, r_earth, r_sun)
    return c - (a + b), c - (b - a)


@njit(cache=True, fastmath=False)
def shadow_factor(
    rx: float, ry: float, rz: float, sx: float, sy: float, sz: float, r_earth: float, r_sun: float, conical: bool
) -> float:
    """Visible fraction of the solar disc in [0, 1] at spacecraft ECI position ``r`` (m) with
    the Sun at ECI ``s`` (m, geocentric). Conical (umbra/penumbra) or cylindrical model."""
    if not conical:
        return 0.0 if _cylinder_distance(rx, ry, rz, sx, sy, sz, r_earth) < 0.0 else 1.0
    a, b, c = _disc_angles(rx, ry, rz, sx, sy, sz, r_earth, r_sun)
    if c >= a + b:
        return 1.0
    if c <= b - a:
        return 0.0
    if c <= a - b:
        return 1.0 - (b * b) / (a * a)
    x = (c * c + a * a - b * b) / (2.0 * c)
    y = math.sqrt(max(0.0, a * a - x * x))
    area = a * a * math.acos(max(-1.0, min(1.0, x / a))) + b * b * math.acos(max(-1.0, min(1.0, (c - x) / b))) - c * y
    return min(1.0, max(0.0, 1.0 - area / (math.pi * a * a)))


@njit(cache=True)
def _illumination_many(r, s, r_earth, r_sun, conical):
    n = r.shape[0]
    out = np.empty(n)
    for k in range(n):
        out[k] = shadow_factor(r[k, 0], r[k, 1], r[k, 2], s[k, 0], s[k, 1], s[k, 2], r_earth, r_sun, conical)
    return out


def _check_model(model: str) -> bool:
    if model not in MODELS:
        raise input_error("eclipse model", model, "must be 'conical' or 'cylindrical'")
    return model == "conical"


def illumination(
    r_sc_eci: np.ndarray,
    r_sun_eci: np.ndarray,
    model: str = "conical",
    r_earth: float = R_EARTH,
    r_sun: float = R_SUN,
) -> np.ndarray:
    """Fraction (n,) of the solar disc visible from spacecraft positions ``r_sc_eci`` (n, 3) m
    with the geocentric Sun at ``r_sun_eci`` (n, 3) or (3,) m: 1 sunlight, 0 umbra.
    ``model="cylindrical"`` gives 0/1 only."""
    conical = _check_model(model)
    r = np.ascontiguousarray(np.atleast_2d(np.asarray(r_sc_eci, dtype=float)))
    s = np.asarray(r_sun_eci, dtype=float)
    s = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(s), r.shape))
    if r.ndim != 2 or r.shape[1] != 3:
        raise input_error("r_sc_eci shape", r.shape, "must be (n, 3)", "m")
    return _illumination_many(r, s, float(r_earth), float(r_sun), conical)


def kepler_positions(elements: OrbitalElements, t_s: np.ndarray, j2_mean: bool = False, mu: float = MU_EARTH):
    """ECI positions (n, 3) m of a Keplerian orbit (or one whose RAAN, argp and mean
    anomaly drift at the secular J2 rates if ``j2_mean``) at ``t_s`` s after the elements."""
    t = np.asarray(t_s, dtype=float)
    el = elements
    n = math.sqrt(mu / el.sma**3)
    raan = np.full_like(t, el.raan)
    argp = np.full_like(t, el.argp)
    m_rate = n
    if j2_mean:
        raan = raan + j2_raan_rate(el.sma, el.ecc, el.inc) * t
        argp = argp + j2_argp_rate(el.sma, el.ecc, el.inc) * t
        p = el.semi_latus_rectum
        eta = math.sqrt(1.0 - el.ecc**2)
        # secular mean-anomaly rate (Vallado eq. 9-41): n [1 + 3/4 J2 (Re/p)^2 eta (2 - 3 sin^2 i)]
        m_rate = n * (1.0 + 0.75 * J2_EARTH * (R_EARTH / p) ** 2 * eta * (2.0 - 3.0 * math.sin(el.inc) ** 2))
    M = true_to_mean_anomaly(el.true_anomaly, el.ecc) + m_rate * t
    nu = np.array([mean_to_true_anomaly(float(mk), el.ecc) for mk in np.atleast_1d(M)]) if el.ecc > 0 else M
    p = el.semi_latus_rectum
    rad = p / (1.0 + el.ecc * np.cos(nu))
    u = argp + nu
    cO, sO = np.cos(raan), np.sin(raan)
    ci, si = math.cos(el.inc), math.sin(el.inc)
    cu, su = np.cos(u), np.sin(u)
    return np.stack([rad * (cO * cu - sO * su * ci), rad * (sO * cu + cO * su * ci), rad * su * si], axis=-1)


def eclipse_profile(
    elements: OrbitalElements,
    epoch: Epoch | str,
    n_per_orbit: int = 1000,
    n_orbits: float = 1.0,
    model: str = "conical",
    j2_mean: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Illumination profile (Wijayatunga et al. sec. 3.1.1, eta_ecl, 1000 points per
    orbit) of the orbit ``elements`` (osculating at ``epoch``): ``(t_s, illum)`` with
    ``t_s`` s after the epoch on a uniform grid of ``n_per_orbit`` points per Keplerian
    period over ``n_orbits`` periods (both ends included) and ``illum`` in [0, 1]
    (1 sunlight). Keplerian motion, or J2 secular drift with ``j2_mean``."""
    epoch = parse_epoch(epoch)
    conical = _check_model(model)
    if int(n_per_orbit) < 2:
        raise input_error("n_per_orbit", n_per_orbit, "must be >= 2")
    if not (float(n_orbits) > 0 and math.isfinite(float(n_orbits))):
        raise input_error("n_orbits", n_orbits, "must be finite and > 0")
    period = orbital_period(elements.sma)
    n_samples = int(round(n_per_orbit * n_orbits)) + 1
    t = np.linspace(0.0, n_orbits * period, n_samples)
    r = np.ascontiguousarray(kepler_positions(elements, t, j2_mean))
    s = np.ascontiguousarray(sun_position_eci(epoch, t))
    return t, _illumination_many(r, s, R_EARTH, R_SUN, conical)
