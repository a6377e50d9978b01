"""Numba kernels for two-body + J2 gravity and Encke differential gravity (SI units).

Scalar kernels return 3-tuples (no heap allocation inside integrator loops); the
``*_vec`` wrappers take and return 3-element numpy arrays.

Gravity model: point mass + J2 zonal harmonic (standard form, e.g. Vallado,
*Fundamentals of Astrodynamics and Applications*, 4th ed., ch. 8; the signs are
checked in tests by energy conservation, a = -grad V):

    a = -mu r / r^3 - 3/2 J2 mu Re^2 / r^5 [x (1 - 5 z^2/r^2), y (1 - 5 z^2/r^2), z (3 - 5 z^2/r^2)]
    V = -mu / r + mu J2 Re^2 / (2 r^3) (3 z^2/r^2 - 1),   a = -grad V

Differential gravity (Encke): for a chaser at ``r_t + dr`` the two-body part of
``g(r_t + dr) - g(r_t)`` is evaluated with Battin's f(q) (Battin, *An Introduction to
the Mathematics and Methods of Astrodynamics*, Encke's method; written here in the
form f = 1 - (r_c/r_t)^3) so that no two 7000 km vectors are subtracted:

    q = (2 r_t . dr + dr . dr) / r_t^2           (r_c^2 = r_t^2 (1 + q))
    f = 1 - (1 + q)^{3/2} = -q (3 + 3 q + q^2) / (1 + (1 + q)^{3/2})
    g(r_c) - g(r_t) = -mu / r_c^3 (dr + f r_t)

The J2 part is subtracted directly: its magnitude is ~1e-2 m/s^2, so the rounding
error of the difference is ~1e-18 m/s^2 (< 1e-10 m after one LEO orbit).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, fastmath=False)
def accel_twobody(x: float, y: float, z: float, mu: float):
    """Point-mass acceleration -mu r / r^3 (m/s^2) as a tuple."""
    r2 = x * x + y * y + z * z
    k = -mu / (r2 * math.sqrt(r2))
    return k * x, k * y, k * z


@njit(cache=True, fastmath=False)
def accel_j2(x: float, y: float, z: float, mu: float, j2: float, re: float):
    """J2 zonal perturbing acceleration (m/s^2) as a tuple."""
    r2 = x * x + y * y + z * z
    r = math.sqrt(r2)
    k = -1.5 * j2 * mu * re * re / (r2 * r2 * r)
    s = 5.0 * z * z / r2
    return k * x * (1.0 - s), k * y * (1.0 - s), k * z * (3.0 - s)


@njit(cache=True, fastmath=False)
def accel_gravity(x: float, y: float, z: float, mu: float, j2: float, re: float):
    """Two-body + J2 acceleration (m/s^2); ``j2 = 0`` gives pure two-body."""
    ax, ay, az = accel_twobody(x, y, z, mu)
    if j2 != 0.0:
        bx, by, bz = accel_j2(x, y, z, mu, j2, re)
        ax += bx
        ay += by
        az += bz
    return ax, ay, az


@njit(cache=True, fastmath=False)
def battin_f(q: float) -> float:
    """f(q) = 1 - (1 + q)^{3/2} computed without cancellation for small q."""
    s = (1.0 + q) * math.sqrt(1.0 + q)
    return -q * (3.0 + 3.0 * q + q * q) / (1.0 + s)


@njit(cache=True, fastmath=False)
def accel_differential(
    rtx: float, rty: float, rtz: float, dx: float, dy: float, dz: float, mu: float, j2: float, re: float
):
    """Exact differential gravity g(r_t + dr) - g(r_t) (m/s^2) as a tuple (Encke/Battin)."""
    rt2 = rtx * rtx + rty * rty + rtz * rtz
    q = (2.0 * (rtx * dx + rty * dy + rtz * dz) + dx * dx + dy * dy + dz * dz) / rt2
    f = battin_f(q)
    rc2 = rt2 * (1.0 + q)
    k = -mu / (rc2 * math.sqrt(rc2))
    ax = k * (dx + f * rtx)
    ay = k * (dy + f * rty)
    az = k * (dz + f * rtz)
    if j2 != 0.0:
        cx, cy, cz = accel_j2(rtx + dx, rty + dy, rtz + dz, mu, j2, re)
        tx, ty, tz = accel_j2(rtx, rty, rtz, mu, j2, re)
        ax += cx - tx
        ay += cy - ty
        az += cz - tz
    return ax, ay, az


@njit(cache=True, fastmath=False)
def potential(x: float, y: float, z: float, mu: float, j2: float, re: float) -> float:
    """Gravitational potential V (J/kg) with a = -grad V (two-body + J2)."""
    r2 = x * x + y * y + z * z
    r = math.sqrt(r2)
    v = -mu / r
    if j2 != 0.0:
        v += mu * j2 * re * re / (2.0 * r2 * r) * (3.0 * z * z / r2 - 1.0)
    return v


def accel_gravity_vec(r: np.ndarray, mu: float, j2: float, re: float) -> np.ndarray:
    """Array wrapper of :func:`accel_gravity` for one position (m) -> (3,) m/s^2."""
    return np.array(accel_gravity(float(r[0]), float(r[1]), float(r[2]), mu, j2, re))


def accel_differential_vec(r_t: np.ndarray, dr: np.ndarray, mu: float, j2: float, re: float) -> np.ndarray:
    """Array wrapper of :func:`accel_differential` -> (3,) m/s^2."""
    return np.array(
        accel_differential(
            float(r_t[0]), float(r_t[1]), float(r_t[2]), float(dr[0]), float(dr[1]), float(dr[2]), mu, j2, re
        )
    )
