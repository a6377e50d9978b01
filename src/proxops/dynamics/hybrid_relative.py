"""The paper's relative-state model of Basu et al.: capture flow f_0 (eqs. 18-32),
contact jump g_0 (eqs. 33-39), composite post-capture pieces (eqs. 44-51) and the
decoupling jump g_1 (eqs. 53-61), written once for numpy and CasADi operands.

Relative state ``x`` (32, eq. §III; SI):

======= ========== =========================================================== ======
index   name       meaning                                                     unit
======= ========== =========================================================== ======
0:3     rho        deputy port minus chief port, C components (eq. 18)        m
3:6     rho_dot    its C-frame derivative                                      m/s
6:9     omega      omega_{D/C}|_D                                              rad/s
9:13    q          attitude of D relative to C (scalar last)                   -
13:17   p          attitude of C relative to T (scalar last)                   -
17:20   omega_c    omega_{C/T}|_C                                              rad/s
20:23   rho_n      pair CoM in T                                               m
23:26   rho_n_dot  its T-frame derivative                                      m/s
26:32   x_ref      (r_des, r_des_dot) in T, exogenous                          m, m/s
======= ========== =========================================================== ======

Matrices as in the paper: ``Q = R(q) = C_{D<-C}``, ``R = R(p) = C_{C<-T}`` (eq. 4, the
passive matrix; ``quat_to_dcm(q).T`` in proxops' convention). ``u = (F_d|_D, M_d|_D)``.

Verification (tests/test_hybrid_physics.py, benchmarks/bench_hybrid_physics.py): the
state predicted by integrating :func:`relative_rhs` and the one mapped from the direct
two-body truth (:func:`relative_from_truth`) agree to integration tolerance over a 100 s
tumbling arc; the jump maps agree with the truth's impulse to round-off. Each equation
was re-derived; the differences from the printed paper (``corrected=False`` restores the
printed form where it is a switch):

* eq. 21/22/32/48 -- G2: printed ``(0, 0, 2 n0)^x`` has the wrong Coriolis sign; the CW
  equations need ``G2 = -(0, 0, 2 n0)^x`` (``x'' = 3n^2 x + 2n y'``). [switch]
* eq. 33 -- impact condition: with rho_0_dot the T-frame derivative (eq. 20), the
  relative velocity of the contact points is ``rho0_dot + R^T Q^T omega x (r - rho_0) -
  R^T omega_c x rho_0``; the printed ``(R^T omega_c + omega_t) x rho_0`` adds a spurious
  ``omega_t x rho_0`` (it would be right for the inertial derivative). [switch]
* eq. 38 -- an internal contact impulse cannot move the pair's CoM: ``rho_n_dot+ =
  rho_n_dot`` (as eq. 58 says for the decoupling), not ``rho_n_dot + gamma n / m_c``. [switch]
* eq. 48 -- the thrust is in D: ``R^T Q^T F_d / m`` (printed ``R^T F_d / m``; equal only
  when docked with q = q_I). Same in f_0^6 (from eqs. 21, 31). [fixed]
* eq. 49/51 -- the composite inertia about the composite CoM is ``J_c + Q^T J_d Q +
  m_c m_d / m (|d|^2 I - d d^T)``, d = R rho_0 (parallel-axis theorem), not ``J_c + J_d``;
  the moment arm of F_d about the composite CoM is ``(m_c/m) d`` (= (m_c/m)(P_c - P_d)
  only at rho = 0, q = q_I), and F_d must be rotated to C (``Q^T F_d``). [fixed]
* eq. 56-57 -- with T_pi "along rho_0" the printed signs push the bodies together; a snap
  that separates them has T_pi = -|T_pi| rho_0/|rho_0| (see
  :func:`proxops.dynamics.two_rigid_bodies.latch_snap_jump`). eq. 60 is then right.
* eq. 78 -- ``q(0, 0) = 0.57 [1_3, 0]`` is not a unit quaternion (norm 0.987): 1/sqrt(3).
* eqs. 19, 20, 22 (apart from G2), 25, 27-29, 34, 36, 37, 41, 43, 50, 53-55, 58-61 agree
  with the derivation.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from proxops.core.small_linalg import cross3
from proxops.core.quaternion import dcm_kernel, multiply_kernel, quat_kinematics, quat_to_dcm
from proxops.dynamics.two_rigid_bodies import (
    SL_QC,
    SL_QD,
    SL_RC,
    SL_RD,
    SL_VC,
    SL_VD,
    SL_WC,
    SL_WD,
    HybridParams,
)

REL_STATE_NAMES = (
    "rho_x", "rho_y", "rho_z", "rho_dot_x", "rho_dot_y", "rho_dot_z",
    "omega_x", "omega_y", "omega_z", "q_x", "q_y", "q_z", "q_w",
    "p_x", "p_y", "p_z", "p_w", "omega_c_x", "omega_c_y", "omega_c_z",
    "rho_n_x", "rho_n_y", "rho_n_z", "rho_n_dot_x", "rho_n_dot_y", "rho_n_dot_z",
    "r_des_x", "r_des_y", "r_des_z", "r_des_dot_x", "r_des_dot_y", "r_des_dot_z",
)  # fmt: skip
N_REL = 32
S_RHO, S_RHOD, S_OM, S_Q = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 13)
S_P, S_OMC, S_RN, S_RND, S_REF = slice(13, 17), slice(17, 20), slice(20, 23), slice(23, 26), slice(26, 32)


# --------------------------------------------------------------------------------------
# numpy / CasADi operations (one model definition for both)
# --------------------------------------------------------------------------------------
class _Np:
    @staticmethod
    def cross(a, b):
        return np.cross(a, b)

    @staticmethod
    def mv(M, v):
        return M @ v

    @staticmethod
    def mm(A, B):
        return A @ B

    @staticmethod
    def dot(a, b):
        return float(a @ b)

    @staticmethod
    def vcat(items):
        return np.concatenate([np.atleast_1d(np.asarray(i, dtype=float)) for i in items])

    @staticmethod
    def solve(J, v):
        return np.linalg.solve(J, v)

    @staticmethod
    def dcm(q):
        """Paper's R(q) of eq. 4 (= quat_to_dcm(q).T)."""
        return quat_to_dcm(q).T


