"""Truth plants for the closed-loop engine (:class:`proxops.contracts.Plant`).

* :class:`RelativeTruth` -- nonlinear two-body (+ J2) truth. Full state (12,):
  target ECI ``[r_t, v_t]`` and chaser ECI offset ``[dr, dv] = chaser - target`` (m, m/s),
  propagated Encke-style (exact differential gravity, no subtraction of 7000 km
  vectors), so the relative state keeps sub-millimetre accuracy. Control: zero-order-hold
  acceleration in Hill axes (rotated to ECI inside the RHS with the current target
  state) and impulsive dv in Hill axes. ``integrator="fast"`` (default, numba DOP853,
  one jitted call per step) or ``"reference"`` (scipy solve_ivp DOP853).
* :class:`CWPlant` -- linear Clohessy-Wiltshire plant, exact STM / ZOH discretisation
  from :mod:`proxops.core.cw`; for tests and cheap runs.
* :func:`propagate_free_drift` -- uncontrolled relative states on a time grid (passive
  abort / safety checks) for either plant.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from proxops.core.constants import J2_EARTH, MU_EARTH, R_EARTH
from proxops.core.cw import cw_discretize_zoh, cw_stm
from proxops.core.memo import memo_get
from proxops.errors import ProxopsError, input_error
from proxops.frames.elements import OrbitalElements, check_perigee_above_surface, eci_to_elements, elements_to_eci
from proxops.propagation import kernels
from proxops.propagation.reference import REFERENCE_ATOL, REFERENCE_RTOL, propagate_reference
from proxops.dynamics.plant import PlantBase
from proxops.dynamics.tumbling_target import quaternion_stepped

STATUS_TEXT = {
    kernels.STATUS_STEP_TOO_SMALL: "step size fell below the time resolution",
    kernels.STATUS_TOO_MANY_STEPS: f"more than {kernels.MAX_STEPS} steps",
    kernels.STATUS_NOT_FINITE: "state became non-finite",
}


def _check_state6(name: str, value) -> np.ndarray:
    arr = np.ascontiguousarray(value, dtype=float)
    if arr.shape != (6,):
        raise input_error(f"{name} shape", arr.shape, "must be (6,) = [x, y, z, vx, vy, vz]", "m, m/s")
    if not np.all(np.isfinite(arr)):
        raise input_error(name, arr.tolist(), "must be finite (no NaN/inf)", "m, m/s")
    return arr


def _check_dt(dt: float) -> float:
    dt = float(dt)
    if not (dt >= 0.0 and math.isfinite(dt)):
        raise input_error("dt", dt, "must be finite and >= 0", "s")
    return dt


def _control(u, name: str = "u") -> np.ndarray:
    arr = np.ascontiguousarray(u, dtype=float)
    if arr.shape != (3,):
        raise input_error(f"{name} shape", arr.shape, "must be (3,) in Hill axes")
    return arr


class RelativeTruth(PlantBase):
    """Nonlinear two-body (+ J2) truth for one target and one chaser (Plant protocol).

    Parameters
    ----------
    target : OrbitalElements | array (6,)
        Target orbit: osculating elements or ECI state ``[r, v]`` (m, m/s).
    chaser_hill : array (6,)
        Initial chaser Hill state ``[x, y, z, vx, vy, vz]`` (m, m/s), exact (nonlinear) map.
    j2 : include the J2 zonal term for both spacecraft.
    integrator : ``"fast"`` or ``"dop853"`` (the same: numba DOP853) or ``"reference"`` (scipy DOP853).
    rtol, atol : integrator tolerances (default 1e-10 / 1e-12, the papers' values).
    """

    n_x = 6
    n_u = 3

    def __init__(
        self,
        target: OrbitalElements | np.ndarray,
        chaser_hill: np.ndarray,
        *,
        j2: bool = True,
        integrator: str = "fast",
        mu: float = MU_EARTH,
        j2_coeff: float = J2_EARTH,
        r_earth: float = R_EARTH,
        rtol: float = REFERENCE_RTOL,
        atol: float = REFERENCE_ATOL,
    ) -> None:
        if integrator not in ("fast", "dop853", "reference"):
            raise input_error("integrator", integrator, "must be 'fast', 'dop853' or 'reference'")
        integrator = "fast" if integrator == "dop853" else integrator
        for name, value in (("rtol", rtol), ("atol", atol)):
            if not (value > 0 and math.isfinite(value)):
                raise input_error(name, value, "must be finite and > 0")
        if isinstance(target, OrbitalElements):
            elements = target
            target_state = elements_to_eci(elements, mu)
        else:
            target_state = _check_state6("target state", target)
            elements = eci_to_elements(target_state, mu)
        check_perigee_above_surface(elements, r_earth, "target orbit")
        self.integrator = integrator
        self.j2 = bool(j2)
        self.mu = float(mu)
        self.rtol = float(rtol)
        self.atol = float(atol)
        self.params = np.array([mu, j2_coeff if j2 else 0.0, r_earth], dtype=float)
        self.target_elements = elements
        self.mean_motion = math.sqrt(mu / elements.sma**3)
        """Keplerian mean motion of the initial osculating target orbit (rad/s)."""
        self._zero_u = np.zeros(3)
        self._x0 = kernels.y_from_hill(
            np.ascontiguousarray(target_state), _check_state6("chaser_hill", chaser_hill), self.params
        )

    # ------------------------------------------------------------------ Plant protocol
    def initial_state(self) -> np.ndarray:
        """Full 12-state at t = 0."""
        return self._x0.copy()

    def relative_state(self, state: np.ndarray) -> np.ndarray:
        """Exact Hill relative state (6,) (with the J2 frame-rate term when j2 is on)."""
        return kernels.hill_from_y(np.ascontiguousarray(state, dtype=float), self.params)

    def propagate(self, t: float, state: np.ndarray, u: np.ndarray | None, dt: float) -> np.ndarray:
        """State after ``dt`` s with Hill acceleration ``u`` (m/s^2) held constant."""
        dt = _check_dt(dt)
        y = np.ascontiguousarray(state, dtype=float)
        uu = self._zero_u if u is None else _control(u)
        if self.integrator == "fast":
            y_new, status, _ = kernels.propagate_dop853(y, dt, uu, self.params, self.rtol, self.atol)
            if status != kernels.STATUS_OK:
                raise ProxopsError(f"truth propagation failed at t = {t} s over dt = {dt} s: {STATUS_TEXT[status]}")
            return y_new
        return propagate_reference(y, dt, uu, self.params, self.rtol, self.atol)

    def propagate_spinning(self, t: float, state: np.ndarray, u: np.ndarray | None, dt: float,
                           q_step: np.ndarray) -> np.ndarray:
        """:meth:`propagate` of a state [y (12), q (4)] that carries an attitude quaternion q, stepped as
        q_step q and normalised (q_step 4x4: the exact step of a constant body rate,
        :class:`proxops.dynamics.tumbling_target.TumblingTargetTruth`); with the fast integrator one jitted call."""
        dt = _check_dt(dt)
        y = np.ascontiguousarray(state, dtype=float)
        if self.integrator == "fast":
            out, status = _propagate_spinning(y, dt, self._zero_u if u is None else _control(u), self.params,
                                              self.rtol, self.atol, q_step)
            if status == kernels.STATUS_OK:
                return out
        return quaternion_stepped(self.propagate(t, y[:12], u, dt), y, q_step)  # reference path, or the error

    def coast(self, times: np.ndarray, state: np.ndarray, u: np.ndarray, dt: float):
        """The engine's idle-step coast (:meth:`PlantBase.coast`): ``len(times)`` pieces of ``dt`` s,
        one jitted call with the numbers of as many :meth:`propagate` calls."""
        if self.integrator != "fast":
            return super().coast(times, state, u, dt)
        dt = _check_dt(dt)
        ys, rel, status, k = kernels.coast_dop853(np.ascontiguousarray(state, dtype=float), len(times), dt,
                                                  self._zero_u if u is None else _control(u), self.params,
                                                  self.rtol, self.atol)
        if status != kernels.STATUS_OK:
            raise ProxopsError(f"truth propagation failed at t = {float(times[k])} s over dt = {dt} s: "
                               f"{STATUS_TEXT[status]}")
        return ys, rel

    def apply_impulse(self, t: float, state: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """State with an instantaneous chaser velocity change ``dv`` (m/s, Hill axes)."""
        return kernels.apply_hill_impulse(np.ascontiguousarray(state, dtype=float), _control(dv, "dv"))

    # ------------------------------------------------------------------ helpers
    def free_drift(self, state: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Uncontrolled Hill states (len(times), 6) at ``times`` (s after now, increasing, >= 0)."""
        y = np.ascontiguousarray(state, dtype=float)
        times = np.ascontiguousarray(times, dtype=float)
        if times.ndim != 1 or times.size == 0 or times[0] < 0.0 or np.any(np.diff(times) < 0.0):
            raise input_error("times", times.tolist(), "must be a non-empty increasing 1-D grid of s >= 0")
        grid = times if times[0] == 0.0 else np.concatenate([[0.0], times])
        if self.integrator == "fast":
            rel, status = kernels.free_drift_hill(y, grid, self.params, self.rtol, self.atol)
            if status != kernels.STATUS_OK:
                raise ProxopsError(f"free-drift propagation failed: {STATUS_TEXT[status]}")
        else:
            rel = np.empty((grid.size, 6))
            rel[0] = self.relative_state(y)
            for k in range(1, grid.size):
                y = propagate_reference(y, grid[k] - grid[k - 1], self._zero_u, self.params, self.rtol, self.atol)
                rel[k] = self.relative_state(y)
        return rel if times[0] == 0.0 else rel[1:]

    def with_relative_state(self, state: np.ndarray, hill_state: np.ndarray) -> np.ndarray:
        """Copy of ``state`` with the chaser moved to ``hill_state`` (target unchanged)."""
        y = np.ascontiguousarray(state, dtype=float)
        return kernels.y_from_hill(y[:6].copy(), _check_state6("hill_state", hill_state), self.params)

    @staticmethod
    def target_state(state: np.ndarray) -> np.ndarray:
        """Target ECI state (6,)."""
        return np.asarray(state, dtype=float)[:6].copy()

    @staticmethod
    def chaser_state(state: np.ndarray) -> np.ndarray:
        """Chaser ECI state (6,) (target + offset; loses ~1e-9 m to rounding)."""
        s = np.asarray(state, dtype=float)
        return s[:6] + s[6:12]


@njit(cache=True)
def _propagate_spinning(state, dt, u, p, rtol, atol, q_step):  # pragma: no cover - compiled
    """(:func:`kernels.propagate_dop853` of state[:12] with the quaternion state[12:16] stepped by q_step, status)."""
    y, status, _ = kernels.propagate_dop853(state[:12], dt, u, p, rtol, atol)
    return quaternion_stepped(y, state, q_step), status


class CWPlant(PlantBase):
    """Linear CW truth (Plant protocol): state = Hill relative state (6,).

    ``propagate`` uses the exact ZOH discretisation (cached per ``dt``); impulses add to
    the velocity."""

    n_x = 6
    n_u = 3

    def __init__(self, mean_motion: float, chaser_hill: np.ndarray) -> None:
        if not (mean_motion > 0 and math.isfinite(mean_motion)):
            raise input_error("mean_motion", mean_motion, "must be finite and > 0", "rad/s")
        self.mean_motion = float(mean_motion)
        self._x0 = _check_state6("chaser_hill", chaser_hill)
        self._cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    @classmethod
    def from_orbit(cls, target: OrbitalElements, chaser_hill: np.ndarray, mu: float = MU_EARTH) -> "CWPlant":
        """CW plant with the Keplerian mean motion of ``target``'s semi-major axis."""
        return cls(math.sqrt(mu / target.sma**3), chaser_hill)

    def initial_state(self) -> np.ndarray:
        return self._x0.copy()

    def relative_state(self, state: np.ndarray) -> np.ndarray:
        return np.array(state, dtype=float)

    def _matrices(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        return memo_get(self._cache, dt, lambda: cw_discretize_zoh(self.mean_motion, dt))

    def propagate(self, t: float, state: np.ndarray, u: np.ndarray | None, dt: float) -> np.ndarray:
        dt = _check_dt(dt)
        Ad, Bd = self._matrices(dt)
        x = Ad @ np.asarray(state, dtype=float)
        if u is not None:
            x += Bd @ _control(u)
        return x

    def apply_impulse(self, t: float, state: np.ndarray, dv: np.ndarray) -> np.ndarray:
        x = np.array(state, dtype=float)
        x[3:6] += _control(dv, "dv")
        return x

    def free_drift(self, state: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Uncontrolled states (len(times), 6) at ``times`` (s after now) from the CW STM."""
        x = np.asarray(state, dtype=float)
        return np.array([cw_stm(self.mean_motion, float(tau)) @ x for tau in np.asarray(times, dtype=float)])


def propagate_free_drift(truth, state: np.ndarray, duration: float, n_samples: int) -> np.ndarray:
    """Uncontrolled relative (Hill) states, shape (n_samples, 6), at
    ``np.linspace(0, duration, n_samples)`` s after ``state`` (both ends included).

    Works with any Plant; uses the plant's ``free_drift`` when it has one (one jitted call
    for :class:`RelativeTruth`)."""
    duration = _check_dt(duration)
    if int(n_samples) < 1:
        raise input_error("n_samples", n_samples, "must be >= 1")
    times = np.linspace(0.0, duration, int(n_samples))
    if hasattr(truth, "free_drift"):
        return truth.free_drift(state, times)
    out = np.empty((times.size, truth.n_x))
    x = np.asarray(state, dtype=float)
    out[0] = truth.relative_state(x)
    zero = np.zeros(truth.n_u)
    for k in range(1, times.size):
        x = truth.propagate(times[k - 1], x, zero, times[k] - times[k - 1])
        out[k] = truth.relative_state(x)
    return out
