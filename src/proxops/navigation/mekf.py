"""Multiplicative EKF (MEKF) of a rigid body's attitude and body rate from pose measurements.

State: the attitude quaternion ``q`` of the body frame B relative to a reference frame A
(scalar-last Hamilton, :mod:`proxops.core.quaternion`: ``quat_to_dcm(q)`` maps B components to A
components), the body rate ``omega = omega_{B/I}|_B`` (rad/s) and, optionally, a gyro bias ``b``
(rad/s). A is inertial by default; ``frame_rate_rad_s`` lets A rotate at a constant rate (A
components, e.g. the Hill frame of a circular orbit, [0, 0, n]), the body rate staying inertial.

Error state (3 + 3 [+ 3]): the body-frame small rotation ``dtheta`` with
``q_true = q (x) exp(dtheta / 2)`` (the convention of
:class:`proxops.navigation.GaussianNavigation`'s quaternion noise), ``domega = omega_true - omega``
and ``db = b_true - b``. The filter keeps the unit quaternion and the additive rest; the
covariance ``P`` is that of the error state (rad^2, rad^2/s, rad^2/s^2).

Process model: torque-free rigid-body rotation, Euler's equations ``J omega_dot = -omega x J omega``
plus white angular acceleration of PSD ``q_accel_psd`` (rad^2/s^3 per body axis; covers unmodelled
torques and inertia errors), ``qdot = 0.5 q (x) [omega, 0]`` (Basu et al. eq. 27). The
bias (when estimated) is a random walk of PSD ``q_bias_psd`` (rad^2/s^3). The mean is integrated
with classical RK4 on ``[q, omega]`` in substeps (at most ``max_substep_s`` and
``max_substep_angle_rad`` of rotation each), the quaternion renormalised after each. Error
dynamics (Markley & Crassidis, Fundamentals of Spacecraft Attitude Determination and Control,
2014, §7.2.3, for a body-frame error):

    dtheta_dot = -[omega]x dtheta + domega
    domega_dot = J^-1 ([J omega]x - [omega]x J) domega + eps       (eps: angular acceleration noise)
    db_dot     = eps_b

linearised at the substep's mean rate (average of its two ends); Phi and Q_d of each substep
come exactly from Van Loan's matrix exponential of that constant F (as
:func:`proxops.navigation.ekf.cw_process_noise`). tests/test_navigation_mekf.py checks Phi against
finite differences of the mean propagation and Q_d against quadrature.

Measurements (``update_attitude``): a pose attitude ``q_meas = q_true (x) exp(v / 2)``,
``v ~ N(0, sigma_rad^2 I)`` (camera/LIDAR pose; :class:`PoseAttitudeSensor` simulates it). The
innovation is the rotation vector ``log(q^-1 (x) q_meas)`` (the shorter of +-q), H = [I 0 (0)].
Optionally a rate (gyro-like) measurement ``omega_meas = omega_true (+ b) + N(0, sigma^2 I)``
(``update_rate``). Both use the update of :class:`proxops.navigation.ekf.RelativeEKF`: expanded
Joseph form, chi-square gate at ``gate_probability`` (a rejected measurement leaves the state,
counts in ``rejected`` and adds a ``nav-rejected`` event). After an accepted attitude update the
correction ``a = K nu`` is moved into the quaternion, ``q <- q (x) exp(a / 2)``, and the covariance
is reset to the new reference to first order, ``P <- G P G^T``, ``G = blockdiag(I - [a]x / 2, I)``
(the error after the reset is e' = (I - [a]x / 2) e - a, from exp(-a/2) (x) exp(e/2) to second
order; Mueller, Hehn & D'Andrea, "Covariance correction step for Kalman filtering with an attitude",
J. Guid. Control Dyn. 40(9), 2017). Field of view and dropouts are the caller's: it simply does
not call an update (:class:`PoseAttitudeSensor` returns None).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from proxops.core.quaternion import (multiply_kernel, quat_normalize, rotation_quaternion_kernel,
                                     rotation_vector_kernel)
from proxops.core.small_linalg import expm_pade13, gated_kalman_update, mahalanobis_squared, matmul, symmetrised
from proxops.errors import input_error
from proxops.navigation import small_rotation
from proxops.navigation.consistency import chi2_band


def rotation_vector(q: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of unit ``q``: angle * axis, angle in [0, pi] (the shorter of +-q);
    the inverse of :func:`proxops.navigation.small_rotation` (exp(phi / 2)); numba:
    :func:`proxops.core.quaternion.rotation_vector_kernel`."""
    return rotation_vector_kernel(np.ascontiguousarray(q, dtype=float))