class _Ca:
    def __init__(self):
        import casadi as ca

        self.ca = ca

    def cross(self, a, b):
        return self.ca.cross(a, b)

    def mv(self, M, v):
        return self.ca.mtimes(M, v)

    mm = mv

    def dot(self, a, b):
        return self.ca.dot(a, b)

    def vcat(self, items):
        return self.ca.vertcat(*items)

    def solve(self, J, v):
        return self.ca.mtimes(np.linalg.inv(J), v)

    def dcm(self, q):
        """eq. 4: R(q) = (q_mu^2 - q_eta.q_eta) I + 2 q_eta q_eta^T - 2 q_mu q_eta^x."""
        ca = self.ca
        e, m = q[0:3], q[3]
        ex = ca.vertcat(
            ca.horzcat(0, -e[2], e[1]), ca.horzcat(e[2], 0, -e[0]), ca.horzcat(-e[1], e[0], 0)
        )
        return (m * m - ca.dot(e, e)) * ca.DM.eye(3) + 2 * ca.mtimes(e, e.T) - 2 * m * ex


def _ops(*values):
    if any(type(v).__module__.startswith("casadi") for v in values):
        return _Ca()
    return _Np


def _g_matrices(params: HybridParams, corrected: bool):
    n = params.mean_motion_rad_s
    G1 = np.diag([3.0 * n * n, 0.0, -n * n])
    G2_printed = np.array([[0.0, -2.0 * n, 0.0], [2.0 * n, 0.0, 0.0], [0.0, 0.0, 0.0]])  # (0, 0, 2n)^x
    return G1, (-G2_printed if corrected else G2_printed)


def _quat_rate(o, q, w):
    """eqs. 27/29: (q_eta', q_mu') = 0.5 ((q_eta^x + q_mu I) w, -q_eta^T w) (= quat_kinematics)."""
    if o is _Np:
        return quat_kinematics(q, w)
    e, m = q[0:3], q[3]
    return o.vcat([0.5 * (o.cross(e, w) + m * w), -0.5 * o.dot(e, w)])


