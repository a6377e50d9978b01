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

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        x = np.array(x_true, dtype=float)
        if self.sigma is not None:
            sigma = np.asarray(self.sigma, dtype=float)
        else:
            half = x.size // 2
            sigma = np.concatenate([np.full(half, self.position_sigma_m), np.full(x.size - half, self.velocity_sigma_mps)])
        if not sigma.any():
            return x
        return x + sigma * rng.standard_normal(x.size)