def attitude_error(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Body-frame error rotation vector ``dtheta = log(q_est^-1 (x) q_true)`` (rad)."""
    return attitude_error_kernel(np.ascontiguousarray(q_est, dtype=float), np.ascontiguousarray(q_true, dtype=float))


@njit(cache=True)
def attitude_error_kernel(q_est, q_true):  # pragma: no cover - compiled
    """:func:`attitude_error` inside numba code: the rotation vector of conj(q_est) (x) q_true."""
    conj = np.empty(4)
    conj[0], conj[1], conj[2], conj[3] = -q_est[0], -q_est[1], -q_est[2], q_est[3]
    return rotation_vector_kernel(multiply_kernel(conj, q_true))


def euler_rate(omega: np.ndarray, inertia: np.ndarray, inertia_inv: np.ndarray) -> np.ndarray:
    """Torque-free Euler equations: omega_dot = -J^-1 (omega x J omega) (rad/s^2)."""
    return -inertia_inv @ np.cross(omega, inertia @ omega)


def error_dynamics(omega: np.ndarray, inertia: np.ndarray, inertia_inv: np.ndarray, bias: bool = False) -> np.ndarray:
    """Continuous error-state matrix F (6x6 or 9x9) at the body rate ``omega`` (module docstring;
    one numba call, :func:`_error_dynamics_kernel`)."""
    return _error_dynamics_kernel(np.ascontiguousarray(omega, dtype=float), np.ascontiguousarray(inertia, dtype=float),
                                  np.ascontiguousarray(inertia_inv, dtype=float), 9 if bias else 6)


@njit(cache=True)
def _error_dynamics_kernel(w, J, J_inv, n):  # pragma: no cover - compiled
    """F (n x n, n = 6 or 9) of :func:`error_dynamics`: F[:3, :3] = -[w]x, F[:3, 3:6] = I,
    F[3:6, 3:6] = J^-1 ([J w]x - [w]x J)."""
    F = np.zeros((n, n))
    h0 = J[0, 0] * w[0] + J[0, 1] * w[1] + J[0, 2] * w[2]
    h1 = J[1, 0] * w[0] + J[1, 1] * w[1] + J[1, 2] * w[2]
    h2 = J[2, 0] * w[0] + J[2, 1] * w[1] + J[2, 2] * w[2]
    sw = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    sh = np.array([[0.0, -h2, h1], [h2, 0.0, -h0], [-h1, h0, 0.0]])
    M = matmul(J_inv, sh - matmul(sw, J))  # J^-1 ([J w]x - [w]x J)
    for i in range(3):
        F[i, 3 + i] = 1.0
        for j in range(3):
            F[i, j] = -sw[i, j]
            F[3 + i, 3 + j] = M[i, j]
    return F


def van_loan(F: np.ndarray, Qc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Q_d) of x_dot = F x + w, E[w w^T] = Qc delta, over ``dt`` s, F constant: Van Loan,
    expm([[-F, Qc], [0, F^T]] dt) = [[., E12], [0, E22]] -> Phi = E22^T, Q_d = Phi E12 (symmetrised).
    One numba call (:func:`_van_loan_kernel`; the exponential is
    :func:`proxops.core.small_linalg.expm_pade13`: no BLAS threads on 12x12 matrices)."""
    return _van_loan_kernel(np.ascontiguousarray(F, dtype=float), np.ascontiguousarray(Qc, dtype=float), float(dt))


@njit(cache=True)
def _van_loan_kernel(F, Qc, dt):  # pragma: no cover - compiled
    """:func:`van_loan` inside numba code."""
    n = F.shape[0]
    m = np.zeros((2 * n, 2 * n))
    for i in range(n):
        for j in range(n):
            m[i, j] = -F[i, j] * dt
            m[i, n + j] = Qc[i, j] * dt
            m[n + i, n + j] = F[j, i] * dt
    e = expm_pade13(m)
    phi = np.ascontiguousarray(e[n:, n:].T)
    return phi, symmetrised(matmul(phi, np.ascontiguousarray(e[:n, n:])))


@njit(cache=True)
def _rigid_rhs(y, J, J_inv):  # pragma: no cover - compiled
    """[qdot; wdot] of torque-free rotation: qdot = 0.5 q (x) [w, 0], wdot = -J^-1 (w x J w)."""
    q0, q1, q2, q3, w0, w1, w2 = y[0], y[1], y[2], y[3], y[4], y[5], y[6]
    out = np.empty(7)
    out[0] = 0.5 * (q3 * w0 + q1 * w2 - q2 * w1)
    out[1] = 0.5 * (q3 * w1 + q2 * w0 - q0 * w2)
    out[2] = 0.5 * (q3 * w2 + q0 * w1 - q1 * w0)
    out[3] = -0.5 * (q0 * w0 + q1 * w1 + q2 * w2)
    h0 = J[0, 0] * w0 + J[0, 1] * w1 + J[0, 2] * w2
    h1 = J[1, 0] * w0 + J[1, 1] * w1 + J[1, 2] * w2
    h2 = J[2, 0] * w0 + J[2, 1] * w1 + J[2, 2] * w2
    c0, c1, c2 = w1 * h2 - w2 * h1, w2 * h0 - w0 * h2, w0 * h1 - w1 * h0
    for i in range(3):
        out[4 + i] = -(J_inv[i, 0] * c0 + J_inv[i, 1] * c1 + J_inv[i, 2] * c2)
    return out


@njit(cache=True)
def _rk4_step(y, h, J, J_inv):  # pragma: no cover - compiled
    """One classical RK4 step of :func:`_rigid_rhs` over ``h`` s, quaternion renormalised."""
    k1 = _rigid_rhs(y, J, J_inv)
    k2 = _rigid_rhs(y + 0.5 * h * k1, J, J_inv)
    k3 = _rigid_rhs(y + 0.5 * h * k2, J, J_inv)
    k4 = _rigid_rhs(y + h * k3, J, J_inv)
    out = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    nq = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3])
    for i in range(4):
        out[i] /= nq
    return out


