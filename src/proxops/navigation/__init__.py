"""Navigation models: what the controller sees of the true relative state."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PerfectNavigation:
    """The controller sees the true state."""

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return np.array(x_true, dtype=float)


@dataclass
class GaussianNavigation:
    """Zero-mean white Gaussian errors on the measured state.

    ``position_sigma_m`` and ``velocity_sigma_mps`` are per-axis 1-sigma values for a
    Hill state ``[x, y, z, vx, vy, vz]``. For any other state layout pass ``sigma``: one
    1-sigma value per state component (its units), which then replaces the two scalars.
    """

    position_sigma_m: float = 0.0
    velocity_sigma_mps: float = 0.0
    sigma: np.ndarray | None = None
    range_scale_m: float | None = None  # range-dependent sigmas (see scale())
    range_floor: float = 0.0

    def scale(self, x: np.ndarray) -> float:
        """1 without ``range_scale_m``; else floor + (1 - floor) ||r|| / range_scale_m (both sigmas
        are multiplied by it): cortex-convex-guidance.md §5.1.2, sigma_r = (Delta r / 3)
        (0.02 + 0.98 ||r|| / r_AS) with floor 0.02 and range_scale_m = r_AS."""
        if self.range_scale_m is None:
            return 1.0
        r = float(np.linalg.norm(x[:3]))
        return self.range_floor + (1.0 - self.range_floor) * r / self.range_scale_m

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        x = np.array(x_true, dtype=float)
        if self.sigma is not None:
            sigma = np.asarray(self.sigma, dtype=float)
        else:
            half = x.size // 2
            sigma = np.concatenate([np.full(half, self.position_sigma_m), np.full(x.size - half, self.velocity_sigma_mps)])
        if not sigma.any():
            return x
        return x + self.scale(x) * sigma * rng.standard_normal(x.size)
