"""Friendly layer over the two-body + J2 gravity kernels of :mod:`proxops.core.twobody`.

Also the secular J2 rates of the mean elements used in tests and J2-aware guidance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxops.core import twobody
from proxops.core.constants import J2_EARTH, MU_EARTH, R_EARTH


@dataclass(frozen=True)
class J2Gravity:
    """Point mass + J2 zonal gravity. ``j2=0`` gives pure two-body. SI units."""

    mu: float = MU_EARTH
    j2: float = J2_EARTH
    re: float = R_EARTH

    def acceleration(self, r: np.ndarray) -> np.ndarray:
        """Gravity acceleration (m/s^2) at ECI position(s) ``r`` (..., 3) in m."""
        r = np.asarray(r, dtype=float)
        flat = r.reshape(-1, 3)
        out = np.array([twobody.accel_gravity(p[0], p[1], p[2], self.mu, self.j2, self.re) for p in flat])
        return out.reshape(r.shape)

    def potential(self, r: np.ndarray) -> np.ndarray:
        """Potential V (J/kg) with a = -grad V, at position(s) ``r`` (..., 3)."""
        r = np.asarray(r, dtype=float)
        flat = r.reshape(-1, 3)
        out = np.array([twobody.potential(p[0], p[1], p[2], self.mu, self.j2, self.re) for p in flat])
        return out.reshape(r.shape[:-1])

    def specific_energy(self, state: np.ndarray) -> np.ndarray:
        """v^2/2 + V (J/kg) of ECI state(s) (..., 6); conserved by the J2 field."""
        s = np.asarray(state, dtype=float)
        return 0.5 * np.sum(s[..., 3:] ** 2, axis=-1) + self.potential(s[..., :3])


def _j2_rate_factor(sma: float, ecc: float, mu: float, j2: float, re: float) -> float:
    """3/2 n J2 (Re / p)^2 (rad/s)."""
    n = math.sqrt(mu / sma**3)
    p = sma * (1.0 - ecc**2)
    return 1.5 * n * j2 * (re / p) ** 2


def j2_raan_rate(
    sma: float, ecc: float, inc: float, mu: float = MU_EARTH, j2: float = J2_EARTH, re: float = R_EARTH
) -> float:
    """Secular nodal regression dRAAN/dt = -3/2 n J2 (Re/p)^2 cos i (rad/s).

    Vallado 4th ed. eq. 9-41; Curtis, *Orbital Mechanics for Engineering Students*, eq. 4.52."""
    return -_j2_rate_factor(sma, ecc, mu, j2, re) * math.cos(inc)


def j2_argp_rate(
    sma: float, ecc: float, inc: float, mu: float = MU_EARTH, j2: float = J2_EARTH, re: float = R_EARTH
) -> float:
    """Secular apsidal rate dargp/dt = 3/4 n J2 (Re/p)^2 (4 - 5 sin^2 i) (rad/s) (Curtis eq. 4.53)."""
    return 0.5 * _j2_rate_factor(sma, ecc, mu, j2, re) * (4.0 - 5.0 * math.sin(inc) ** 2)