@njit(cache=True)
def _sandwich(A, P):  # pragma: no cover - compiled
    """A P A^T, symmetrised."""
    return symmetrised(matmul(matmul(A, P), np.ascontiguousarray(A.T)))


@njit(cache=True)
def _predict_kernel(q, w, P, dt, J, J_inv, Qc, frame_rate, rotating, max_substep_s,
                    max_substep_angle_rad):  # pragma: no cover - compiled
    """:meth:`AttitudeMEKF.predict` for dt > 0 s: (q, omega, P) after ``dt``, in RK4 substeps of at most
    max_substep_s and max_substep_angle_rad of rotation. Each substep: Phi, Q_d from Van Loan at the
    substep's mean rate, P <- Phi P Phi^T + Q_d (symmetrised); with ``rotating`` the reference frame turns
    at ``frame_rate`` (rad/s, its own axes): q <- exp(-w_A h / 2) (x) q; q renormalised."""
    n = P.shape[0]
    rate = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    n_sub = max(1, math.ceil(dt / max_substep_s), math.ceil(rate * dt / max_substep_angle_rad))
    h = dt / n_sub
    y = np.empty(7)
    q, w, P = q.copy(), w.copy(), P.copy()
    w_mid = np.empty(3)
    for _ in range(n_sub):
        y[0:4] = q
        y[4:7] = w
        y1 = _rk4_step(y, h, J, J_inv)
        for i in range(3):
            w_mid[i] = 0.5 * (w[i] + y1[4 + i])
        phi, qd = _van_loan_kernel(_error_dynamics_kernel(w_mid, J, J_inv, n), Qc, h)
        P = symmetrised(matmul(matmul(phi, P), np.ascontiguousarray(phi.T)) + qd)
        qn = y1[0:4].copy()
        if rotating:
            qn = multiply_kernel(rotation_quaternion_kernel(-h * frame_rate), qn)
        nq = math.sqrt(qn[0] * qn[0] + qn[1] * qn[1] + qn[2] * qn[2] + qn[3] * qn[3])
        for i in range(4):
            q[i] = qn[i] / nq
        w[:] = y1[4:7]
    return q, w, P