# --------------------------------------------------------------------------------------
# capture flow f_0 (eq. 32)
# --------------------------------------------------------------------------------------
def omega_c_dot(p, omega_c, params: HybridParams):
    """f_0^5 of eq. 28: omega_c' = J_c^-1 (-(W x J_c W)) + omega_c x R omega_t, W = omega_c + R omega_t."""
    o = _ops(p, omega_c)
    R = o.dcm(p)
    Rwt = o.mv(R, params.omega_t)
    W = omega_c + Rwt
    return o.solve(params.J_c, -o.cross(W, o.mv(params.J_c, W))) + o.cross(omega_c, Rwt)


def omega_dot(omega, q, p, omega_c, M_d, params: HybridParams):
    """f_0^3 of eq. 25 (rad/s^2)."""
    o = _ops(omega, q, p, omega_c, M_d)
    Q, R = o.dcm(q), o.dcm(p)
    W = omega_c + o.mv(R, params.omega_t)  # omega_{C/I}|_C
    Wd = omega + o.mv(Q, W)  # omega_{D/I}|_D, eq. 7
    return (
        o.solve(params.J_d, M_d - o.cross(Wd, o.mv(params.J_d, Wd)))
        + o.mv(Q, o.solve(params.J_c, o.cross(W, o.mv(params.J_c, W))))
        - o.cross(o.mv(Q, W), omega)
    )


def rho_ddot(x, F_d, omega_dot_, omega_c_dot_, params: HybridParams, corrected: bool = True):
    """f_0^2 of eq. 22 (m/s^2) given omega' and omega_c' (from eqs. 25 and 28)."""
    o = _ops(x, F_d, omega_dot_, omega_c_dot_)
    G1, G2 = _g_matrices(params, corrected)
    rho, rhod, om, q, p, omc = x[0:3], x[3:6], x[6:9], x[9:13], x[13:17], x[17:20]
    Q, R = o.dcm(q), o.dcm(p)
    Rt, Qt = R.T, Q.T
    RG1Rt, RG2Rt = o.mm(R, o.mm(G1, Rt)), o.mm(R, o.mm(G2, Rt))
    Pc, Pd = params.P_c, params.P_d
    a = rho + Pc
    wd = om + o.mv(Q, omc)  # eq. 6
    wd_dot = omega_dot_ + o.mv(Q, omega_c_dot_ - o.cross(o.mv(Qt, om), omc))
    return (
        o.mv(RG2Rt, rhod)
        + o.mv(RG1Rt, rho)
        + o.mv(Qt, F_d) / params.mass_deputy_kg
        + o.mv(RG1Rt, Pc - o.mv(Qt, Pd))
        - 2.0 * o.cross(omc, rhod)
        - o.cross(omega_c_dot_, a)
        + o.mv(RG2Rt, o.cross(omc, a) - o.mv(Qt, o.cross(wd, Pd)))
        - o.cross(omc, o.cross(omc, a))
        + o.mv(Qt, o.cross(wd_dot, Pd) + o.cross(wd, o.cross(wd, Pd)))
    )


def relative_rhs(x, u, params: HybridParams, corrected: bool = True):
    """Capture flow f_0(x, u) of eq. 32 (numpy array or CasADi column, 32 entries).

    The composite CoM obeys CW with the total external force (f_0^6 from eqs. 21, 31):
    rho_n'' = G1 rho_n + G2 rho_n' + R^T Q^T F_d / m. x_ref is held (eq. 32: 0_{6x1})."""
    o = _ops(x, u)
    G1, G2 = _g_matrices(params, corrected)
    q, p, om, omc = x[9:13], x[13:17], x[6:9], x[17:20]
    F_d, M_d = u[0:3], u[3:6]
    omd = omega_dot(om, q, p, omc, M_d, params)
    omcd = omega_c_dot(p, omc, params)
    Q, R = o.dcm(q), o.dcm(p)
    F_T = o.mv(R.T, o.mv(Q.T, F_d))
    rn, rnd = x[20:23], x[23:26]
    return o.vcat(
        [
            x[3:6],
            rho_ddot(x, F_d, omd, omcd, params, corrected),
            omd,
            _quat_rate(o, q, om),
            _quat_rate(o, p, omc),
            omcd,
            rnd,
            o.mv(G1, rn) + o.mv(G2, rnd) + F_T / params.mass_total_kg,
            0.0 * x[26:32],
        ]
    )


