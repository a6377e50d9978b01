"""Navigation models: what the controller sees of the true relative state.

Every model follows :class:`proxops.contracts.Navigation`: ``measure(t, x_true, rng)``
and ``period_s`` (s between measurements, None = every controller sample). Noise is drawn
per block of the plant's :class:`proxops.core.layout.StateLayout`: additive on position,
velocity, angle and rate blocks, a small random rotation on a quaternion block. :mod:`proxops.navigation.ekf` holds the relative-navigation filter
(EKF on the Hill state fed by simulated sensors), which also takes the controller's commands
(``command(t, u, kind)``) and reports rejected measurements through its ``events`` list;
:mod:`proxops.navigation.consistency` holds the NEES / NIS chi-square bands and the innovation-whiteness
test that judge such a filter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from proxops.core.layout import StateLayout
from proxops.core.quaternion import quat_multiply, rotation_quaternion_kernel


@dataclass
class NavigationBase:
    """Defaults of a navigation model: measured every controller sample."""

    period_s: float | None = field(default=None, kw_only=True)

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        raise NotImplementedError

    def measure_many(self, t: np.ndarray, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Estimates (n, n_x) of the samples ``x_true`` (n, n_x) at times ``t`` (n,): the numbers and
        random draws of ``measure`` called on each in turn (the engine's idle-step coast)."""
        return np.array([self.measure(float(ti), xi, rng) for ti, xi in zip(t, x_true)], dtype=float).reshape(
            np.shape(x_true))


@dataclass
class PerfectNavigation(NavigationBase):
    """The controller sees the true state."""

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return np.array(x_true, dtype=float)

    def measure_many(self, t: np.ndarray, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return np.array(x_true, dtype=float)


@dataclass
class GaussianNavigation(NavigationBase):
    """Zero-mean white Gaussian errors on the measured state, per layout block.

    ``position_sigma_m`` / ``velocity_sigma_mps``: per-axis 1-sigma on position / velocity
    blocks; ``angle_sigma_rad`` / ``rate_sigma_rad_s`` on planar-angle / angular-rate blocks;
    ``attitude_sigma_rad``: per-axis 1-sigma of the small rotation vector applied to each
    quaternion block, q_meas = q (x) exp(phi / 2) (body-frame error; the result stays a unit
    quaternion). ``sigma`` (one 1-sigma per component, its units) replaces the additive
    per-block values. Without a ``layout`` the state is split in halves [position, velocity]
    (a Hill state ``[x, y, z, vx, vy, vz]``). The additive part draws one
    ``standard_normal(n_x)`` vector, then each quaternion block three more.
    """

    position_sigma_m: float = 0.0
    velocity_sigma_mps: float = 0.0
    sigma: np.ndarray | None = None
    range_scale_m: float | None = None  # range-dependent sigmas (see scale())
    range_floor: float = 0.0
    layout: StateLayout | None = None
    attitude_sigma_rad: float = 0.0
    angle_sigma_rad: float = 0.0
    rate_sigma_rad_s: float = 0.0

    def scale(self, x: np.ndarray) -> float:
        """1 without ``range_scale_m``; else floor + (1 - floor) ||r|| / range_scale_m (the additive
        sigmas are multiplied by it): Wijayatunga et al. §5.1.2, sigma_r = (Delta r / 3)
        (0.02 + 0.98 ||r|| / r_AS) with floor 0.02 and range_scale_m = r_AS."""
        if self.range_scale_m is None:
            return 1.0
        r = float(np.linalg.norm(x[:3]))
        return self.range_floor + (1.0 - self.range_floor) * r / self.range_scale_m

    def __post_init__(self):
        self._sigma_cache: tuple[int, np.ndarray] | None = None

    def additive_sigma(self, n_x: int) -> np.ndarray:
        """1-sigma of the additive noise per state component."""
        if self.sigma is not None:
            return np.asarray(self.sigma, dtype=float)
        if self.layout is None:
            half = n_x // 2
            return np.concatenate([np.full(half, self.position_sigma_m), np.full(n_x - half, self.velocity_sigma_mps)])
        per_kind = {"position": self.position_sigma_m, "velocity": self.velocity_sigma_mps,
                    "angle": self.angle_sigma_rad, "rate": self.rate_sigma_rad_s}
        out = np.zeros(n_x)
        for b in self.layout.blocks:
            out[b.start:b.stop] = per_kind.get(b.kind, 0.0)
        return out

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        x = np.array(x_true, dtype=float)
        cache = self._sigma_cache
        if cache is None or cache[0] != x.size:
            sigma = self.additive_sigma(x.size)
            cache = self._sigma_cache = (x.size, sigma, bool(sigma.any()), 1.0 * sigma)
        if cache[2]:
            # without range scaling scale(x) = 1.0: cache[3] = 1.0 * sigma, the same product
            factor = cache[3] if self.range_scale_m is None else self.scale(x) * cache[1]
            x = x + factor * rng.standard_normal(x.size)
        if self.attitude_sigma_rad > 0.0 and self.layout is not None:
            for b in self.layout.blocks:
                if b.kind == "quaternion":
                    x[b.start:b.stop] = quat_multiply(x[b.start:b.stop],
                                                      small_rotation(self.attitude_sigma_rad * rng.standard_normal(3)))
        return x


    def measure_many(self, t: np.ndarray, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Vectorised :meth:`measure` (same draws: ``standard_normal((n, n_x))`` is n consecutive
        ``standard_normal(n_x)``; same numbers: the per-row factor is computed as in ``measure``)."""
        x = np.array(x_true, dtype=float)
        if self.attitude_sigma_rad > 0.0 and self.layout is not None and any(
                b.kind == "quaternion" for b in self.layout.blocks):
            return super().measure_many(t, x_true, rng)  # quaternion draws interleave with the additive ones
        if x.shape[0] == 0:
            return x
        if self._sigma_cache is None or self._sigma_cache[0] != x.shape[1]:
            sigma = self.additive_sigma(x.shape[1])
            self._sigma_cache = (x.shape[1], sigma, bool(sigma.any()), 1.0 * sigma)
        sigma = self._sigma_cache[1]
        if not sigma.any():
            return x
        noise = rng.standard_normal(x.shape)
        if self.range_scale_m is None:
            return x + (1.0 * sigma) * noise
        scale = np.array([self.scale(row) for row in x])
        return x + (scale[:, None] * sigma) * noise


def small_rotation(phi: np.ndarray) -> np.ndarray:
    """Unit quaternion (scalar-last) of the rotation vector ``phi`` (rad): [sin(|phi|/2) phi/|phi|, cos(|phi|/2)]
    (:func:`proxops.core.quaternion.rotation_quaternion_kernel`)."""
    return rotation_quaternion_kernel(np.ascontiguousarray(phi, dtype=float))