@njit(cache=True)
def _update_kernel(q, w, b, P, nu, H, R, gate, bias):  # pragma: no cover - compiled
    """The arithmetic of :meth:`AttitudeMEKF._update`: S = H P H^T + R, NIS = nu^T S^-1 nu; when
    NIS <= gate, the expanded Joseph form P - K H P - (K H P)^T + K S K^T with K = P H^T S^-1, the
    correction a = K nu moved into q <- q (x) exp(a / 2) (renormalised), omega (and the bias), and the
    reset P <- G P G^T (symmetrised), G = blockdiag(I - [a]x / 2, I). Returns (q, omega, b, P, nis,
    accepted); a rejected update returns its inputs."""
    dx, Pn, _, nis, accepted = gated_kalman_update(P, H, R, nu, gate)
    if not accepted:
        return q, w, b, P, nis, False
    n = P.shape[0]
    qn = multiply_kernel(q, rotation_quaternion_kernel(dx[0:3]))
    nq = math.sqrt(qn[0] * qn[0] + qn[1] * qn[1] + qn[2] * qn[2] + qn[3] * qn[3])
    for i in range(4):
        qn[i] /= nq
    bn = b + dx[6:9] if bias else b.copy()
    G = np.eye(n)  # I - [a]x / 2 on the attitude block
    G[0, 1], G[0, 2] = 0.5 * dx[2], -0.5 * dx[1]
    G[1, 0], G[1, 2] = -0.5 * dx[2], 0.5 * dx[0]
    G[2, 0], G[2, 1] = 0.5 * dx[1], -0.5 * dx[0]
    return qn, w + dx[3:6], bn, _sandwich(G, Pn), nis, True


def _inertia_matrix(inertia) -> np.ndarray:
    J = np.asarray(inertia, dtype=float)
    if J.shape == (3,):
        J = np.diag(J)
    if J.shape != (3, 3) or not np.all(np.isfinite(J)) or not np.allclose(J, J.T, rtol=1e-12, atol=0.0):
        raise input_error("attitude filter inertia", np.asarray(inertia).tolist(),
                          "must be 3 principal moments or a symmetric 3x3 matrix", "kg m^2")
    if not np.linalg.eigvalsh(J).min() > 0.0:
        raise input_error("attitude filter inertia", np.asarray(inertia).tolist(), "must be positive definite", "kg m^2")
    return J


@dataclass(frozen=True)
class AttitudeUpdate:
    """Result of one measurement update: innovation (rad or rad/s), its NIS, and whether the
    chi-square gate accepted it."""

    innovation: np.ndarray
    nis: float
    accepted: bool


