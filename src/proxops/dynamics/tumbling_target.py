"""Tumbling target: attitude (eq. 2), body-frame relative state (eqs. 7-8) and the
body-frame prediction model with its exact Jacobian (Iskender 2026 §3-4).

Frames. F_I = ECI, F_L = Hill/LVLH of the target (x radial out, y along-track, z orbit
normal), F_B = target body (docking axis +y_B). The target spins at a constant body rate
``omega_B = [0, 0, w_t]`` (rad/s) relative to F_I (eq. 2, torque-free spin about a
principal axis). Quaternion ``q_IB`` (scalar-last Hamilton, proxops.core.quaternion):
``R_IB = quat_to_dcm(q_IB)`` maps body components to ECI components.

Relative state in F_B (eqs. 7-8; checked by differentiating r_B = R_IB^T dr with
dR_IB/dt = R_IB [w_B]x):

    r_B = R_IB^T (r_c - r_t)
    v_B = R_IB^T (v_c - v_t) - w_B x r_B

Prediction model (what the MPC uses). With body z along the orbit normal, F_B turns
relative to F_L about z at ``w_rel = w_t - n`` (the LVLH frame itself turns at n), so
``R_LB(t) = R_z(theta(t))``, ``theta(t) = theta_0 + w_rel t``. Paper eq. (10) writes
R_z(-w_t t), i.e. it drops n; that is a 6.5 % rate error at 1 deg/s (26 deg of phase
after 400 s), so we keep w_t - n. The body state is ``x_B = T(theta) x_L`` with

    T(theta) = [[R, 0], [-W R, R]],   R = R_z(theta)^T = R_BL,   W = [w_rel e_z]x

(v_B = R_BL v_L - w_rel e_z x r_B, the same transport term as eq. 8 written from F_L).
One ZOH step of the CW model (eq. 5, control ``u_L`` in LVLH axes) in body coordinates is

    x_B,k+1 = A_k x_B,k + B_k u_L,k,   A_k = T(theta_k+1) Phi(dt) T(theta_k)^-1,
                                       B_k = T(theta_k+1) B_d(dt)

which is the *exact* Jacobian of the body-frame CW pipeline (it is linear). The paper
obtains these matrices by forward finite differences of the nonlinear pipeline (§4.4);
:class:`NonlinearBodyStep` is that pipeline (exact two-body relative motion about a
circular orbit, RK4) with its exact Jacobian from CasADi automatic differentiation, and
tests/test_tumbling_target.py checks both against finite differences.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
from numba import njit

from proxops.core.constants import MU_EARTH
from proxops.core.cw import cw_discretize_zoh
from proxops.core.quaternion import (IDENTITY, dcm_kernel, dcm_to_quat, propagate_kernel, quat_normalize,
                                     quat_propagate)
from proxops.errors import input_error
from proxops.frames.hill import hill_dcm
from proxops.dynamics.plant import PlantBase


# --------------------------------------------------------------------------------------
# attitude and the exact body-frame state (truth side)
# --------------------------------------------------------------------------------------
class TumblingTarget:
    """Target attitude under a constant body rate about body z (eq. 2).

    ``tumble_rate_rad_s``: w_t (rad/s, sign = sense about +z_B). ``q0_IB``: attitude at
    t = 0 (scalar-last); use :meth:`aligned_with_hill` to start with F_B = F_L rotated by
    ``theta0`` about the orbit normal.
    """

    def __init__(self, tumble_rate_rad_s: float, q0_IB: np.ndarray = IDENTITY):
        if not np.isfinite(tumble_rate_rad_s):
            raise input_error("target.tumble_rate", tumble_rate_rad_s, "must be finite", "rad/s")
        self.tumble_rate_rad_s = float(tumble_rate_rad_s)
        self.q0_IB = quat_normalize(np.asarray(q0_IB, dtype=float))
        self.omega_body = np.array([0.0, 0.0, self.tumble_rate_rad_s])

    @classmethod
    def aligned_with_hill(cls, tumble_rate_rad_s: float, target_eci_state: np.ndarray, theta0_rad: float = 0.0):
        """Target whose body axes equal the Hill axes of ``target_eci_state`` turned by
        ``theta0_rad`` about the orbit normal at t = 0 (body z = orbit normal)."""
        R_IL = hill_dcm(np.asarray(target_eci_state, float)).T  # columns: Hill axes in ECI
        R_IB = R_IL @ rot_z(theta0_rad)
        return cls(tumble_rate_rad_s, dcm_to_quat(R_IB))

    def quaternion(self, t: float) -> np.ndarray:
        """q_IB(t) = q0 (x) exp(0.5 [0, 0, w_t] t): exact solution of eq. (2) (one numba call,
        :func:`proxops.core.quaternion.propagate_kernel`: the bits of :func:`quat_propagate`)."""
        return propagate_kernel(self.q0_IB, self.omega_body, float(t))

    def rotation_inertial_from_body(self, t: float) -> np.ndarray:
        """R_IB(t) (3x3): body components -> ECI components."""
        return dcm_kernel(self.quaternion(t))  # quat_to_dcm (the same bits)

    def body_state_from_offset(self, t: float, eci_offset: np.ndarray) -> np.ndarray:
        """Body-frame relative state [r_B, v_B] (m, m/s) from the ECI offset chaser - target
        (eqs. 7-8)."""
        return body_state_from_offset(self.rotation_inertial_from_body(t), self.omega_body, eci_offset)

    @cached_property
    def initial_rotation(self) -> np.ndarray:
        """R_IB(0) (read-only), computed once per target: every run sharing the target starts with it."""
        R = self.rotation_inertial_from_body(0.0)
        R.flags.writeable = False
        return R

    def offset_from_body_state(self, t: float, body_state: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`body_state_from_offset`: ECI offset [dr, dv] (m, m/s)."""
        R = self.initial_rotation if t == 0.0 else self.rotation_inertial_from_body(t)
        x = np.asarray(body_state, float)
        r_B, v_B = x[:3], x[3:6]
        return np.concatenate([R @ r_B, R @ (v_B + cross3(self.omega_body, r_B))])


