"""Two rigid bodies (chief C and deputy D) in the target orbit frame T: the direct truth of
Basu et al. (§II.A, §IV, §VII), their cuboid geometry, contacts and the
frictionless impulse jump (eqs. 33-39 written on the direct state).

Frames (paper §II.A). T = LVLH/Hill frame of the chief's initial circular orbit (x radial
out, y along-track, z orbit normal; the project's Hill frame), turning at
``omega_t = (0, 0, n0)`` relative to inertial. C, D = principal body frames. Quaternions
are scalar-last Hamilton (:mod:`proxops.core.quaternion`): ``quat_to_dcm(q_c) = C_{T<-C}``.
The paper's ``R = R(p)`` (eq. 4, passive) is ``quat_to_dcm(p).T = C_{C<-T}`` with ``p = q_c``.

Truth state (26, SI) -- each body on its own, no relative coordinates:

====== ======= ============================================================ =========
index  name    meaning                                                      unit
====== ======= ============================================================ =========
0:3    r_c     chief CoM position in T                                      m
3:6    v_c     its T-frame derivative (velocity seen from T, T components)  m/s
6:9    r_d     deputy CoM position in T                                     m
9:12   v_d     its T-frame derivative                                       m/s
12:16  q_c     attitude of C relative to T (``quat_to_dcm = C_{T<-C}``)     -
16:19  w_c     omega_{C/I}|_C, chief inertial body rate                     rad/s
19:23  q_d     attitude of D relative to T                                  -
23:26  w_d     omega_{D/I}|_D, deputy inertial body rate                    rad/s
====== ======= ============================================================ =========

Control ``u = (F_d|_D, M_d|_D)`` (N, N m): thrust through the deputy CoM and torque, in D.

Flow (eq. 21 for each CoM, eqs. 23-24 for the attitudes)::

    r'' = G1 r + G2 r' + F|_T / m,   G1 = diag(3 n0^2, 0, -n0^2),  G2 = -2 omega_t^x
    J w' = -w x J w + M              (Euler, inertial body rate)
    q'  = 0.5 q (x) [w - C_{B<-T} omega_t, 0]   (attitude relative to the rotating T)

Correction of eq. 21: the paper prints ``G2 = (0, 0, 2 n0)^x`` = [[0, -2n0, 0], [2n0, 0, 0],
[0, 0, 0]], which gives ``x'' = ... - 2 n0 y'``; the standard CW equations (Coriolis
``-2 omega_t x r'``, :func:`proxops.core.cw.cw_matrices`) have ``x'' = 3n0^2 x + 2 n0 y'``,
``y'' = -2 n0 x'``, i.e. ``G2 = -(0, 0, 2 n0)^x``. We use the standard one (tests check it
against the closed-form CW state-transition matrix).

Not modelled (as in the paper): gravity-gradient and other environmental torques, and
differential gravity beyond the CW linearisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from proxops.core.small_linalg import cross3
from proxops.core.constants import MU_EARTH
from numba import njit

from proxops.core.quaternion import (
    dcm_kernel,
    multiply_kernel,
    quat_multiply,
    quat_rotate,
    quat_rotate_inverse,
    quat_to_dcm,
)
from proxops.errors import input_error

TRUTH_STATE_NAMES = (
    "r_c_x", "r_c_y", "r_c_z", "v_c_x", "v_c_y", "v_c_z",
    "r_d_x", "r_d_y", "r_d_z", "v_d_x", "v_d_y", "v_d_z",
    "q_c_x", "q_c_y", "q_c_z", "q_c_w", "w_c_x", "w_c_y", "w_c_z",
    "q_d_x", "q_d_y", "q_d_z", "q_d_w", "w_d_x", "w_d_y", "w_d_z",
)  # fmt: skip
TRUTH_STATE_UNITS = ("m",) * 3 + ("m/s",) * 3 + ("m",) * 3 + ("m/s",) * 3 + ("-",) * 4 + ("rad/s",) * 3 + ("-",) * 4 + (
    "rad/s",
) * 3
N_TRUTH = 26
SL_RC, SL_VC, SL_RD, SL_VD = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)
SL_QC, SL_WC, SL_QD, SL_WD = slice(12, 16), slice(16, 19), slice(19, 23), slice(23, 26)

UNIT_QUAT_TOL = 1e-6  # |‖q‖ - 1| allowed for an input quaternion
DEFAULT_ALTITUDE_M = 500e3  # the paper gives no orbit ("circular low Earth orbit"): our choice


def cuboid_inertia(mass_kg: float, dims_m) -> np.ndarray:
    """Principal inertia (kg m^2) of a constant-density cuboid of edges (a, b, c) m along
    its x, y, z axes: m/12 diag(b^2 + c^2, a^2 + c^2, a^2 + b^2) (§VII)."""
    a, b, c = (float(v) for v in dims_m)
    return mass_kg / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


def box_sdf(points, half_extents) -> np.ndarray:
    """Signed distance (m) of points (..., 3) in a box's own frame to the box surface of
    half extents h (m): positive outside, zero on the surface, negative inside."""
    d = np.abs(np.asarray(points, dtype=float)) - np.asarray(half_extents, dtype=float)
    outside = np.linalg.norm(np.maximum(d, 0.0), axis=-1)
    inside = np.minimum(np.max(d, axis=-1), 0.0)
    return outside + inside


def boxes_overlap(c1, R1, h1, c2, R2, h2, margin: float = 0.0) -> bool:
    """Exact separating-axis test of two oriented boxes (centres c (T), active DCMs R =
    C_{T<-B}, half extents h): True if their interiors overlap by more than ``margin`` m
    along every one of the 15 candidate axes (Gottschalk et al. 1996)."""
    c1, c2 = np.asarray(c1, float), np.asarray(c2, float)
    axes = [R1[:, i] for i in range(3)] + [R2[:, i] for i in range(3)]
    for i in range(3):
        for j in range(3):
            a = np.cross(R1[:, i], R2[:, j])
            n = np.linalg.norm(a)
            if n > 1e-9:
                axes.append(a / n)
    d = c2 - c1
    for a in axes:
        r1 = np.sum(np.abs(R1.T @ a) * h1)
        r2 = np.sum(np.abs(R2.T @ a) * h2)
        if abs(d @ a) >= r1 + r2 - margin:
            return False
    return True


def _check_positive(name: str, value, unit: str) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
        raise input_error(name, value, "must be a finite number > 0", unit)


def check_inertia(name: str, J) -> np.ndarray:
    """A valid rigid-body inertia matrix (kg m^2): symmetric 3x3, positive definite, and its
    principal moments satisfy the triangle inequality J1 + J2 >= J3 (any physical mass
    distribution does)."""
    J = np.asarray(J, dtype=float)
    if J.shape != (3, 3) or not np.all(np.isfinite(J)):
        raise input_error(name, J.tolist(), "must be a finite 3x3 matrix", "kg m^2")
    if not np.allclose(J, J.T, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(J).max())):
        raise input_error(name, J.tolist(), "must be symmetric", "kg m^2")
    ev = np.linalg.eigvalsh(J)
    if ev[0] <= 0.0:
        raise input_error(name, J.tolist(), "must be positive definite (principal moments > 0)", "kg m^2")
    if ev[0] + ev[1] < ev[2] * (1.0 - 1e-9):
        raise input_error(
            name, J.tolist(), "principal moments must satisfy the triangle inequality J1 + J2 >= J3", "kg m^2"
        )
    return J


def check_unit_quaternion(name: str, q) -> np.ndarray:
    """A scalar-last unit quaternion (| |q| - 1 | <= 1e-6), returned renormalised."""
    q = np.asarray(q, dtype=float)
    if q.shape != (4,) or not np.all(np.isfinite(q)):
        raise input_error(name, q.tolist(), "must be 4 finite numbers [qx, qy, qz, qw] (scalar last)")
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > UNIT_QUAT_TOL:
        raise input_error(name, q.tolist(), f"must be a unit quaternion (norm is {norm:.6g}, allowed 1 +- 1e-6)")
    return q / norm


def _vec3(name: str, v, unit: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise input_error(name, np.asarray(v).tolist(), "must be 3 finite numbers", unit)
    return v


@dataclass(frozen=True)
class HybridParams:
    """Chief/deputy physical parameters, Basu et al. §VII (SI units).

    Inertias default to the §VII constant-density cuboids; docking ports default to face
    centres: the chief's on its +y face (the docking normal ``v = [0, 1, 0]`` of §VII) and
    the deputy's on its -y face, so that q = q_I with rho = 0 (eq. 13) is face-to-face.
    """

    mass_chief_kg: float = 360.0  # m_c, §VII
    mass_deputy_kg: float = 120.0  # m_d, §VII
    dims_chief_m: tuple = (1.04, 1.15, 1.57)  # §VII cuboid (x, y, z edges)
    dims_deputy_m: tuple = (0.6, 0.7, 0.8)  # §VII cuboid
    inertia_chief_kgm2: object = None  # J_c; None -> cuboid_inertia (§VII "diagonal")
    inertia_deputy_kgm2: object = None  # J_d; None -> cuboid_inertia
    port_chief_m: object = None  # P_c in C; None -> (0, +b_c/2, 0), centre of the +y face
    port_deputy_m: object = None  # P_d in D; None -> (0, -b_d/2, 0), centre of the -y face
    # n0: the paper only says "circular low Earth orbit"; our documented choice is 500 km.
    mean_motion_rad_s: float = math.sqrt(MU_EARTH / (6378137.0 + DEFAULT_ALTITUDE_M) ** 3)
    # e: not given by the paper. 0.5: a partly plastic metal-on-metal docking-face contact
    # (scenario key; e = 1 elastic, e = 0 plastic).
    restitution: float = 0.5
    # latch of eq. 81 (post-capture spring-damper): K_T = K_R = 5 I, D_T = D_R = 2 I
    latch_KT: float = 5.0  # N/m (eq. 40 read as a force, see hybrid_relative.post_capture_rhs)
    latch_DT: float = 2.0  # N s/m
    latch_KR: float = 5.0  # N m/rad
    latch_DR: float = 2.0  # N m s/rad
    # actuation bounds (§VII): +-1 N / +-1 N m in capture, +-5 N / +-5 N m after capture
    force_max_capture_N: float = 1.0
    torque_max_capture_Nm: float = 1.0
    force_max_post_N: float = 5.0
    torque_max_post_Nm: float = 5.0
    horizon_capture_s: float = 10.0  # T^0, §VII
    snap_impulse_Ns: float = 0.05  # latch snap, §VII ("along rho_0")
    snap_time_s: float = 593.0  # §VII ("approximately t = 593 s")
    J_c: np.ndarray = field(init=False, repr=False, compare=False)
    J_d: np.ndarray = field(init=False, repr=False, compare=False)
    J_c_inv: np.ndarray = field(init=False, repr=False, compare=False)
    J_d_inv: np.ndarray = field(init=False, repr=False, compare=False)
    P_c: np.ndarray = field(init=False, repr=False, compare=False)
    P_d: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        _check_positive("mass_chief_kg", self.mass_chief_kg, "kg")
        _check_positive("mass_deputy_kg", self.mass_deputy_kg, "kg")
        for name in ("dims_chief_m", "dims_deputy_m"):
            dims = np.asarray(getattr(self, name), dtype=float)
            if dims.shape != (3,) or not np.all(np.isfinite(dims)) or np.any(dims <= 0.0):
                raise input_error(name, list(getattr(self, name)), "must be 3 finite edge lengths > 0", "m")
        if not (math.isfinite(self.mean_motion_rad_s) and self.mean_motion_rad_s > 0.0):
            raise input_error("mean_motion_rad_s", self.mean_motion_rad_s, "must be a finite number > 0", "rad/s")
        if not (math.isfinite(self.restitution) and 0.0 <= self.restitution <= 1.0):
            raise input_error("restitution", self.restitution, "must lie in [0, 1] (0 plastic, 1 elastic)")
        for name, unit in (("latch_KT", "N/m"), ("latch_DT", "N s/m"), ("latch_KR", "N m/rad"), ("latch_DR", "N m s/rad"),
                           ("force_max_capture_N", "N"), ("torque_max_capture_Nm", "N m"), ("force_max_post_N", "N"),
                           ("torque_max_post_Nm", "N m"), ("horizon_capture_s", "s")):  # fmt: skip
            _check_positive(name, getattr(self, name), unit)
        for name, unit in (("snap_impulse_Ns", "N s"), ("snap_time_s", "s")):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
                raise input_error(name, value, "must be a finite number >= 0", unit)
        dc, dd = np.asarray(self.dims_chief_m, float), np.asarray(self.dims_deputy_m, float)
        Jc = cuboid_inertia(self.mass_chief_kg, dc) if self.inertia_chief_kgm2 is None else self.inertia_chief_kgm2
        Jd = cuboid_inertia(self.mass_deputy_kg, dd) if self.inertia_deputy_kgm2 is None else self.inertia_deputy_kgm2
        Jc = check_inertia("inertia_chief_kgm2", Jc)
        Jd = check_inertia("inertia_deputy_kgm2", Jd)
        Pc = np.array([0.0, 0.5 * dc[1], 0.0]) if self.port_chief_m is None else _vec3("port_chief_m", self.port_chief_m, "m")
        Pd = (
            np.array([0.0, -0.5 * dd[1], 0.0])
            if self.port_deputy_m is None
            else _vec3("port_deputy_m", self.port_deputy_m, "m")
        )
        tol = 1e-9 * max(dc.max(), dd.max())
        if box_sdf(Pc, 0.5 * dc) > tol:
            raise input_error("port_chief_m", Pc.tolist(), f"must lie on or inside the chief cuboid {dc.tolist()} m", "m")
        if box_sdf(Pd, 0.5 * dd) > tol:
            raise input_error("port_deputy_m", Pd.tolist(), f"must lie on or inside the deputy cuboid {dd.tolist()} m", "m")
        object.__setattr__(self, "J_c", Jc)
        object.__setattr__(self, "J_d", Jd)
        object.__setattr__(self, "J_c_inv", np.linalg.inv(Jc))
        object.__setattr__(self, "J_d_inv", np.linalg.inv(Jd))
        object.__setattr__(self, "P_c", Pc)
        object.__setattr__(self, "P_d", Pd)

    @property
    def mass_total_kg(self) -> float:
        return self.mass_chief_kg + self.mass_deputy_kg

    @property
    def half_chief(self) -> np.ndarray:
        return 0.5 * np.asarray(self.dims_chief_m, dtype=float)

    @property
    def half_deputy(self) -> np.ndarray:
        return 0.5 * np.asarray(self.dims_deputy_m, dtype=float)

    @property
    def omega_t(self) -> np.ndarray:
        """omega_{T/I}|_T = (0, 0, n0) (rad/s)."""
        return np.array([0.0, 0.0, self.mean_motion_rad_s])


@dataclass(frozen=True)
class HybridInitialState:
    """Initial relative state, eq. (78) of §VII (paper's relative variables, SI).

    ``q`` of eq. 78 is printed as 0.57 [1, 1, 1, 0], whose norm is 0.987 (not a unit
    quaternion): 0.57 is 1/sqrt(3) = 0.577 rounded, so the default is [1, 1, 1, 0]/sqrt(3)
    (a 180 deg rotation about (1, 1, 1)). A non-unit value passed here is refused.
    ``rho0_dot`` is the T-frame derivative of rho_0 (eq. 20), T components.
    """

    rho0_m: tuple = (2.0, 0.0, 0.0)  # rho_0(0,0) in T
    rho0_dot_m_s: tuple = (-0.081, 0.011, 0.0133)  # rho_0 dot in T
    omega_rad_s: tuple = (0.09, 0.06, 0.009)  # omega = omega_{D/C}|_D
    q: tuple = (1.0 / math.sqrt(3.0), 1.0 / math.sqrt(3.0), 1.0 / math.sqrt(3.0), 0.0)  # D rel. C
    omega_c_rad_s: tuple = (-0.0024, 0.0024, -0.0024)  # omega_c = omega_{C/T}|_C
    p: tuple = (-0.5, 0.5, 0.5, 0.5)  # C rel. T: 0.5 [-1, 1_3] with the scalar last

    def __post_init__(self):
        _vec3("rho0_m", self.rho0_m, "m")
        _vec3("rho0_dot_m_s", self.rho0_dot_m_s, "m/s")
        _vec3("omega_rad_s", self.omega_rad_s, "rad/s")
        _vec3("omega_c_rad_s", self.omega_c_rad_s, "rad/s")
        check_unit_quaternion("q", self.q)
        check_unit_quaternion("p", self.p)


def truth_state_from_initial(params: HybridParams, ic: HybridInitialState) -> np.ndarray:
    """Truth state (26) of eq. 78: chief CoM at the origin of T at rest, attitudes and rates
    composed from (p, omega_c) and (q, omega); refuses an interpenetrating start."""
    p = check_unit_quaternion("p", ic.p)
    q = check_unit_quaternion("q", ic.q)
    x = np.zeros(N_TRUTH)
    x[SL_RD] = ic.rho0_m
    x[SL_VD] = ic.rho0_dot_m_s
    x[SL_QC] = p
    wc = np.asarray(ic.omega_c_rad_s, float) + quat_rotate_inverse(p, params.omega_t)  # omega_c + R omega_t
    x[SL_WC] = wc
    x[SL_QD] = quat_multiply(p, q)
    x[SL_WD] = np.asarray(ic.omega_rad_s, float) + quat_rotate_inverse(q, wc)  # omega + Q (omega_c + R omega_t)
    check_not_interpenetrating(params, x)
    return x


def check_not_interpenetrating(params: HybridParams, x, name: str = "initial_state") -> None:
    """Raise a one-line input error if the two cuboids overlap (exact separating-axis test,
    1 mm margin so that touching faces, e.g. the docked configuration, are allowed)."""
    x = np.asarray(x, dtype=float)
    if boxes_overlap(
        x[SL_RC], quat_to_dcm(x[SL_QC]), params.half_chief, x[SL_RD], quat_to_dcm(x[SL_QD]), params.half_deputy, 1e-3
    ):
        raise input_error(
            name,
            f"rho_0 = {np.round(x[SL_RD] - x[SL_RC], 4).tolist()} m",
            "the chief and deputy cuboids already interpenetrate; start them apart",
        )


# --------------------------------------------------------------------------------------
# flow
# --------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _mv(M, v):
    """M @ v for a 3x3 M inside numba code (a loop: numba's ``@`` calls BLAS, ~1 us per call)."""
    out = np.empty(3)
    for i in range(3):
        out[i] = M[i, 0] * v[0] + M[i, 1] * v[1] + M[i, 2] * v[2]
    return out


@njit(cache=True, inline="always")
def _mtv(M, v):
    """M.T @ v for a 3x3 M inside numba code."""
    out = np.empty(3)
    for i in range(3):
        out[i] = M[0, i] * v[0] + M[1, i] * v[1] + M[2, i] * v[2]
    return out


@njit(cache=True, inline="always")
def _mtm(A, B):
    """A.T @ B for 3x3 matrices inside numba code."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = A[0, i] * B[0, j] + A[1, i] * B[1, j] + A[2, i] * B[2, j]
    return out


@njit(cache=True, inline="always")
def _attitude_rhs(x, dx, iq, iw, R, J, Ji, M0, M1, M2, n):
    """Attitude kinematics relative to T and Euler's equation of one body (quaternion at iq, inertial
    body rate at iw; R = C_{T<-B} as a 9-tuple; torque (M0, M1, M2) in B), written into dx."""
    w0, w1, w2 = x[iw], x[iw + 1], x[iw + 2]
    r0, r1, r2 = w0 - R[6] * n, w1 - R[7] * n, w2 - R[8] * n  # w - R^T omega_t
    qx, qy, qz, qw = x[iq], x[iq + 1], x[iq + 2], x[iq + 3]
    dx[iq] = 0.5 * (qw * r0 + qy * r2 - qz * r1)  # 0.5 q (x) [w_rel, 0]
    dx[iq + 1] = 0.5 * (qw * r1 + qz * r0 - qx * r2)
    dx[iq + 2] = 0.5 * (qw * r2 + qx * r1 - qy * r0)
    dx[iq + 3] = -0.5 * (qx * r0 + qy * r1 + qz * r2)
    h0 = J[0, 0] * w0 + J[0, 1] * w1 + J[0, 2] * w2
    h1 = J[1, 0] * w0 + J[1, 1] * w1 + J[1, 2] * w2
    h2 = J[2, 0] * w0 + J[2, 1] * w1 + J[2, 2] * w2
    t0 = M0 - (w1 * h2 - w2 * h1)  # eqs. 23-24: J w' = M - w x J w
    t1 = M1 - (w2 * h0 - w0 * h2)
    t2 = M2 - (w0 * h1 - w1 * h0)
    for i in range(3):
        dx[iw + i] = Ji[i, 0] * t0 + Ji[i, 1] * t1 + Ji[i, 2] * t2


@njit(cache=True, inline="always")
def _cw_scalar(x, dx, i, F0, F1, F2, m, n):
    """CW (eq. 21 with the standard G2 = -2 omega_t^x) for the CoM at index i (velocity at i + 3)."""
    dx[i] = x[i + 3]
    dx[i + 1] = x[i + 4]
    dx[i + 2] = x[i + 5]
    dx[i + 3] = 3.0 * n * n * x[i] + 2.0 * n * x[i + 4] + F0 / m
    dx[i + 4] = -2.0 * n * x[i + 3] + F1 / m
    dx[i + 5] = -n * n * x[i + 2] + F2 / m


@njit(cache=True)
def truth_rhs_kernel(x, u, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n):
    """numba kernel of :func:`truth_rhs` (same layout; plain float64 arrays; scalar form, one
    heap array: dx)."""
    dx = np.empty(26)
    truth_rhs_into(x, u, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, dx)
    return dx


@njit(cache=True)
def truth_rhs_into(x, u, m_c, m_d, J_c, J_c_inv, J_d, J_d_inv, n, dx):
    """:func:`truth_rhs_kernel` written into ``dx[0:26]`` (no heap array; the plant's RK4)."""
    Rc = dcm9(x[12:16])  # C_{T<-C}
    Rd = dcm9(x[19:23])  # C_{T<-D}
    F0, F1, F2 = mv9(Rd, u[0], u[1], u[2])
    _cw_scalar(x, dx, 0, 0.0, 0.0, 0.0, m_c, n)  # chief CoM
    _cw_scalar(x, dx, 6, F0, F1, F2, m_d, n)  # deputy CoM
    _attitude_rhs(x, dx, 12, 16, Rc, J_c, J_c_inv, 0.0, 0.0, 0.0, n)  # eq. 23
    _attitude_rhs(x, dx, 19, 23, Rd, J_d, J_d_inv, u[3], u[4], u[5], n)  # eq. 24


def truth_rhs(t: float, x: np.ndarray, u: np.ndarray, params: HybridParams) -> np.ndarray:
    """dx/dt of the direct two-body truth (layout in the module doc); eqs. 21 (corrected
    G2), 23, 24 and the attitude kinematics relative to the rotating T (numba kernel)."""
    return truth_rhs_kernel(
        np.asarray(x, dtype=float),
        np.asarray(u, dtype=float),
        params.mass_chief_kg,
        params.mass_deputy_kg,
        params.J_c,
        params.J_c_inv,
        params.J_d,
        params.J_d_inv,
        params.mean_motion_rad_s,
    )


def propagate_truth(
    x0, t_span, params: HybridParams, u_of_t=None, t_eval=None, rtol=1e-11, atol=1e-12, events=None, latched=False
):
    """Reference integration of :func:`truth_rhs` (``latched``: :func:`truth_rhs_latched`)
    with scipy's DOP853; ``u_of_t(t, x)`` gives the control (zero if None). Returns the
    scipy OdeResult."""
    from scipy.integrate import solve_ivp

    zero = np.zeros(6)
    rhs = truth_rhs_latched if latched else truth_rhs

    def f(t, x):
        return rhs(t, x, zero if u_of_t is None else u_of_t(t, x), params)

    return solve_ivp(f, t_span, np.asarray(x0, float), method="DOP853", rtol=rtol, atol=atol, t_eval=t_eval, events=events)


# --------------------------------------------------------------------------------------
# invariants
# --------------------------------------------------------------------------------------
def inertial_velocities(x, params: HybridParams):
    """(v_c, v_d) inertial velocities relative to T's origin, T components:
    v + omega_t x r (m/s)."""
    wt = params.omega_t
    return x[SL_VC] + np.cross(wt, x[SL_RC]), x[SL_VD] + np.cross(wt, x[SL_RD])


def momenta(x, params: HybridParams):
    """Linear momentum (N s) and angular momentum about T's origin (N m s) of the pair,
    inertial velocities, T components (conserved by any internal impulse)."""
    x = np.asarray(x, dtype=float)
    vc, vd = inertial_velocities(x, params)
    mc, md = params.mass_chief_kg, params.mass_deputy_kg
    p_lin = mc * vc + md * vd
    Hc = quat_rotate(x[SL_QC], params.J_c @ x[SL_WC])
    Hd = quat_rotate(x[SL_QD], params.J_d @ x[SL_WD])
    h = mc * np.cross(x[SL_RC], vc) + md * np.cross(x[SL_RD], vd) + Hc + Hd
    return p_lin, h


def kinetic_energy(x, params: HybridParams) -> float:
    """Kinetic energy (J) of the pair with inertial velocities and rates."""
    vc, vd = inertial_velocities(x, params)
    wc, wd = x[SL_WC], x[SL_WD]
    return float(
        0.5 * params.mass_chief_kg * vc @ vc
        + 0.5 * params.mass_deputy_kg * vd @ vd
        + 0.5 * wc @ params.J_c @ wc
        + 0.5 * wd @ params.J_d @ wd
    )


# --------------------------------------------------------------------------------------
# contacts
# --------------------------------------------------------------------------------------
# Which geometry the paper means. Eq. 33 takes a contact point r anywhere on the chief
# with the surface normal n at r ("n depends on the surface geometry at the contact point"),
# and §VII models both vehicles as cuboids: contacts are between the cuboids, not between
# the docking ports (two points never touch generically; the ports meet only at docking,
# which is the post-capture transition of Case 2, not a jump). The docking faces meeting
# at an angle (Fig. 5) is one such contact.
#
# Guard: the separating-axis value of the two boxes. For each of the 15 candidate axes a
# (3 face normals of each box, 9 edge-edge cross products) the gap along a is
# |d.a| - r_c(a) - r_d(a); g is the largest. Its sign is exact (g > 0 iff the boxes are
# apart, g = 0 at first touch of any kind: vertex-face, edge-edge, face-face), so root
# finding on g locates every contact. (A vertex-in-box test alone misses edge-edge
# contacts: in 9 of 20 random tumbling approaches the edges crossed first, by up to 2.7 s.)
def _support_offset(R, h, n, sign):
    """Centroid offset (T) of the supporting feature of a box (DCM R, half extents h) in
    direction sign*n: vertex, edge centre or face centre (axes within 1e-9 of
    perpendicular to n contribute 0)."""
    proj = R.T @ n
    s = np.where(np.abs(proj) < 1e-9, 0.0, np.sign(proj)) * sign
    return R @ (s * h)


def _sat(x, params: HybridParams):
    """(g, kind, i, j, n): separating-axis gap (m), the axis kind ('chief_face',
    'deputy_face', 'edge_edge'), its indices and the unit axis oriented chief -> deputy."""
    Rc, Rd = quat_to_dcm(x[SL_QC]), quat_to_dcm(x[SL_QD])
    hc, hd = params.half_chief, params.half_deputy
    d = x[SL_RD] - x[SL_RC]
    best = (-np.inf, "", -1, -1, None)
    cands = [("chief_face", i, -1, Rc[:, i]) for i in range(3)] + [("deputy_face", -1, j, Rd[:, j]) for j in range(3)]
    for i in range(3):
        for j in range(3):
            a = np.cross(Rc[:, i], Rd[:, j])
            na = np.linalg.norm(a)
            if na > 1e-9:
                cands.append(("edge_edge", i, j, a / na))
    for kind, i, j, a in cands:
        da = d @ a
        gap = abs(da) - np.sum(np.abs(Rc.T @ a) * hc) - np.sum(np.abs(Rd.T @ a) * hd)
        if gap > best[0]:
            best = (gap, kind, i, j, a if da >= 0 else -a)
    return best


def contact_guard(x, params: HybridParams) -> float:
    """Guard g(x) (m): the separating-axis gap of the two cuboids. g > 0 apart, g = 0 at
    the contact instant, g < 0 interpenetrating (sign exact, see the note above); use it as
    the event function for root finding. In the docked configuration (faces flush) g = 0 by
    construction: the contact event belongs to the capture mode (h = 0) only."""
    return float(_sat(np.asarray(x, float), params)[0])


def contact_event(params: HybridParams):
    """``event(t, x)`` for ``solve_ivp`` / an event-locating engine: :func:`contact_guard`
    crossing zero downwards (terminal). Locates the contact instant by root finding, so a
    contact cannot tunnel through an integrator step longer than the contact itself."""

    def event(t, x):
        return contact_guard(x, params)

    event.terminal = True
    event.direction = -1
    return event


def contact_frame(x, params: HybridParams):
    """Contact point and normal at (or near) touch, T components: ``(r, n_hat)`` with r
    from the chief CoM to the contact point (m) and n_hat the unit normal pointing from the
    chief into the deputy (eq. 33's n, impulse on the deputy along +n).

    Face axis of one box: the point is the other box's supporting feature centroid (a
    vertex for a vertex-face contact; the centre of an edge or face when they lie flat).
    Edge-edge: the midpoint of the closest points of the two supporting edges."""
    x = np.asarray(x, float)
    _, kind, i, j, n = _sat(x, params)
    Rc, Rd = quat_to_dcm(x[SL_QC]), quat_to_dcm(x[SL_QD])
    rc, rd = x[SL_RC], x[SL_RD]
    hc, hd = params.half_chief, params.half_deputy
    if kind == "chief_face":
        point = rd + _support_offset(Rd, hd, n, -1.0)
    elif kind == "deputy_face":
        point = rc + _support_offset(Rc, hc, n, +1.0)
    else:
        # supporting edges: chief edge along Rc[:, i], deputy edge along Rd[:, j]
        pc = rc + _support_offset(Rc, hc, n, +1.0) - Rc[:, i] * (Rc[:, i] @ _support_offset(Rc, hc, n, +1.0))
        pd = rd + _support_offset(Rd, hd, n, -1.0) - Rd[:, j] * (Rd[:, j] @ _support_offset(Rd, hd, n, -1.0))
        e1, e2 = Rc[:, i], Rd[:, j]
        w = pc - pd
        b = e1 @ e2
        den = 1.0 - b * b
        s = np.clip((b * (e2 @ w) - (e1 @ w)) / den, -hc[i], hc[i])
        t = np.clip((e2 @ w) + b * s, -hd[j], hd[j])
        point = 0.5 * ((pc + s * e1) + (pd + t * e2))
    return point - rc, n


def contact_normal_velocity(x, params: HybridParams, r=None, n=None) -> float:
    """v_rel of eq. 33 (m/s) computed on the truth state: normal component of the deputy
    material point's velocity relative to the chief's at the contact point (inertial
    velocities). Negative = approaching (the impact condition is v_rel <= 0)."""
    x = np.asarray(x, float)
    if r is None or n is None:
        r, n = contact_frame(x, params)
    vc, vd = inertial_velocities(x, params)
    Wc = quat_rotate(x[SL_QC], x[SL_WC])  # omega_{C/I} in T
    Wd = quat_rotate(x[SL_QD], x[SL_WD])
    rho0 = x[SL_RD] - x[SL_RC]
    v_point_d = vd + np.cross(Wd, r - rho0)
    v_point_c = vc + np.cross(Wc, r)
    return float(n @ (v_point_d - v_point_c))


def contact_impulse(x, params: HybridParams, r, n, restitution: float | None = None) -> float:
    """Magnitude gamma (N s) of the frictionless impulse along n that makes the normal
    relative velocity -e times its value before the impact (Newton's restitution law):
    gamma = -(1 + e) v_rel / (1/m_c + 1/m_d + n.(I_d^-1 (r_d x n)) x r_d + n.(I_c^-1 (r x n)) x r),
    with r_d = r - rho_0 and world-frame inverse inertias. Zero if not approaching."""
    e = params.restitution if restitution is None else float(restitution)
    if not (math.isfinite(e) and 0.0 <= e <= 1.0):
        raise input_error("restitution", e, "must lie in [0, 1] (0 plastic, 1 elastic)")
    x = np.asarray(x, float)
    v_rel = contact_normal_velocity(x, params, r, n)
    if v_rel >= 0.0:
        return 0.0
    Rc, Rd = quat_to_dcm(x[SL_QC]), quat_to_dcm(x[SL_QD])
    rd = r - (x[SL_RD] - x[SL_RC])
    Ic_inv = Rc @ np.linalg.inv(params.J_c) @ Rc.T
    Id_inv = Rd @ np.linalg.inv(params.J_d) @ Rd.T
    k = (
        1.0 / params.mass_chief_kg
        + 1.0 / params.mass_deputy_kg
        + n @ np.cross(Id_inv @ np.cross(rd, n), rd)
        + n @ np.cross(Ic_inv @ np.cross(r, n), r)
    )
    return -(1.0 + e) * v_rel / k


def apply_impulse(x, params: HybridParams, r, impulse_T) -> np.ndarray:
    """Truth state after an internal impulse ``impulse_T`` (N s, T components) on the deputy
    at the point r (m, from the chief CoM, T) and its opposite on the chief (eqs. 34, 36 on
    the direct state). Positions and attitudes do not jump."""
    x = np.asarray(x, float)
    J = np.asarray(impulse_T, float)
    rd = r - (x[SL_RD] - x[SL_RC])
    xp = x.copy()
    xp[SL_VD] += J / params.mass_deputy_kg
    xp[SL_VC] -= J / params.mass_chief_kg
    xp[SL_WD] += np.linalg.solve(params.J_d, quat_rotate_inverse(x[SL_QD], np.cross(rd, J)))
    xp[SL_WC] -= np.linalg.solve(params.J_c, quat_rotate_inverse(x[SL_QC], np.cross(r, J)))
    return xp


def contact_jump(x, params: HybridParams, restitution: float | None = None):
    """Contact jump map on the truth: ``(x_plus, gamma, r, n)`` with gamma (N s) the impulse
    magnitude along n (0 and x unchanged if the bodies are separating, v_rel >= 0)."""
    r, n = contact_frame(x, params)
    gamma = contact_impulse(x, params, r, n, restitution)
    if gamma == 0.0:
        return np.asarray(x, float).copy(), 0.0, r, n
    return apply_impulse(x, params, r, gamma * n), gamma, r, n


def in_jump_set(x, params: HybridParams, tol: float = 1e-9) -> bool:
    """D_0 of eq. 15: in contact (g <= tol) and approaching (eq. 33, v_rel <= 0)."""
    return contact_guard(x, params) <= tol and contact_normal_velocity(x, params) < 0.0


def latch_snap_jump(x, params: HybridParams, impulse_Ns: float | None = None) -> np.ndarray:
    """The §VII latch-snap disturbance on the truth: an internal impulse of magnitude
    ``impulse_Ns`` along rho_0 = r_d - r_c pushing the deputy away from the chief (and the
    chief back), applied on the line through both CoMs so that no rate changes (eq. 53-54).

    Sign: eq. 56-57 write ``rho0_dot+ = rho0_dot - T_pi (1/m_c + 1/m_d)``; with T_pi along
    rho_0 that would push the bodies together. A snap that separates them is
    ``T_pi = -|T_pi| rho_0/|rho_0|``, which is what we apply."""
    J = params.snap_impulse_Ns if impulse_Ns is None else float(impulse_Ns)
    x = np.asarray(x, float)
    rho0 = x[SL_RD] - x[SL_RC]
    e = rho0 / np.linalg.norm(rho0)
    return apply_impulse(x, params, rho0, J * e)  # applied at the deputy CoM: zero moment arm on both


# --------------------------------------------------------------------------------------
# post-capture latch (eqs. 40-42 and 81) as an internal force/torque pair on the truth
# --------------------------------------------------------------------------------------
@njit(cache=True)
def port_kinematics_kernel(x, P_c, P_d, n):
    """Relative port kinematics of the truth state x (26), the numba form of the first 13
    entries of hybrid_relative.relative_from_truth: ``(Rc = C_{T<-C}, Rd = C_{T<-D}, Q =
    C_{D<-C}, q (D rel. C, scalar last, q_w >= 0), omega_{D/C}|_D, rho (m, C), rho' (m/s, C))``."""
    Rc = dcm_kernel(x[12:16])  # C_{T<-C}
    Rd = dcm_kernel(x[19:23])  # C_{T<-D}
    qc = x[12:16]
    qc_conj = np.array([-qc[0], -qc[1], -qc[2], qc[3]])
    q = multiply_kernel(qc_conj, x[19:23])  # D rel. C
    if q[3] < 0:
        q = -q
    Q = _mtm(Rd, Rc)  # C_{D<-C}
    wt = np.array([0.0, 0.0, n])
    omc = x[16:19] - _mtv(Rc, wt)  # R = Rc^T = C_{C<-T}
    om = x[23:26] - _mv(Q, x[16:19])
    wd = om + _mv(Q, omc)
    rho0 = x[6:9] - x[0:3]
    rho0d = x[9:12] - x[3:6]
    rho = _mtv(Rc, rho0) + _mtv(Q, P_d) - P_c
    rhod = _mtv(Rc, rho0d) - cross3(omc, rho + P_c) + _mtv(Q, cross3(wd, P_d))
    return Rc, Rd, Q, q, om, rho, rhod


@njit(cache=True)
def dcm9(q):
    """:func:`quat_to_dcm` of one unit quaternion as a 9-tuple (row major), allocation-free."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    return (w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z)


@njit(cache=True)
def mv9(M, a, b, c):
    """M (a, b, c) for a row-major 9-tuple M."""
    return (M[0] * a + M[1] * b + M[2] * c, M[3] * a + M[4] * b + M[5] * c, M[6] * a + M[7] * b + M[8] * c)


@njit(cache=True)
def mtv9(M, a, b, c):
    """M^T (a, b, c) for a row-major 9-tuple M."""
    return (M[0] * a + M[3] * b + M[6] * c, M[1] * a + M[4] * b + M[7] * c, M[2] * a + M[5] * b + M[8] * c)


@njit(cache=True)
def cross9(a0, a1, a2, b0, b1, b2):
    """(a0, a1, a2) x (b0, b1, b2) as a tuple."""
    return (a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0)


@njit(cache=True)
def _latch_kernel(x, P_c, P_d, KT, DT, KR, DR, n):
    """Latch pair of :func:`latch_wrench` in scalar form (the port kinematics of
    :func:`port_kinematics_kernel` inline, no heap arrays but the three returned)."""
    F0, F1, F2, d0, d1, d2, c0, c1, c2 = latch_scalars(x, P_c, P_d, KT, DT, KR, DR, n)
    tau_d = np.empty(3)
    tau_d[0], tau_d[1], tau_d[2] = d0, d1, d2
    tau_c = np.empty(3)
    tau_c[0], tau_c[1], tau_c[2] = c0, c1, c2
    F = np.empty(3)
    F[0], F[1], F[2] = F0, F1, F2
    return F, tau_d, tau_c


@njit(cache=True)
def latch_scalars(x, P_c, P_d, KT, DT, KR, DR, n):
    """:func:`_latch_kernel` as nine floats (F_T, tau_d|_D, tau_c|_C; no heap array)."""
    Rc = dcm9(x[12:16])  # C_{T<-C}
    Rd = dcm9(x[19:23])  # C_{T<-D}
    # q = q_c* (x) q_d (scalar >= 0 branch)
    p0, p1, p2, p3 = -x[12], -x[13], -x[14], x[15]
    d0, d1, d2, d3 = x[19], x[20], x[21], x[22]
    q0 = p3 * d0 + d3 * p0 + p1 * d2 - p2 * d1
    q1 = p3 * d1 + d3 * p1 + p2 * d0 - p0 * d2
    q2 = p3 * d2 + d3 * p2 + p0 * d1 - p1 * d0
    q3 = p3 * d3 - p0 * d0 - p1 * d1 - p2 * d2
    if q3 < 0:
        q0, q1, q2, q3 = -q0, -q1, -q2, -q3
    # Q = C_{D<-C} = Rd^T Rc; Q^T = Rc^T Rd
    omc0, omc1, omc2 = x[16] - Rc[6] * n, x[17] - Rc[7] * n, x[18] - Rc[8] * n  # omega_c = W_c - R omega_t
    a0, a1, a2 = mv9(Rc, x[16], x[17], x[18])
    Qw0, Qw1, Qw2 = mtv9(Rd, a0, a1, a2)
    om0, om1, om2 = x[23] - Qw0, x[24] - Qw1, x[25] - Qw2
    a0, a1, a2 = mv9(Rc, omc0, omc1, omc2)
    b0, b1, b2 = mtv9(Rd, a0, a1, a2)
    wd0, wd1, wd2 = om0 + b0, om1 + b1, om2 + b2
    r0, r1, r2 = x[6] - x[0], x[7] - x[1], x[8] - x[2]
    v0, v1, v2 = x[9] - x[3], x[10] - x[4], x[11] - x[5]
    a0, a1, a2 = mtv9(Rc, r0, r1, r2)
    e0, e1, e2 = mv9(Rd, P_d[0], P_d[1], P_d[2])  # arm_d = Rd P_d
    b0, b1, b2 = mtv9(Rc, e0, e1, e2)  # Q^T P_d
    rho0, rho1, rho2 = a0 + b0 - P_c[0], a1 + b1 - P_c[1], a2 + b2 - P_c[2]
    a0, a1, a2 = mtv9(Rc, v0, v1, v2)
    c0, c1, c2 = cross9(omc0, omc1, omc2, rho0 + P_c[0], rho1 + P_c[1], rho2 + P_c[2])
    f0, f1, f2 = cross9(wd0, wd1, wd2, P_d[0], P_d[1], P_d[2])
    g0, g1, g2 = mv9(Rd, f0, f1, f2)
    b0, b1, b2 = mtv9(Rc, g0, g1, g2)  # Q^T (wd x P_d)
    rd0, rd1, rd2 = a0 - c0 + b0, a1 - c1 + b1, a2 - c2 + b2
    F0, F1, F2 = mv9(Rc, KT * rho0 + DT * rd0, KT * rho1 + DT * rd1, KT * rho2 + DT * rd2)
    F0, F1, F2 = -F0, -F1, -F2
    s = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    k = 2.0 * math.atan2(s, q3) / s if s > 1e-15 else 2.0
    t0, t1, t2 = -KR * k * q0 - DR * om0, -KR * k * q1 - DR * om1, -KR * k * q2 - DR * om2  # on D, D components
    ac0, ac1, ac2 = mv9(Rc, P_c[0] + rho0, P_c[1] + rho1, P_c[2] + rho2)
    c0, c1, c2 = cross9(e0, e1, e2, F0, F1, F2)
    b0, b1, b2 = mtv9(Rd, c0, c1, c2)
    d0, d1, d2 = t0 + b0, t1 + b1, t2 + b2
    g0, g1, g2 = mv9(Rd, t0, t1, t2)
    a0, a1, a2 = mtv9(Rc, g0, g1, g2)  # Q^T tau
    c0, c1, c2 = cross9(ac0, ac1, ac2, -F0, -F1, -F2)
    b0, b1, b2 = mtv9(Rc, c0, c1, c2)
    return F0, F1, F2, d0, d1, d2, -a0 + b0, -a1 + b1, -a2 + b2


def latch_wrench(x, params: HybridParams):
    """Spring-damper latch of §IV.E / eq. 81 acting between the docking ports, as an
    internal pair (momentum conserving): ``(F_T, tau_d_D, tau_c_C)``.

    Force on the deputy at its port, T components: ``F = -C_{T<-C} (K_T rho + D_T rho')``
    (eq. 40 replaces F_d by ``Q (-K_T rho - D_T rho')``, a force in D, i.e. the same vector;
    K_T in N/m, D_T in N s/m); ``-F`` acts on the chief. Torque on the deputy, D components:
    ``-K_R theta e - D_R omega`` with ``theta e = 2 atan2(|q_eta|, q_mu) q_eta/|q_eta|``
    (eq. 42; K_R in N m/rad, D_R in N m s/rad) and its opposite on the chief. Returned
    torques include the moments of the port forces about each CoM. Both forces act at the
    deputy's port point, so the pair has no net moment and the latch conserves the pair's
    angular momentum (the damper force is not parallel to the port offset, so applying -F at
    the chief's own port would not).

    The paper's eqs. 40/42 apply the latch to the deputy only and give the chief the
    composite dynamics (eq. 51); here both bodies feel it, which is the physical latch."""
    return _latch_kernel(
        np.asarray(x, dtype=float), params.P_c, params.P_d, float(params.latch_KT), float(params.latch_DT),
        float(params.latch_KR), float(params.latch_DR), params.mean_motion_rad_s,
    )  # fmt: skip


def truth_rhs_latched(t: float, x: np.ndarray, u: np.ndarray, params: HybridParams) -> np.ndarray:
    """:func:`truth_rhs` plus the latch pair of :func:`latch_wrench` (post-capture, h = 1)."""
    dx = truth_rhs(t, x, u, params)
    F, tau_d, tau_c = latch_wrench(x, params)
    dx[SL_VD] += F / params.mass_deputy_kg
    dx[SL_VC] -= F / params.mass_chief_kg
    dx[SL_WD] += params.J_d_inv @ tau_d
    dx[SL_WC] += params.J_c_inv @ tau_c
    return dx