class AttitudeMEKF:
    """Multiplicative EKF of attitude + body rate (+ gyro bias): see the module docstring.

    ``q0`` (4, scalar last), ``w0`` (3, rad/s), ``b0`` (3, rad/s; only with ``gyro_bias``): the
    initial estimate. ``P0``: initial error covariance (6x6, or 9x9 with ``gyro_bias``; rad^2,
    rad^2/s^2 blocks). ``inertia``: principal moments (3,) or 3x3 (kg m^2; only its ratios matter).
    ``q_accel_psd``: angular-acceleration PSD per axis (rad^2/s^3). ``frame_rate_rad_s``: rate of
    the reference frame A (A components, rad/s), None = inertial.
    """

    def __init__(self, q0, w0, P0, inertia, q_accel_psd: float, *, gyro_bias: bool = False, b0=None,
                 q_bias_psd: float = 0.0, gate_probability: float = 0.9999, frame_rate_rad_s=None,
                 max_substep_s: float = 1.0, max_substep_angle_rad: float = 0.05):
        from scipy.stats import chi2

        self.J = _inertia_matrix(inertia)
        self.J_inv = np.linalg.inv(self.J)
        self.gyro_bias = bool(gyro_bias)
        self.n = 9 if self.gyro_bias else 6
        if not (math.isfinite(q_accel_psd) and q_accel_psd >= 0.0):
            raise input_error("attitude filter q_accel_psd", q_accel_psd, "must be >= 0", "rad^2/s^3")
        if not (math.isfinite(q_bias_psd) and q_bias_psd >= 0.0):
            raise input_error("attitude filter q_bias_psd", q_bias_psd, "must be >= 0", "rad^2/s^3")
        if not 0.0 < gate_probability < 1.0:
            raise input_error("attitude filter gate_probability", gate_probability, "must be in (0, 1)")
        if not (max_substep_s > 0.0 and max_substep_angle_rad > 0.0):
            raise input_error("attitude filter max_substep", (max_substep_s, max_substep_angle_rad), "must be > 0")
        self.q_accel_psd = float(q_accel_psd)
        self.q_bias_psd = float(q_bias_psd)
        self.gate_probability = float(gate_probability)
        self.gates = {m: float(chi2.ppf(gate_probability, m)) for m in (3,)}
        self.max_substep_s = float(max_substep_s)
        self.max_substep_angle_rad = float(max_substep_angle_rad)
        self.frame_rate = None if frame_rate_rad_s is None else np.asarray(frame_rate_rad_s, dtype=float)
        self._frame_rate = np.zeros(3) if self.frame_rate is None else np.ascontiguousarray(self.frame_rate, dtype=float)
        self._H_attitude = np.zeros((3, self.n))  # pose attitude: H = [I 0 (0)]
        self._H_attitude[:, :3] = np.eye(3)
        self.Qc = np.zeros((self.n, self.n))
        self.Qc[3:6, 3:6] = self.q_accel_psd * np.eye(3)
        if self.gyro_bias:
            self.Qc[6:9, 6:9] = self.q_bias_psd * np.eye(3)
        self.reset(q0, w0, P0, b0)

    def reset(self, q0, w0, P0, b0=None) -> None:
        """Start again from the estimate (q0, w0[, b0]) with error covariance P0."""
        P0 = np.asarray(P0, dtype=float)
        if P0.shape != (self.n, self.n) or not np.allclose(P0, P0.T, rtol=1e-12, atol=0.0):
            raise input_error("attitude filter P0", f"shape {P0.shape}", f"must be a symmetric {self.n}x{self.n} matrix",
                              "rad^2, rad^2/s^2")
        if not np.linalg.eigvalsh(P0).min() > 0.0:
            raise input_error("attitude filter P0", f"min eigenvalue {np.linalg.eigvalsh(P0).min():.3g}",
                              "must be positive definite")
        self._q = quat_normalize(np.asarray(q0, dtype=float))
        self._w = np.array(w0, dtype=float).reshape(3)
        self._b = np.zeros(3) if b0 is None else np.array(b0, dtype=float).reshape(3)
        self._P = P0.copy()
        self.nis: list[float] = []
        self.rejected = 0
        self.updates = 0
        self.events: list[tuple[str, str]] = []

    def add_rate(self, delta_omega=None, rate_variance: float = 0.0) -> None:
        """Known changes between two samples (HybridNavigation's): the body rate estimate moves by
        ``delta_omega`` (rad/s, body axes; a commanded torque's effect) and ``rate_variance`` (rad^2/s^2,
        >= 0) is added to each rate variance (an impulse of unknown size). In place, counters kept."""
        if delta_omega is not None:
            self._w = self._w + np.asarray(delta_omega, dtype=float)
        if rate_variance > 0.0:
            P = self._P.copy()
            for i in range(3, 6):
                P[i, i] += rate_variance
            self._P = P

    # --- state ------------------------------------------------------------------------
    @property
    def q(self) -> np.ndarray:
        """Attitude estimate (unit quaternion, scalar last) of B relative to A."""
        return self._q.copy()

    @property
    def omega(self) -> np.ndarray:
        """Body-rate estimate (rad/s, B components, relative to inertial space)."""
        return self._w.copy()

    @property
    def bias(self) -> np.ndarray:
        """Gyro-bias estimate (rad/s; zeros without ``gyro_bias``)."""
        return self._b.copy()

    @property
    def P(self) -> np.ndarray:
        """Error-state covariance (n x n)."""
        return self._P.copy()

    # --- prediction -------------------------------------------------------------------
    def predict(self, dt: float) -> None:
        """Propagate the estimate and covariance by ``dt`` s (>= 0) under torque-free rotation."""
        if not (math.isfinite(dt) and dt >= 0.0):
            raise input_error("attitude filter dt", dt, "must be finite and >= 0", "s")
        if dt == 0.0:
            return
        self._q, self._w, self._P = _predict_kernel(self._q, self._w, self._P, float(dt), self.J, self.J_inv, self.Qc,
                                                    self._frame_rate, self.frame_rate is not None, self.max_substep_s,
                                                    self.max_substep_angle_rad)

    # --- updates ----------------------------------------------------------------------
    def _update(self, nu: np.ndarray, H: np.ndarray, R: np.ndarray, kind: str) -> AttitudeUpdate:
        """Linear update of the error state with innovation ``nu`` (3,), H (3 x n), R (3x3):
        chi-square gate, expanded Joseph form (as RelativeEKF.update), then the reset."""
        q, w, b, P, nis, accepted = _update_kernel(self._q, self._w, self._b, self._P, np.ascontiguousarray(nu, dtype=float),
                                                   H, R, self.gates[3], self.gyro_bias)
        self.nis.append(nis)
        if not accepted:
            self.rejected += 1
            self.events.append(("nav-rejected", f"{kind} measurement rejected: NIS {nis:.3g} > {self.gates[3]:.3g} "
                                f"(chi-square {self.gate_probability:g}, 3 dof)"))
            return AttitudeUpdate(nu, nis, False)
        self._q, self._w, self._b, self._P = q, w, b, P
        self.updates += 1
        return AttitudeUpdate(nu, nis, True)

    def update_attitude(self, q_meas, sigma_rad: float) -> AttitudeUpdate:
        """Pose-attitude update with ``q_meas`` (unit quaternion, scalar last) of 1-sigma
        ``sigma_rad`` per axis (body-frame small rotation). Returns innovation (rad), NIS, accepted."""
        if not (math.isfinite(sigma_rad) and sigma_rad > 0.0):
            raise input_error("attitude sigma", sigma_rad, "must be > 0", "rad")
        q_meas = np.asarray(q_meas, dtype=float)
        nu = attitude_error(self._q, q_meas / math.sqrt(float(q_meas @ q_meas)))
        return self._update(nu, self._H_attitude, sigma_rad ** 2 * np.eye(3), "attitude")

    def update_rate(self, w_meas, sigma_rad_s: float) -> AttitudeUpdate:
        """Rate (gyro-like) update: ``w_meas = omega (+ b) + N(0, sigma^2 I)`` (rad/s)."""
        if not (math.isfinite(sigma_rad_s) and sigma_rad_s > 0.0):
            raise input_error("rate sigma", sigma_rad_s, "must be > 0", "rad/s")
        H = np.zeros((3, self.n))
        H[:, 3:6] = np.eye(3)
        if self.gyro_bias:
            H[:, 6:9] = np.eye(3)
        nu = np.asarray(w_meas, dtype=float) - (self._w + self._b)
        return self._update(nu, H, sigma_rad_s ** 2 * np.eye(3), "rate")

    # --- consistency ------------------------------------------------------------------
    def error(self, q_true, w_true, b_true=None) -> np.ndarray:
        """True error state [dtheta, domega(, db)] (rad, rad/s) of the estimate."""
        e = [attitude_error(self._q, np.asarray(q_true, dtype=float)), np.asarray(w_true, dtype=float) - self._w]
        if b_true is not None:
            e.append(np.asarray(b_true, dtype=float) - self._b)
        return np.concatenate(e)

    def nees(self, q_true, w_true, b_true=None) -> float:
        """Normalised estimation error squared e^T P^-1 e of attitude + rate (6 dof), or of the
        full 9-state error when ``b_true`` is given (the bias marginalised otherwise)."""
        e = self.error(q_true, w_true, b_true)
        P = self._P[: e.size, : e.size]
        return mahalanobis_squared(np.ascontiguousarray(P), e)


