"""Navigation of the hybrid capture system (Basu et al.): what both MPCs
see instead of the exact relative state.

Measured state (34, :data:`proxops.propagation.hybrid_plant.HYBRID_LAYOUT` order): the paper's
32 entries, the contact count and the latch sensor.

* Chief attitude p (C relative to T) and tumble omega_c: estimated by
  :class:`proxops.navigation.mekf.AttitudeMEKF` (reference frame T turning at
  omega_t = [0, 0, n0], body rate inertial) from a pose attitude measurement of the chief
  (``chief_attitude_sigma_deg``, e.g. a camera/LIDAR model fit) at every controller sample;
  omega_c = omega_hat - C_{C<-T}(p_hat) omega_t. Both MPCs use this estimate.
* Relative pose and rates (rho, rho_dot, q, omega): the measurement itself, Gaussian noise
  of ``position_sigma_m``, ``velocity_sigma_mps``, ``attitude_sigma_deg`` (a small rotation on
  q) and ``rate_sigma_deg_s``.
  The filter's process model is torque-free; two known inputs are added outside it: while the
  latch sensor reads locked, the commanded deputy wrench turns the pair (``command`` hook:
  delta omega = J_pair^-1 (M + arm x F) dt, composite inertia about the pair CoM in C, added to
  the estimate), and when the contact count rises the rate covariance is widened by
  ``contact_rate_sigma_deg_s`` (a contact impulse spins the chief by up to a few deg/s).
* Composite CoM (rho_n, rho_n_dot, relative to the chief's initial orbit frame): Gaussian
  noise of ``com_position_sigma_m`` and ``com_velocity_sigma_mps`` (relative GNSS-like fix).
* x_ref (the desired orbit), the contact count and the latch sensor: exact (known / discrete).

No translational filter: :class:`proxops.navigation.ekf.RelativeEKF` estimates a Hill-frame
CW state, while rho is the port offset in the tumbling chief frame (not its state).
Each draw comes from the engine's navigation stream, so the run is reproducible per seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from numba import njit

from proxops.core.quaternion import dcm_kernel, multiply_kernel, quat_multiply, quat_rotate_inverse, rotation_quaternion_kernel
from proxops.navigation import NavigationBase, small_rotation
from proxops.navigation.mekf import AttitudeMEKF, attitude_error_kernel


@dataclass
class HybridNavigation(NavigationBase):
    """Noisy relative pose + MEKF chief attitude (module doc). ``inertia_chief`` (3x3, kg m^2),
    ``mean_motion_rad_s`` (n0). Sigmas are 1-sigma per axis."""

    inertia_chief: np.ndarray
    mean_motion_rad_s: float
    inertia_pair_C: np.ndarray  # composite inertia about the pair CoM, docked, C axes (kg m^2)
    arm_C: np.ndarray  # (m_c / m) (P_c - P_d): moment arm of the deputy thrust about the pair CoM (m)
    position_sigma_m: float = 2e-3
    velocity_sigma_mps: float = 5e-4
    attitude_sigma_deg: float = 0.2
    rate_sigma_deg_s: float = 0.02
    chief_attitude_sigma_deg: float = 0.5
    com_position_sigma_m: float = 1e-3
    com_velocity_sigma_mps: float = 1e-4
    q_accel_psd: float = 1e-8  # rad^2/s^3: unmodelled chief torques (contacts are jumps: see gate below)
    initial_attitude_sigma_deg: float = 2.0
    initial_rate_sigma_deg_s: float = 0.2
    contact_rate_sigma_deg_s: float = 5.0
    filter: AttitudeMEKF | None = field(default=None, init=False)
    attitude_errors_deg: list = field(default_factory=list, init=False)
    _t_last: float | None = field(default=None, init=False)
    _u: np.ndarray = field(default_factory=lambda: np.zeros(6), init=False)
    _contacts: float = field(default=0.0, init=False)
    _sigmas: np.ndarray | None = field(default=None, init=False)  # the measurement sigmas in the draws' order
    _pair_inertia_inv: np.ndarray | None = field(default=None, init=False)

    def command(self, t: float, u: np.ndarray, kind: str) -> None:
        """The deputy's held wrench (F_d, M_d in D; N, N m) from ``t`` on."""
        self._u = np.asarray(u, dtype=float)[:6].copy()

    def _known_inputs(self, x: np.ndarray, dt: float) -> None:
        f = self.filter
        dw = None
        if x[33] > 0.5 and dt > 0.0:  # latched: the pair turns under the commanded wrench
            Q_T = dcm_kernel(x[9:13])  # C_{C<-D} (measured q)
            F, a = Q_T @ self._u[0:3], self.arm_C
            M = Q_T @ self._u[3:6] + np.array([a[1] * F[2] - a[2] * F[1], a[2] * F[0] - a[0] * F[2],
                                                a[0] * F[1] - a[1] * F[0]])
            if self._pair_inertia_inv is None:
                self._pair_inertia_inv = np.linalg.inv(self.inertia_pair_C)
            dw = (self._pair_inertia_inv @ M) * dt
        variance = 0.0
        if x[32] > self._contacts:  # a contact impulse: the rate is uncertain by a few deg/s
            self._contacts = float(x[32])
            variance = math.radians(self.contact_rate_sigma_deg_s) ** 2
        if dw is not None or variance > 0.0:
            f.add_rate(dw, variance)

    def _start(self, x: np.ndarray, rng: np.random.Generator) -> None:
        s_a, s_w = math.radians(self.initial_attitude_sigma_deg), math.radians(self.initial_rate_sigma_deg_s)
        wt = np.array([0.0, 0.0, self.mean_motion_rad_s])
        p = x[13:17]
        q0 = quat_multiply(p, small_rotation(s_a * rng.standard_normal(3)))
        w_true = x[17:20] + quat_rotate_inverse(p, wt)
        w0 = w_true + s_w * rng.standard_normal(3)
        P0 = np.diag([s_a ** 2] * 3 + [s_w ** 2] * 3)
        self.filter = AttitudeMEKF(q0, w0, P0, self.inertia_chief, self.q_accel_psd, frame_rate_rad_s=wt,
                                   gate_probability=1.0 - 1e-9)

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        x = np.array(x_true, dtype=float)
        out = x.copy()
        if self.filter is None:
            self._start(x, rng)
        else:
            dt = max(t - self._t_last, 0.0)
            self.filter.predict(dt)
            self._known_inputs(x, dt)
        self._t_last = t
        f = self.filter
        e = rng.standard_normal(21)  # the 7 draws of 3 in the order of _noisy_measurement (one call: the same numbers)
        sigma_chief = math.radians(self.chief_attitude_sigma_deg)
        f.update_attitude(multiply_kernel(x[13:17], small_rotation(sigma_chief * e[0:3])), sigma_chief)
        if self._sigmas is None:
            self._sigmas = np.array([self.position_sigma_m, self.velocity_sigma_mps, math.radians(self.rate_sigma_deg_s),
                                     math.radians(self.attitude_sigma_deg), self.com_position_sigma_m,
                                     self.com_velocity_sigma_mps])
        out, error_rad = _noisy_measurement(x, e, f.q, f.omega, self._sigmas, self.mean_motion_rad_s)
        self.attitude_errors_deg.append(math.degrees(error_rad))
        return out