def sync_range(a_max_mps2: float, tumble_rate_rad_s: float) -> float:
    """r_sync = 2 a_max / w_t^2 (m), Iskender 2026 eq. (14): inside it the chaser's
    acceleration a_max (m/s^2) can follow the rotating docking axis (tumble rate w_t, rad/s, either
    sign). inf for a target at rest (w_t = 0). The one home of this formula (guidance, reach, los)."""
    if not (math.isfinite(a_max_mps2) and a_max_mps2 > 0.0):
        raise input_error("a_max", a_max_mps2, "must be finite and > 0", "m/s^2")
    if not math.isfinite(tumble_rate_rad_s):
        raise input_error("omega", tumble_rate_rad_s, "tumble rate must be finite", "rad/s")
    if tumble_rate_rad_s == 0.0:
        return math.inf
    return 2.0 * a_max_mps2 / tumble_rate_rad_s**2


def body_state_from_offset(R_IB: np.ndarray, omega_body: np.ndarray, eci_offset: np.ndarray) -> np.ndarray:
    """Eqs. (7)-(8): r_B = R_IB^T dr, v_B = R_IB^T dv - w_B x r_B."""
    d = np.asarray(eci_offset, float)
    r_B = R_IB.T @ d[:3]
    v_B = R_IB.T @ d[3:6] - cross3(omega_body, r_B)
    return np.concatenate([r_B, v_B])


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for two 3-vectors (much cheaper than np.cross on single vectors)."""
    a0, a1, a2 = np.asarray(a, float).tolist()  # Python floats: same arithmetic, less overhead
    b0, b1, b2 = np.asarray(b, float).tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _right_product_matrix(dq: np.ndarray) -> np.ndarray:
    """4x4 matrix M with q (x) dq = M q (Hamilton, scalar last)."""
    x, y, z, w = dq
    return np.array([[w, z, -y, x], [-z, w, x, y], [y, -x, w, z], [-x, -y, -z, w]])


# --------------------------------------------------------------------------------------
# body <-> Hill for a body frame turning about the orbit normal (prediction side)
# --------------------------------------------------------------------------------------
def rot_z(theta: float) -> np.ndarray:
    """Active rotation R_z(theta) (3x3): components in the turned frame -> original frame."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotate_z(theta: float, v: np.ndarray) -> np.ndarray:
    """R_z(theta) v for one 3-vector (rot_z(theta) @ v written out; equal to it up to rounding)."""
    c, s = math.cos(theta), math.sin(theta)
    a, b, z = np.asarray(v, float).tolist()
    return np.array([c * a - s * b, s * a + c * b, z])