@dataclass
class PoseAttitudeSensor:
    """Simulated attitude part of a camera/LIDAR pose measurement (and an optional rate).

    ``sigma_rad``: 1-sigma per axis of the body-frame small rotation of the measured attitude,
    ``q_meas = q_true (x) exp(v / 2)``, ``v ~ N(0, sigma^2 I)``. ``rate_sigma_rad_s``: also a
    rate measurement ``w_true + N(0, sigma^2 I)`` (None: none). Visibility: the line of sight
    ``direction`` the caller gives (any frame) must lie within half of ``fov_rad`` (full cone
    angle, (0, pi]) of ``boresight`` (the same frame; None: no cone), the measurement is lost
    with ``outage_probability``, and ``illuminated(t)`` (callable, None: always lit) must be True.
    Each call draws the same numbers whatever happens (one uniform, then 3 normals, then 3 more
    with a rate sigma), so the navigation stream never shifts.
    """

    sigma_rad: float
    rate_sigma_rad_s: float | None = None
    fov_rad: float = math.pi
    boresight: np.ndarray | None = None
    outage_probability: float = 0.0
    illuminated: object = None

    def __post_init__(self):
        if not (math.isfinite(self.sigma_rad) and self.sigma_rad > 0.0):
            raise input_error("navigation.attitude_sigma_deg", math.degrees(self.sigma_rad), "must be > 0", "deg")
        if self.rate_sigma_rad_s is not None and not (math.isfinite(self.rate_sigma_rad_s) and self.rate_sigma_rad_s > 0):
            raise input_error("navigation.attitude_rate_sigma_deg_s", math.degrees(self.rate_sigma_rad_s),
                              "must be > 0 (or none: no rate measurement)", "deg/s")
        if not (0.0 < self.fov_rad <= math.pi + 1e-12):
            raise input_error("navigation.attitude_fov_deg", math.degrees(self.fov_rad), "must be in (0, 180]", "deg")
        if not (0.0 <= self.outage_probability <= 1.0):
            raise input_error("navigation.outage_probability", self.outage_probability, "must be in [0, 1]")
        if self.boresight is not None:
            b = np.asarray(self.boresight, dtype=float)
            if not np.linalg.norm(b) > 0.0:
                raise input_error("attitude sensor boresight", b.tolist(), "must be a non-zero vector")
            self.boresight = b / np.linalg.norm(b)

    def visible(self, t: float, direction) -> bool:
        """Line of sight ``direction`` within the cone (half-angle fov/2 about the boresight) and lit."""
        if self.boresight is not None and self.fov_rad < math.pi:
            d = np.asarray(direction, dtype=float)
            r = math.sqrt(float(d @ d))
            if r == 0.0 or float(d @ self.boresight) / r < math.cos(0.5 * self.fov_rad):
                return False
        return self.illuminated is None or bool(self.illuminated(t))

    def draw(self, t: float, q_true, w_true, direction, rng: np.random.Generator):
        """(q_meas or None, w_meas or None) of the truth (None: outage, out of view, eclipse)."""
        u = rng.random()
        v = rng.standard_normal(3)
        e = rng.standard_normal(3) if self.rate_sigma_rad_s is not None else None
        if u < self.outage_probability or not self.visible(t, direction):
            return None, None
        q = multiply_kernel(np.asarray(q_true, dtype=float), small_rotation(self.sigma_rad * v))
        w = None if e is None else np.asarray(w_true, dtype=float) + self.rate_sigma_rad_s * e
        return q / math.sqrt(float(q @ q)), w