def steady_inputs(p, omega_c, params: HybridParams, corrected: bool = True):
    """kappa^0(p, omega_c) = (u1_bar, u2_bar) of eqs. 41 and 43: the input that holds the
    docking configuration (rho = 0, rho' = 0, omega = 0, q = q_I) in equilibrium."""
    o = _ops(p, omega_c)
    G1, G2 = _g_matrices(params, corrected)
    R = o.dcm(p)
    RG1Rt, RG2Rt = o.mm(R, o.mm(G1, R.T)), o.mm(R, o.mm(G2, R.T))
    d = params.P_c - params.P_d
    omcd = omega_c_dot(p, omega_c, params)
    u1 = params.mass_deputy_kg * (
        -o.mv(RG1Rt, d) + o.cross(omcd, d) + o.cross(omega_c, o.cross(omega_c, d)) - o.mv(RG2Rt, o.cross(omega_c, d))
    )
    W = omega_c + o.mv(R, params.omega_t)
    u2 = o.cross(W, o.mv(params.J_d, W)) - o.mv(params.J_d, o.solve(params.J_c, o.cross(W, o.mv(params.J_c, W))))
    return u1, u2


# --------------------------------------------------------------------------------------
# relative state <-> truth
# --------------------------------------------------------------------------------------
@njit(cache=True)
def relative_from_truth_kernel(xt, x_ref, out, P_c, P_d, m_c, m_d, n):
    """numba form of :func:`relative_from_truth`: writes the 32 relative entries into ``out``
    (truth xt (26), x_ref (6); P_c, P_d (m, body axes), masses (kg), n0 (rad/s))."""
    qc = xt[12:16]
    qd = xt[19:23]
    q = multiply_kernel(np.array([-qc[0], -qc[1], -qc[2], qc[3]]), qd)  # q_c* (x) q_d
    if q[3] < 0:  # the paper's q and -q are the same attitude; keep the scalar >= 0 branch
        q = -q
    Rc = dcm_kernel(qc)  # C_{T<-C} = R^T
    Qt = dcm_kernel(q)  # C_{C<-D} = Q^T
    Wc, Wd = xt[16:19], xt[23:26]
    omc = np.empty(3)
    om = np.empty(3)
    rho = np.empty(3)
    for i in range(3):  # omega_c = W_c - R omega_t (eq. 30), omega = W_d - Q W_c (eq. 7)
        omc[i] = Wc[i] - Rc[2, i] * n
        om[i] = Wd[i] - (Qt[0, i] * Wc[0] + Qt[1, i] * Wc[1] + Qt[2, i] * Wc[2])
    wd = np.empty(3)
    for i in range(3):  # omega_{D/C} + Q omega_c, eq. 6
        wd[i] = om[i] + (Qt[0, i] * omc[0] + Qt[1, i] * omc[1] + Qt[2, i] * omc[2])
    rho0 = xt[6:9] - xt[0:3]
    rho0d = xt[9:12] - xt[3:6]
    wxp = cross3(wd, P_d)
    for i in range(3):  # eqs. 18-19
        rho[i] = (Rc[0, i] * rho0[0] + Rc[1, i] * rho0[1] + Rc[2, i] * rho0[2]
                  + Qt[i, 0] * P_d[0] + Qt[i, 1] * P_d[1] + Qt[i, 2] * P_d[2] - P_c[i])
    a = rho + P_c
    oxa = cross3(omc, a)
    m = m_c + m_d
    for i in range(3):
        out[i] = rho[i]
        out[3 + i] = (Rc[0, i] * rho0d[0] + Rc[1, i] * rho0d[1] + Rc[2, i] * rho0d[2] - oxa[i]
                      + Qt[i, 0] * wxp[0] + Qt[i, 1] * wxp[1] + Qt[i, 2] * wxp[2])  # eq. 20
        out[6 + i] = om[i]
        out[17 + i] = omc[i]
        out[20 + i] = (m_c * xt[i] + m_d * xt[6 + i]) / m  # eq. 30
        out[23 + i] = (m_c * xt[3 + i] + m_d * xt[9 + i]) / m
    for i in range(4):
        out[9 + i] = q[i]
        out[13 + i] = qc[i]
    for i in range(6):
        out[26 + i] = x_ref[i]


