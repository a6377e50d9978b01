"""Reference path: scipy ``solve_ivp(method="DOP853")`` on the same Encke right-hand side
as the fast path (:mod:`proxops.propagation.kernels`), at the papers' tolerances."""

from __future__ import annotations

import numpy as np

from proxops.errors import ProxopsError
from proxops.propagation import kernels

REFERENCE_RTOL = 1e-10
REFERENCE_ATOL = 1e-12


def propagate_reference(
    y0: np.ndarray,
    dt: float,
    u: np.ndarray,
    params: np.ndarray,
    rtol: float = REFERENCE_RTOL,
    atol: float = REFERENCE_ATOL,
) -> np.ndarray:
    """State (12,) after integrating the 12-state over ``[0, dt]`` with scipy DOP853."""
    y0 = np.ascontiguousarray(y0, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    params = np.ascontiguousarray(params, dtype=float)
    if dt == 0.0:
        return y0.copy()

    from scipy.integrate import solve_ivp  # heavy (0.5 s): only on the reference path

    def fun(_t, y):
        return kernels.rhs_relative_alloc(y, u, params)

    sol = solve_ivp(fun, (0.0, float(dt)), y0, method="DOP853", rtol=rtol, atol=atol)
    if not sol.success:
        raise ProxopsError(f"reference propagation failed: {sol.message}")
    return sol.y[:, -1].copy()