def body_from_hill_matrix(theta: float | np.ndarray, w_rel: float) -> np.ndarray:
    """T(theta) (6x6, or (n, 6, 6) for an array of angles): x_B = T x_L for a body frame at
    angle theta about z_L turning at w_rel (rad/s) relative to F_L."""
    th = np.atleast_1d(np.asarray(theta, float))
    c, s = np.cos(th), np.sin(th)
    T = np.zeros((th.size, 6, 6))
    # R = R_z(theta)^T
    T[:, 0, 0] = c
    T[:, 0, 1] = s
    T[:, 1, 0] = -s
    T[:, 1, 1] = c
    T[:, 2, 2] = 1.0
    T[:, 3:6, 3:6] = T[:, 0:3, 0:3]
    # -W R with W = w_rel [e_z]x = w_rel [[0,-1,0],[1,0,0],[0,0,0]]
    T[:, 3, 0] = w_rel * (-s)
    T[:, 3, 1] = w_rel * c
    T[:, 4, 0] = -w_rel * c
    T[:, 4, 1] = -w_rel * s
    return T[0] if np.ndim(theta) == 0 else T


def hill_from_body_matrix(theta: float, w_rel: float) -> np.ndarray:
    """T(theta)^-1 = [[R^T, 0], [R^T W, R^T]] (6x6): x_L = T^-1 x_B."""
    Rt = rot_z(theta)
    W = w_rel * np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    Ti = np.zeros((6, 6))
    Ti[0:3, 0:3] = Rt
    Ti[3:6, 3:6] = Rt
    Ti[3:6, 0:3] = Rt @ W
    return Ti