_ZERO_REF = np.zeros(6)


def relative_from_truth(xt, params: HybridParams, x_ref=None) -> np.ndarray:
    """The paper's relative state (32) computed from the direct truth state (26):
    q = q_c* (x) q_d, p = q_c, eqs. 6-7, 18-20, 30 (numba kernel
    :func:`relative_from_truth_kernel`)."""
    out = np.empty(N_REL)
    relative_from_truth_kernel(np.asarray(xt, dtype=float), _ZERO_REF if x_ref is None else np.asarray(x_ref, float),
                               out, params.P_c, params.P_d, float(params.mass_chief_kg),
                               float(params.mass_deputy_kg), float(params.mean_motion_rad_s))
    return out


def rho0_and_rate(x, params: HybridParams):
    """(rho_0, rho_0_dot) in T from the relative state: eqs. 19-20 (numpy)."""
    x = np.asarray(x, dtype=float)
    Q, R = quat_to_dcm(x[S_Q]).T, quat_to_dcm(x[S_P]).T
    rho, rhod, om, omc = x[S_RHO], x[S_RHOD], x[S_OM], x[S_OMC]
    wd = om + Q @ omc
    rho0 = R.T @ (rho + params.P_c) - R.T @ Q.T @ params.P_d
    rho0d = R.T @ (rhod + np.cross(omc, rho + params.P_c)) - R.T @ Q.T @ np.cross(wd, params.P_d)
    return rho0, rho0d


# --------------------------------------------------------------------------------------
# contact jump g_0 (eqs. 33-39)
# --------------------------------------------------------------------------------------
def impact_velocity(x, r, n, params: HybridParams, corrected: bool = True) -> float:
    """v_rel of eq. 33 (m/s) from the relative state; r (m, from the chief CoM) and the
    normal n in T. Impact when v_rel <= 0."""
    x = np.asarray(x, dtype=float)
    Q, R = quat_to_dcm(x[S_Q]).T, quat_to_dcm(x[S_P]).T
    rho0, rho0d = rho0_and_rate(x, params)
    w_rel = R.T @ x[S_OMC] + (0.0 if corrected else params.omega_t)
    return float(n @ (rho0d + np.cross(R.T @ Q.T @ x[S_OM], r - rho0) - np.cross(w_rel, rho0)))


def relative_contact_jump(x, gamma, r, n, params: HybridParams, corrected: bool = True) -> np.ndarray:
    """g_0 of eq. 39: the relative state after an impulse gamma (N s) along n (T, from the
    chief into the deputy) at r (m, from the chief CoM, T). eqs. 34, 37, 38."""
    x = np.asarray(x, dtype=float)
    Q, R = quat_to_dcm(x[S_Q]).T, quat_to_dcm(x[S_P]).T
    rho, rhod, om, omc = x[S_RHO], x[S_RHOD], x[S_OM], x[S_OMC]
    Pc, Pd = params.P_c, params.P_d
    rho0, _ = rho0_and_rate(x, params)
    mc, md = params.mass_chief_kg, params.mass_deputy_kg
    om_p = om + gamma * (
        np.linalg.solve(params.J_d, Q @ R @ np.cross(r - rho0, n)) + Q @ np.linalg.solve(params.J_c, R @ np.cross(r, n))
    )  # eq. 34
    omc_p = omc - gamma * np.linalg.solve(params.J_c, R @ np.cross(r, n))  # eq. 34
    wd = om + Q @ omc
    a = rho + Pc
    rhod_p = (
        rhod
        + np.cross(omc, a)
        - Q.T @ np.cross(wd, Pd)
        + gamma * R @ n * (1.0 / md + 1.0 / mc)
        + Q.T @ np.cross(Q @ omc_p, Pd)
        - np.cross(omc_p, a)
        + Q.T @ np.cross(om_p, Pd)
    )  # eq. 37
    xp = x.copy()
    xp[S_RHOD], xp[S_OM], xp[S_OMC] = rhod_p, om_p, omc_p
    if not corrected:
        xp[S_RND] = x[S_RND] + gamma * n / mc  # eq. 38 as printed
    return xp