def attitude_summary(stats: dict, prefix: str = "att") -> dict:
    """``att_*`` run-summary keys of an attitude filter's :attr:`proxops.navigation.target_attitude.TargetAttitudeNavigation.record`-like
    dict: mean NEES, its per-epoch two-sided 95 % chi-square band (``nees_dof`` dof) and the fraction
    of epochs inside it (0.95 expected of a consistent filter), the same for the NIS of the updates,
    the attitude error (deg) and rate error (deg/s) (median, p95, max), updates and rejections."""
    out: dict = {}
    out.update(consistency_keys(stats.get("nees", []), stats.get("nees_dof", 6), f"{prefix}_nees"))
    out.update(consistency_keys(stats.get("nis", []), stats.get("nis_dof", 3), f"{prefix}_nis"))
    for key, name, scale in (("att_err_rad", "error_deg", 180.0 / math.pi),
                             ("rate_err_rad_s", "rate_error_deg_s", 180.0 / math.pi)):
        vals = np.asarray(stats.get(key, []), dtype=float) * scale
        if vals.size:
            out[f"{prefix}_{name}"] = {"median": float(np.median(vals)), "p95": float(np.percentile(vals, 95)),
                                       "max": float(vals.max())}
    out[f"{prefix}_updates"] = int(stats.get("updates", 0))
    out[f"{prefix}_rejected"] = int(stats.get("rejected", 0))
    return out


def consistency_keys(values, dof: int, prefix: str) -> dict:
    """``<prefix>_mean``, ``_band`` (two-sided 95 % chi-square band of one value of ``dof`` dof),
    ``_inside_fraction`` (of the values inside it; 0.95 expected of a consistent filter) and ``_dof``."""
    vals = np.asarray(values, dtype=float)
    lo, hi = chi2_band(dof)
    return {f"{prefix}_mean": float(vals.mean()) if vals.size else None, f"{prefix}_band": [lo, hi],
            f"{prefix}_inside_fraction": float(np.mean((vals >= lo) & (vals <= hi))) if vals.size else None,
            f"{prefix}_dof": int(dof)}
