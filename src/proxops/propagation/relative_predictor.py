"""Mean prediction of a navigation filter's Hill state by the nonlinear two-body + J2 relative model.

:class:`HillPredictor` is the process model a relative-navigation filter
(:class:`proxops.navigation.ekf.RelativeEKF`, ``predictor``) uses instead of the linear
Clohessy-Wiltshire transition: the target's orbit is known (the scenario's [orbit]), the chaser
is put at the estimated Hill state with the exact nonlinear map and both are propagated Encke-style
(:class:`proxops.propagation.truth.RelativeTruth`, two-body + J2, DOP853), the commanded Hill
acceleration held or the commanded impulse applied first. It removes the deterministic error of the
CW model at km ranges (curvature of the along-track direction, ~1.5 n^2 rho^2 / r, and the
differential J2 terms, ~6 n^2 J2 (R_E / r)^2 rho) that made ``srf-vbar-ekf`` overconfident.
The target's own trajectory does not depend on the chaser and is cached between calls.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from proxops.errors import ProxopsError
from proxops.frames.elements import OrbitalElements
from proxops.propagation import kernels
from proxops.propagation.truth import STATUS_TEXT, RelativeTruth, _check_dt


class HillPredictor:
    """``predict(t0, x_hill, u, kind, dt) -> x_hill(t0 + dt)`` on two-body (+ J2) dynamics.

    ``target``: the target's osculating elements at t = 0 (s); ``j2``: include J2 (default True).
    ``u`` (Hill, m/s^2 held over the step for ``kind = "acceleration"``, m/s applied at t0 for
    ``"impulse"``). Calls need not be monotonic in t0 (the cached target restarts from t = 0)."""

    def __init__(self, target: OrbitalElements, j2: bool = True):
        self.model = RelativeTruth(target, np.zeros(6), j2=j2, integrator="fast")
        self._y0 = self.model.initial_state()
        self._t, self._y = 0.0, self._y0.copy()  # cached full state whose target part is at _t

    def _target_at(self, t: float) -> np.ndarray:
        if t < self._t - 1e-9:
            self._t, self._y = 0.0, self._y0.copy()
        if t > self._t + 1e-9:
            self._y = self.model.propagate(self._t, self._y, None, t - self._t)
            self._t = t
        return self._y

    def predict(self, t0: float, x_hill: np.ndarray, u: np.ndarray, kind: str, dt: float) -> np.ndarray:
        m = self.model
        if m.integrator != "fast":  # the truth's own methods (reference integrator)
            y = m.with_relative_state(self._target_at(t0), np.asarray(x_hill, dtype=float)[:6])
            if kind == "impulse":
                if np.any(u):
                    y = m.apply_impulse(t0, y, u)
                y = m.propagate(t0, y, None, dt)
            else:
                y = m.propagate(t0, y, u, dt)
            self._t, self._y = t0 + dt, y
            return m.relative_state(y)
        dt = _check_dt(dt)  # the truth's own check of dt
        y, rel, status = _predict_kernel(self._target_at(t0), np.ascontiguousarray(x_hill[:6], dtype=float),
                                         np.ascontiguousarray(u, dtype=float), kind == "impulse", dt, m.params,
                                         m.rtol, m.atol)
        if status != kernels.STATUS_OK:
            raise ProxopsError(f"filter prediction failed at t = {t0} s over dt = {dt} s: {STATUS_TEXT[status]}")
        self._t, self._y = t0 + dt, y
        return rel


@njit(cache=True)
def _predict_kernel(y_target, x_hill, u, impulse, dt, p, rtol, atol):  # pragma: no cover - compiled
    """:meth:`HillPredictor.predict` with the fast integrator in one call: the chaser put at ``x_hill``
    next to the target's full state (``y_target``: its first 6 entries), the impulse ``u`` applied first
    (``impulse``; else ``u`` held), ``dt`` s of DOP853; returns (state, Hill state, integrator status) -
    RelativeTruth's with_relative_state, apply_impulse, propagate and relative_state in turn."""
    y = kernels.y_from_hill(y_target[:6].copy(), x_hill, p)
    held = u
    if impulse:
        held = np.zeros(3)
        if u[0] != 0.0 or u[1] != 0.0 or u[2] != 0.0:
            y = kernels.apply_hill_impulse(y, u)
    y_new, status, _ = kernels.propagate_dop853(y, dt, held, p, rtol, atol)
    return y_new, kernels.hill_from_y(y_new, p), status