class BodyFrameModel:
    """CW prediction model written in the rotating target body frame (see module doc).

    ``mean_motion`` n (rad/s), ``tumble_rate_rad_s`` w_t, ``dt`` (s), ``theta0_rad`` angle
    of F_B about z_L at t = 0. Control ``u`` is an LVLH acceleration (m/s^2), ZOH.
    """

    def __init__(self, mean_motion: float, tumble_rate_rad_s: float, dt: float, theta0_rad: float = 0.0):
        if not mean_motion > 0.0:
            raise input_error("mean_motion", mean_motion, "must be > 0", "rad/s")
        if not dt > 0.0:
            raise input_error("dt", dt, "must be > 0", "s")
        self.n = float(mean_motion)
        self.tumble_rate_rad_s = float(tumble_rate_rad_s)
        self.w_rel = self.tumble_rate_rad_s - self.n
        self.dt = float(dt)
        self.theta0_rad = float(theta0_rad)
        self.Phi, self.Bd = cw_discretize_zoh(self.n, self.dt)

    def theta(self, t: float | np.ndarray) -> float | np.ndarray:
        """Angle of F_B about z_L (rad) at time t (s): theta0 + (w_t - n) t."""
        return self.theta0_rad + self.w_rel * np.asarray(t, float)

    def rotation_body_from_hill(self, t: float) -> np.ndarray:
        """R_BL(t) (3x3)."""
        return rot_z(float(self.theta(t))).T

    def body_from_hill(self, t: float, x_hill: np.ndarray) -> np.ndarray:
        """x_B = T(theta(t)) x_L (written out: r_B = R_BL r_L, v_B = R_BL v_L - W x r_B)."""
        th = self.theta0_rad + self.w_rel * t
        c, s, w = np.cos(th), np.sin(th), self.w_rel
        x = x_hill
        rb0, rb1 = c * x[0] + s * x[1], -s * x[0] + c * x[1]
        return np.array([rb0, rb1, x[2], c * x[3] + s * x[4] + w * rb1, -s * x[3] + c * x[4] - w * rb0, x[5]])

    def hill_from_body(self, t: float, x_body: np.ndarray) -> np.ndarray:
        """x_L = T(theta(t))^-1 x_B (r_L = R_LB r_B, v_L = R_LB (v_B + W x r_B))."""
        th = self.theta0_rad + self.w_rel * t
        c, s, w = np.cos(th), np.sin(th), self.w_rel
        x = x_body
        v0, v1 = x[3] - w * x[1], x[4] + w * x[0]
        return np.array([c * x[0] - s * x[1], s * x[0] + c * x[1], x[2], c * v0 - s * v1, s * v0 + c * v1, x[5]])

    def step_matrices(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Exact Jacobians (A_k, B_k) of x_B(t + dt) w.r.t. (x_B(t), u_L) (module doc)."""
        T_next = body_from_hill_matrix(float(self.theta(t + self.dt)), self.w_rel)
        return T_next @ self.Phi @ hill_from_body_matrix(float(self.theta(t)), self.w_rel), T_next @ self.Bd

    def step(self, t: float, x_body: np.ndarray, u_hill: np.ndarray) -> np.ndarray:
        A, B = self.step_matrices(t)
        return A @ np.asarray(x_body, float) + B @ np.asarray(u_hill, float)

    def horizon_transforms(self, t: float, n_steps: int) -> np.ndarray:
        """T(theta(t + j dt)) for j = 0..n_steps, shape (n_steps + 1, 6, 6)."""
        return body_from_hill_matrix(self.theta(t + self.dt * np.arange(n_steps + 1)), self.w_rel)


# --------------------------------------------------------------------------------------
# the nonlinear pipeline of §4.4 and its exact Jacobian (CasADi AD)
# --------------------------------------------------------------------------------------
class NonlinearBodyStep:
    """One ZOH step of the nonlinear pipeline x_B,k -> x_L -> integrate -> x_B,k+1.

    Relative motion is exact two-body about a circular reference orbit of radius
    ``sma_m`` in Hill coordinates (x_dd = 2n y_d + n^2 (a + x) - mu (a + x)/rho^3 + u_x,
    y_dd = -2n x_d + n^2 y - mu y/rho^3 + u_y, z_dd = -mu z/rho^3 + u_z), integrated with
    ``substeps`` RK4 steps; CW (eq. 4) is its first-order expansion. ``jacobian(t, x, u)``
    returns the exact derivative of this discrete map (CasADi AD).
    """

    def __init__(self, sma_m: float, tumble_rate_rad_s: float, dt: float, theta0_rad: float = 0.0,
                 mu: float = MU_EARTH, substeps: int = 10):
        self.a = float(sma_m)
        self.mu = float(mu)
        self.n = float(np.sqrt(mu / sma_m**3))
        self.w_rel = float(tumble_rate_rad_s) - self.n
        self.dt = float(dt)
        self.theta0_rad = float(theta0_rad)
        self.substeps = int(substeps)

    @cached_property
    def _functions(self):
        import casadi as ca

        x = ca.SX.sym("x", 6)
        u = ca.SX.sym("u", 3)
        th = ca.SX.sym("theta")
        a, mu, n, w = self.a, self.mu, self.n, self.w_rel

        def T_inv(theta, xb):  # body -> Hill
            c, s = ca.cos(theta), ca.sin(theta)
            rb, vb = xb[0:3], xb[3:6]
            vb_plus = ca.vertcat(vb[0] - w * rb[1], vb[1] + w * rb[0], vb[2])  # v_B + W r_B
            rot = lambda p: ca.vertcat(c * p[0] - s * p[1], s * p[0] + c * p[1], p[2])  # R_z(theta)
            return ca.vertcat(rot(rb), rot(vb_plus))

        def T(theta, xl):  # Hill -> body
            c, s = ca.cos(theta), ca.sin(theta)
            rot_t = lambda p: ca.vertcat(c * p[0] + s * p[1], -s * p[0] + c * p[1], p[2])  # R_z(theta)^T
            rb = rot_t(xl[0:3])
            vb = rot_t(xl[3:6])
            return ca.vertcat(rb, vb[0] + w * rb[1], vb[1] - w * rb[0], vb[2])

        def f(xl):
            px, py, pz = a + xl[0], xl[1], xl[2]
            rho3 = (px * px + py * py + pz * pz) ** 1.5
            return ca.vertcat(
                xl[3:6],
                2 * n * xl[4] + n * n * px - mu * px / rho3 + u[0],
                -2 * n * xl[3] + n * n * py - mu * py / rho3 + u[1],
                -mu * pz / rho3 + u[2],
            )

        h = self.dt / self.substeps
        xl = T_inv(th, x)
        for _ in range(self.substeps):
            k1 = f(xl)
            k2 = f(xl + 0.5 * h * k1)
            k3 = f(xl + 0.5 * h * k2)
            k4 = f(xl + h * k3)
            xl = xl + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        x_next = T(th + w * self.dt, xl)
        step = ca.Function("body_step", [th, x, u], [x_next])
        jac = ca.Function("body_step_jacobian", [th, x, u], [ca.jacobian(x_next, x), ca.jacobian(x_next, u)])
        return step, jac

    def theta(self, t: float) -> float:
        return self.theta0_rad + self.w_rel * float(t)

    def step(self, t: float, x_body: np.ndarray, u_hill: np.ndarray) -> np.ndarray:
        """x_B(t + dt) (m, m/s) from x_B(t) under the LVLH ZOH acceleration u_hill (m/s^2)."""
        step, _ = self._functions
        return np.asarray(step(self.theta(t), np.asarray(x_body, float), np.asarray(u_hill, float))).ravel()

    def jacobian(self, t: float, x_body: np.ndarray, u_hill: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact (A, B) = d x_B(t+dt) / d (x_B(t), u) of the discrete nonlinear map."""
        _, jac = self._functions
        A, B = jac(self.theta(t), np.asarray(x_body, float), np.asarray(u_hill, float))
        return np.asarray(A), np.asarray(B)

    def finite_difference_jacobian(self, t: float, x_body, u_hill, eps: float = 1e-6):
        """The paper's forward differences (§4.4, eps = 1e-6) of :meth:`step`."""
        x0 = np.asarray(x_body, float)
        u0 = np.asarray(u_hill, float)
        f0 = self.step(t, x0, u0)
        A = np.zeros((6, 6))
        B = np.zeros((6, 3))
        for i in range(6):
            dx = np.zeros(6)
            dx[i] = eps
            A[:, i] = (self.step(t, x0 + dx, u0) - f0) / eps
        for i in range(3):
            du = np.zeros(3)
            du[i] = eps
            B[:, i] = (self.step(t, x0, u0 + du) - f0) / eps
        return A, B


# --------------------------------------------------------------------------------------
# truth plant reporting the body-frame relative state
# --------------------------------------------------------------------------------------
class TumblingTargetTruth(PlantBase):
    """Plant (proxops.contracts) around an Encke truth (e.g.
    :class:`proxops.propagation.truth.RelativeTruth`, two-body + J2) and a tumbling target.

    Full state (16,): the inner 12-state ``[r_t, v_t, dr, dv]`` (ECI, m, m/s) and the
    target quaternion ``q_IB`` (4,), propagated exactly with eq. (2) (§9 step 2: "quaternion
    propagation"). ``relative_state`` is the *body-frame* state [r_B, v_B] of eqs. (7)-(8)
    computed from the ECI offset and q_IB - what the LOS MPC and the corridor check use.
    Control: LVLH (Hill) acceleration, ZOH, as the inner truth.

    ``initial_body_state``: chaser state in F_B at t = 0 (m, m/s), mapped exactly to the
    ECI offset with the target's attitude at t = 0.
    """

    n_x = 6
    n_u = 3

    def __init__(self, inner, target: TumblingTarget, initial_body_state: np.ndarray):
        self.inner = inner
        self.target = target
        y0 = np.array(inner.initial_state(), dtype=float)
        y0[6:12] = target.offset_from_body_state(0.0, np.asarray(initial_body_state, float))
        self._x0 = np.concatenate([y0, target.q0_IB])
        self._q_dt = None
        self._q_step = np.eye(4)
        # the inner truth steps [y, q] in one call (RelativeTruth.propagate_spinning), else propagate + the quaternion
        self._spinning = hasattr(inner, "propagate_spinning")

    def initial_state(self) -> np.ndarray:
        return self._x0.copy()

    def relative_state(self, state: np.ndarray) -> np.ndarray:
        """Body-frame relative state [r_B, v_B] (eqs. 7-8), one jitted call (:func:`_body_state`)."""
        return _body_state(np.ascontiguousarray(state, dtype=float), self.target.tumble_rate_rad_s)

    def hill_state(self, state: np.ndarray) -> np.ndarray:
        """Hill/LVLH relative state of the chaser (6,) from the inner truth."""
        return self.inner.relative_state(state[:12])

    def propagate(self, t: float, state: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        """The inner truth's step of state[:12] and the exact eq.-(2) step of q_IB (one jitted call with
        :meth:`proxops.propagation.truth.RelativeTruth.propagate_spinning`)."""
        if dt != self._q_dt:  # exact eq.-(2) step q (x) exp(0.5 w dt) as a 4x4 matrix, cached per dt
            self._q_step = _right_product_matrix(quat_propagate(IDENTITY, self.target.omega_body, dt))
            self._q_dt = dt
        if self._spinning:
            return self.inner.propagate_spinning(t, state, u, dt, self._q_step)
        y = self.inner.propagate(t, state[:12], u, dt)
        return quaternion_stepped(y, np.ascontiguousarray(state, dtype=float), self._q_step)

    def apply_impulse(self, t: float, state: np.ndarray, dv: np.ndarray) -> np.ndarray:
        return np.concatenate([self.inner.apply_impulse(t, state[:12], dv), state[12:16]])


@njit(cache=True)
def _body_state(state, w_t):  # pragma: no cover - compiled
    """Eqs. (7)-(8) from the full state (16,): r_B = R_IB^T dr, v_B = R_IB^T dv - w_B x r_B with
    R_IB = dcm_kernel(q_IB), q_IB = state[12:16] (scalar last) and w_B = [0, 0, w_t]."""
    R = dcm_kernel(state[12:16])
    out = np.empty(6)
    for i in range(3):
        out[i] = R[0, i] * state[6] + R[1, i] * state[7] + R[2, i] * state[8]
        out[3 + i] = R[0, i] * state[9] + R[1, i] * state[10] + R[2, i] * state[11]
    out[3] += w_t * out[1]  # - (w_B x r_B) = -[-w_t r_y, w_t r_x, 0]
    out[4] -= w_t * out[0]
    return out


@njit(cache=True)
def quaternion_stepped(y12, state, q_step):  # pragma: no cover - compiled
    """[y12; q'] (16,): q' = q_step q normalised, q = state[12:16] (q_step: the exact eq.-(2) step as a 4x4
    matrix, :meth:`TumblingTargetTruth.propagate`)."""
    out = np.empty(16)
    for i in range(12):
        out[i] = y12[i]
    norm2 = 0.0
    for i in range(4):
        acc = 0.0
        for j in range(4):
            acc += q_step[i, j] * state[12 + j]
        out[12 + i] = acc
        norm2 += acc * acc
    norm = math.sqrt(norm2)
    for i in range(4):
        out[12 + i] /= norm
    return out
