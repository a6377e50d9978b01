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

from proxops.frames.elements import OrbitalElements
from proxops.propagation.truth import RelativeTruth


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
        y = self.model.with_relative_state(self._target_at(t0), np.asarray(x_hill, dtype=float)[:6])
        if kind == "impulse":
            if np.any(u):
                y = self.model.apply_impulse(t0, y, u)
            y = self.model.propagate(t0, y, None, dt)
        else:
            y = self.model.propagate(t0, y, u, dt)
        self._t, self._y = t0 + dt, y
        return self.model.relative_state(y)