# --------------------------------------------------------------------------------------
# post-capture composite (eqs. 44-51) and decoupling g_1 (eqs. 53-61)
# --------------------------------------------------------------------------------------
def composite_inertia(x, params: HybridParams) -> np.ndarray:
    """Inertia (kg m^2, C components) of the pair about its CoM: J_c + Q^T J_d Q +
    m_c m_d / m (|d|^2 I - d d^T), d = R rho_0 (corrects eq. 49's J_c + J_d)."""
    x = np.asarray(x, dtype=float)
    Q, R = quat_to_dcm(x[S_Q]).T, quat_to_dcm(x[S_P]).T
    rho0, _ = rho0_and_rate(x, params)
    d = R @ rho0
    mu = params.mass_chief_kg * params.mass_deputy_kg / params.mass_total_kg
    return params.J_c + Q.T @ params.J_d @ Q + mu * (d @ d * np.eye(3) - np.outer(d, d))


def composite_omega_c_dot(x, u, params: HybridParams) -> np.ndarray:
    """f_1^5 of eq. 51 (rigidly docked pair, rad/s^2) with the corrected composite inertia
    and moment arm: omega_c' = omega_c x R omega_t + J^-1 [-W x J W + Q^T M_d + (m_c/m) d x Q^T F_d]."""
    x = np.asarray(x, dtype=float)
    u = np.asarray(u, dtype=float)
    Q, R = quat_to_dcm(x[S_Q]).T, quat_to_dcm(x[S_P]).T
    omc = x[S_OMC]
    Rwt = R @ params.omega_t
    W = omc + Rwt
    J = composite_inertia(x, params)
    rho0, _ = rho0_and_rate(x, params)
    d = R @ rho0
    torque = Q.T @ u[3:6] + params.mass_chief_kg / params.mass_total_kg * np.cross(d, Q.T @ u[0:3])
    return np.cross(omc, Rwt) + np.linalg.solve(J, -np.cross(W, J @ W) + torque)


def composite_com_ddot(x, u, params: HybridParams, corrected: bool = True) -> np.ndarray:
    """f_1^6 of eq. 48: rho_n'' = G1 rho_n + G2 rho_n' + R^T Q^T F_d / m (m/s^2)."""
    x = np.asarray(x, dtype=float)
    G1, G2 = _g_matrices(params, corrected)
    Q, R = quat_to_dcm(x[S_Q]).T, quat_to_dcm(x[S_P]).T
    return G1 @ x[S_RN] + G2 @ x[S_RND] + R.T @ Q.T @ np.asarray(u, float)[0:3] / params.mass_total_kg


def reference_rhs(x_ref, params: HybridParams):
    """f_T of eq. 52: the desired orbit r_des of the pair's CoM. The paper leaves it open;
    our default is natural CW motion in T (a parking orbit that needs no thrust)."""
    G1, G2 = _g_matrices(params, True)
    x_ref = np.asarray(x_ref, dtype=float)
    return np.concatenate([x_ref[3:6], G1 @ x_ref[0:3] + G2 @ x_ref[3:6]])