@njit(cache=True)
def _noisy_measurement(x, e, p_hat, omega_hat, sigmas, n0):  # pragma: no cover - compiled
    """The measured state (34) of :meth:`HybridNavigation.measure` from the truth x and the normal draws
    e[3:21], with the MEKF's chief attitude p_hat (sign with q_mu >= 0) and omega_c = omega_hat -
    C_{C<-T}(p_hat) [0, 0, n0]; sigmas = [position (m), velocity (m/s), rate (rad/s), attitude (rad), CoM
    position (m), CoM velocity (m/s)] in the order of the draws: rho, rho_dot, omega, q (a small rotation),
    rho_n, rho_n_dot. Returns (measured state, |log(p_hat^-1 (x) p)| (rad), the estimate's attitude error)."""
    out = x.copy()
    if p_hat[3] < 0.0:
        p_hat = -p_hat
    out[13:17] = p_hat
    R = dcm_kernel(p_hat)
    for i in range(3):
        out[17 + i] = omega_hat[i] - n0 * R[2, i]
        out[i] += sigmas[0] * e[3 + i]
        out[3 + i] += sigmas[1] * e[6 + i]
        out[6 + i] += sigmas[2] * e[9 + i]
        out[20 + i] += sigmas[4] * e[15 + i]
        out[23 + i] += sigmas[5] * e[18 + i]
    q = multiply_kernel(x[9:13], rotation_quaternion_kernel(sigmas[3] * e[12:15]))
    if q[3] < 0.0:
        q = -q
    out[9:13] = q
    err = attitude_error_kernel(p_hat, x[13:17])
    return out, math.sqrt(err[0] * err[0] + err[1] * err[1] + err[2] * err[2])