def post_capture_rhs(x, u, params: HybridParams, corrected: bool = True) -> np.ndarray:
    """f_1 of eq. 52 (numpy): the docked pair with the eq. 81 latch, built as the paper does:
    the deputy's relative motion is f_0^2 / f_0^3 with the latch added to the deputy's force
    and torque (eqs. 40, 42), the chief's rate follows the composite rigid body (eq. 51),
    the pair's CoM follows eq. 48 and x_ref follows f_T (:func:`reference_rhs`).

    Readings of the printed equations: eq. 40 writes ``-K_T rho - D_T rho'`` as an
    acceleration but says it replaces F_d by ``Q(-K_T rho - D_T rho') + u1_bar``, a force;
    we take the force (divided by m_d), consistent with the truth latch
    (:func:`proxops.dynamics.two_rigid_bodies.latch_wrench`). The steady inputs u1_bar, u2_bar
    (eqs. 41, 43) are the controller's business and enter through ``u``. With
    ``corrected=False`` the printed G2, eq. 48 without Q^T and eq. 51 with J_c + J_d and the
    (P_c - P_d) arm are used. This is an approximate model (the chief feels the latch only
    through the composite eq. 51); benchmarks/bench_hybrid_physics.py measures it against
    the latched two-body truth."""
    x = np.asarray(x, dtype=float)
    u = np.asarray(u, dtype=float)
    G1, G2 = _g_matrices(params, corrected)
    rho, rhod, om, q, p, omc = x[S_RHO], x[S_RHOD], x[S_OM], x[S_Q], x[S_P], x[S_OMC]
    Q, R = quat_to_dcm(q).T, quat_to_dcm(p).T
    s = np.linalg.norm(q[:3])
    theta_e = 2.0 * np.arctan2(s, q[3]) * q[:3] / s if s > 1e-15 else 2.0 * q[:3]
    F_latch = Q @ (-params.latch_KT * rho - params.latch_DT * rhod)  # in D
    M_latch = -params.latch_KR * theta_e - params.latch_DR * om
    F_d, M_d = u[0:3] + F_latch, u[3:6] + M_latch
    if corrected:
        omcd = composite_omega_c_dot(x, u, params)
    else:
        Rwt = R @ params.omega_t
        W = omc + Rwt
        J = params.J_c + params.J_d
        arm = params.mass_chief_kg / params.mass_total_kg * (params.P_c - params.P_d)
        omcd = np.cross(omc, Rwt) + np.linalg.solve(J, -np.cross(W, J @ W) + u[3:6] + np.cross(arm, u[0:3]))
    omd = omega_dot(om, q, p, omc, M_d, params)
    F_T = R.T @ ((Q.T if corrected else np.eye(3)) @ u[0:3])
    return np.concatenate(
        [
            rhod,
            rho_ddot(x, F_d, omd, omcd, params, corrected),
            omd,
            _quat_rate(_Np, q, om),
            _quat_rate(_Np, p, omc),
            omcd,
            x[S_RND],
            G1 @ x[S_RN] + G2 @ x[S_RND] + F_T / params.mass_total_kg,
            reference_rhs(x[S_REF], params),
        ]
    )


def relative_decoupling_jump(x, T_pi, params: HybridParams) -> np.ndarray:
    """g_1 of eq. 61: after an internal impulse T_pi (N s, T components; +T_pi on the chief,
    -T_pi on the deputy, eq. 57) along the CoM line: rates, attitudes, rho and the pair CoM
    are unchanged (eqs. 53-55, 58) and rho' jumps by -R (1/m_c + 1/m_d) T_pi (eq. 60)."""
    x = np.asarray(x, dtype=float)
    R = quat_to_dcm(x[S_P]).T
    xp = x.copy()
    xp[S_RHOD] = x[S_RHOD] - R @ np.asarray(T_pi, float) * (1.0 / params.mass_chief_kg + 1.0 / params.mass_deputy_kg)
    return xp


__all__ = [
    "N_REL",
    "REL_STATE_NAMES",
    "composite_com_ddot",
    "composite_inertia",
    "composite_omega_c_dot",
    "impact_velocity",
    "omega_c_dot",
    "omega_dot",
    "post_capture_rhs",
    "reference_rhs",
    "relative_contact_jump",
    "relative_decoupling_jump",
    "relative_from_truth",
    "relative_rhs",
    "rho0_and_rate",
    "rho_ddot",
    "steady_inputs",
]
