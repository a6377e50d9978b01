"""numba kernels of the hybrid capture / post-capture MPCs (:mod:`proxops.control.hybrid_mpc`):
one call per step builds the condensed box QP with its soft rate rows from the continuous
model, so the step costs the solver plus a few microseconds (issue: hybrid at the solver's speed).

* :class:`Tape` / :func:`tape_eval`: a CasADi SX function (the capture linearisation, eqs. 62-72)
  replayed as its own instruction list (+, -, *, /, neg, sq, twice, sqrt, constants) in numba:
  the same floating-point operations in the same order as CasADi's virtual machine, without its
  ~0.1-0.2 ms call overhead.
* the ZOH exponential is :func:`proxops.core.small_linalg.expm_pade13` (shared with the MEKF).
* :func:`condensed_qp`: ZOH discretisation, condensing X = Phi x0 + G U, the weighted cost
  with the rank-one face terms of eq. 66 (QP form), the bounds and the rate rows.
* :func:`approach_target_kernel`: the approach-guidance waypoint (hybrid_mpc module doc).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from proxops.core.quaternion import dcm_kernel
from proxops.core.small_linalg import expm_pade13, matmul_into, matmul_tn_into

# CasADi opcodes -> ours (casadi.OP_*; checked at Tape construction)
_OP_NAMES = ("INPUT", "OUTPUT", "CONST", "ADD", "SUB", "MUL", "DIV", "NEG", "SQ", "TWICE", "SQRT", "INV", "ASSIGN")


class Tape:
    """The instruction list of a CasADi SX Function with dense vector inputs and one output,
    evaluated by :func:`tape_eval`. ``ok`` is False if the function uses an operation the
    kernel does not know (the caller then keeps calling CasADi)."""

    def __init__(self, fun):
        import casadi as ca

        codes = {getattr(ca, "OP_" + name): k for k, name in enumerate(_OP_NAMES)}
        n = fun.n_instructions()
        offsets = np.cumsum([0] + [fun.nnz_in(i) for i in range(fun.n_in())])
        rows = np.asarray(fun.sparsity_out(0).row(), dtype=np.int64)
        self.n_in = int(offsets[-1])
        self.n_out = int(fun.sparsity_out(0).size1())
        self.code = np.zeros(n, np.int64)
        self.a = np.zeros(n, np.int64)
        self.b = np.zeros(n, np.int64)
        self.o = np.zeros(n, np.int64)
        self.c = np.zeros(n)
        self.ok = fun.n_out() == 1 and fun.sparsity_out(0).size2() == 1
        for k in range(n):
            op = fun.instruction_id(k)
            if op not in codes:
                self.ok = False
                return
            code = codes[op]
            ins, outs = fun.instruction_input(k), fun.instruction_output(k)
            self.code[k] = code
            if code == 0:  # INPUT: (input index, nz) -> w
                self.a[k] = offsets[ins[0]] + ins[1]
                self.o[k] = outs[0]
            elif code == 1:  # OUTPUT: w -> (output 0, nz)
                self.a[k] = ins[0]
                self.o[k] = rows[outs[1]]
            elif code == 2:
                self.c[k] = fun.instruction_constant(k)
                self.o[k] = outs[0]
            else:
                self.a[k] = ins[0]
                self.b[k] = ins[1] if len(ins) > 1 else 0
                self.o[k] = outs[0]
        self.n_work = int(fun.sz_w())

    def __call__(self, inp: np.ndarray) -> np.ndarray:
        out = np.zeros(self.n_out)
        tape_eval(self.code, self.a, self.b, self.o, self.c, inp, np.empty(self.n_work), out)
        return out


@njit(cache=True)
def tape_eval(code, a, b, o, c, inp, w, out):
    """Replay a :class:`Tape` (inputs concatenated in ``inp``, work vector ``w``, dense ``out``)."""
    for k in range(code.shape[0]):
        op = code[k]
        if op == 5:
            w[o[k]] = w[a[k]] * w[b[k]]
        elif op == 3:
            w[o[k]] = w[a[k]] + w[b[k]]
        elif op == 4:
            w[o[k]] = w[a[k]] - w[b[k]]
        elif op == 2:
            w[o[k]] = c[k]
        elif op == 0:
            w[o[k]] = inp[a[k]]
        elif op == 1:
            out[o[k]] = w[a[k]]
        elif op == 8:
            w[o[k]] = w[a[k]] * w[a[k]]
        elif op == 9:
            w[o[k]] = 2.0 * w[a[k]]
        elif op == 7:
            w[o[k]] = -w[a[k]]
        elif op == 6:
            w[o[k]] = w[a[k]] / w[b[k]]
        elif op == 10:
            w[o[k]] = math.sqrt(w[a[k]])
        elif op == 11:
            w[o[k]] = 1.0 / w[a[k]]
        else:  # ASSIGN
            w[o[k]] = w[a[k]]


@njit(cache=True)
def condensed_qp(A, B, dt, N, dx0, W, r_blk, ref, face_a, wf, rate_first, rate_w, H, f, G, free, A_rate, bl, bu):
    """Condensed box QP of a linear MPC over N stages with ZOH period dt (s), written into the
    caller's arrays (no array is returned: numba boxes each returned array at ~1 us).

    Model x' = A x + B u (n x n, n x m), discretised exactly (expm of [[A, B], [0, 0]] dt);
    X = [x_1..x_N] = Phi x0 + G U. Cost sum_k (x_k - ref_k)' diag(W_k) (x_k - ref_k) + U' diag(r_blk) U
    + wf sum_k (a_k' rho_k)^2 (face rows a_k = face_a[k] on x_k[0:3], on rho itself, not rho - ref;
    wf = 0: none), scaled by s = 1 / max(r_blk). Outputs: H (nU, nU) = s (H + H'), f (nU) = 2 s f,
    G (nX, nU), free (nX) = Phi x0 and, for rate_w >= 0, the rate rows
    -rate_w <= x_k[rate_first:rate_first+3] <= rate_w as A_rate (3N, nU), bl, bu (3N) (rate_w < 0:
    not written; nX = N n, nU = N m).

    Every sum runs in dot-product order (each output element from 0.0 over the inner index in turn;
    the free response, g and f with the output index innermost), so the bits do not depend on the
    loop nesting."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    for i in range(n):
        for j in range(n):
            M[i, j] = A[i, j] * dt
        for j in range(m):
            M[i, n + j] = B[i, j] * dt
    E = expm_pade13(M)
    Ad = np.ascontiguousarray(E[:n, :n])
    Bd = np.ascontiguousarray(E[:n, n:])
    nU = N * m
    scale = 1.0 / r_blk.max()
    # powers Ad^i Bd (the blocks of G) and the free response Ad^(k+1) x0
    PB = np.empty((N, n, m))
    PB[0] = Bd
    for i in range(1, N):
        matmul_into(Ad, PB[i - 1], PB[i])
    for k in range(N):
        for i in range(n):
            free[k * n + i] = 0.0
        for l in range(n):
            c = dx0[l] if k == 0 else free[(k - 1) * n + l]
            for i in range(n):
                free[k * n + i] += Ad[i, l] * c
    for k in range(N):
        for j in range(N):
            for i in range(n):
                for l in range(m):
                    G[k * n + i, j * m + l] = PB[k - j, i, l] if j <= k else 0.0
    # H = G' Wt G and f = G' Wt (free - ref) without forming G' Wt G: with the stage weight
    # Wt_k = diag(W_k) + wf a_k a_k' (face rows on x_k[0:3]), P_j = Wt_j + Ad' P_{j+1} Ad and
    # g_j = Wt_j e_j + Ad' g_{j+1} (e = free - ref), block (i, j >= i) of H is (Ad^(j-i) Bd)' P_j Bd
    # and block i of f is Bd' g_i (the backward recursion of the condensed cost).
    P = np.zeros((n, n))
    g = np.zeros(n)
    Wt = np.empty((n, n))
    PA = np.empty((n, n))
    PBj = np.empty((n, m))
    gj = np.empty(n)
    acc = np.empty(n)
    for j in range(N - 1, -1, -1):
        Wt[:, :] = 0.0
        for i in range(n):
            Wt[i, i] = W[j * n + i]
        if wf > 0.0:
            for i in range(3):
                for l in range(3):
                    Wt[i, l] += wf * face_a[j, i] * face_a[j, l]
        # linear term: diag(W_j) (free_j - ref_j) + wf a_j (a_j' free_j[0:3]) (the face rows see rho itself)
        for i in range(n):
            gj[i] = W[j * n + i] * (free[j * n + i] - ref[j * n + i])
        if wf > 0.0:
            af = face_a[j, 0] * free[j * n] + face_a[j, 1] * free[j * n + 1] + face_a[j, 2] * free[j * n + 2]
            for i in range(3):
                gj[i] += wf * face_a[j, i] * af
        if j == N - 1:
            P[:, :] = Wt
            g[:] = gj
        else:
            matmul_into(P, Ad, PA)  # P Ad
            matmul_tn_into(Ad, PA, P)  # Ad' (P Ad)
            for i in range(n):
                for l in range(n):
                    P[i, l] = Wt[i, l] + P[i, l]
            acc[:] = 0.0  # Ad' g
            for l in range(n):
                c = g[l]
                for i in range(n):
                    acc[i] += Ad[l, i] * c
            for i in range(n):
                g[i] = gj[i] + acc[i]
        matmul_into(P, Bd, PBj)
        for i in range(m):  # f_j = Bd' g_j, scaled
            acc[i] = 0.0
        for l in range(n):
            c = g[l]
            for i in range(m):
                acc[i] += Bd[l, i] * c
        for i in range(m):
            f[j * m + i] = (2.0 * scale) * acc[i]
        for i in range(j + 1):  # block (i, j) = (Ad^(j-i) Bd)' P_j Bd, straight into H
            blk = PB[j - i]
            for a in range(m):
                for b in range(m):
                    sacc = 0.0
                    for l in range(n):
                        sacc += blk[l, a] * PBj[l, b]
                    H[i * m + a, j * m + b] = sacc
    for i in range(nU):  # the input weight, the lower triangle mirrored, s (H + H')
        d = H[i, i] + r_blk[i]
        H[i, i] = scale * (d + d)
        for l in range(i + 1, nU):
            v = scale * (H[i, l] + H[i, l])
            H[i, l] = v
            H[l, i] = v
    if rate_w >= 0.0:
        for k in range(N):
            for i in range(3):
                r = k * n + rate_first + i
                for l in range(nU):
                    A_rate[3 * k + i, l] = G[r, l]
                bl[3 * k + i] = -rate_w - free[r]
                bu[3 * k + i] = rate_w - free[r]


@njit(cache=True)
def face_rows(rho_bar, v, N):
    """Face-term rows a_k = rho_bar_k / |rho_bar_k| - v (0 for |rho_bar_k| <= 1e-9; the terminal
    stage k = N-1 none): the QP form of eq. 66 (hybrid_mpc.face_pointing_linearized)."""
    a = np.zeros((N, 3))
    for k in range(N - 1):
        r = math.sqrt(rho_bar[k, 0] ** 2 + rho_bar[k, 1] ** 2 + rho_bar[k, 2] ** 2)
        if r > 1e-9:
            for i in range(3):
                a[k, i] = rho_bar[k, i] / r - v[i]
    return a


@njit(cache=True)
def approach_target_kernel(rho, P_c, v, radius, half_angle, retreat, step_max):
    """Approach-guidance target of the deputy port (C, m): hybrid_mpc.CaptureMPC.approach_target."""
    s = rho + P_c
    r = math.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2])
    out = np.zeros(3)
    if r < 1e-9:
        return out
    cos_t = min(max((s[0] * v[0] + s[1] * v[1] + s[2] * v[2]) / r, -1.0), 1.0)
    theta = math.acos(cos_t)
    if theta <= half_angle:
        return out
    if r < retreat * radius:  # too close to go round: back off radially first
        return radius * s / r - P_c
    axis = np.array([s[1] * v[2] - s[2] * v[1], s[2] * v[0] - s[0] * v[2], s[0] * v[1] - s[1] * v[0]])
    na = math.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
    if na < 1e-6 * r:  # exactly behind the port: go round any side
        if abs(v[0]) < 0.9:
            axis = np.array([0.0, v[2], -v[1]])  # v x e_x
        else:
            axis = np.array([v[1], -v[0], 0.0])  # v x e_z
        na = math.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
    axis = axis / na
    step = min(theta, step_max)
    e = s / r
    ce = np.array([axis[1] * e[2] - axis[2] * e[1], axis[2] * e[0] - axis[0] * e[2], axis[0] * e[1] - axis[1] * e[0]])
    e_next = e * math.cos(step) + ce * math.sin(step)  # Rodrigues (axis is normal to e)
    return radius * e_next - P_c


@njit(cache=True)
def post_model_kernel(x, A0, B0, G1, G2, gyro, arm, m, kinematics, thrust):
    """(A, B, kappa^1) of the post-capture MPC at the relative state x (32): PostCaptureMPC.continuous_model
    (A0, B0 about A_1; G1, G2 of eq. 21; gyro = omega_t x J omega_t; arm = (m_c/m) d; m the pair's mass)."""
    r, v = x[26:29], x[29:32]
    k1 = np.empty(3)
    for i in range(3):  # eq. 65: m (r_des'' - G1 r_des - G2 r_des') with r_des'' of the natural CW reference
        g1r = G1[i, 0] * r[0] + G1[i, 1] * r[1] + G1[i, 2] * r[2]
        g2v = G2[i, 0] * v[0] + G2[i, 1] * v[1] + G2[i, 2] * v[2]
        k1[i] = m * ((g1r + g2v) - g1r - g2v)
    kappa = np.empty(6)
    kappa[3] = gyro[0] - (arm[1] * k1[2] - arm[2] * k1[1])
    kappa[4] = gyro[1] - (arm[2] * k1[0] - arm[0] * k1[2])
    kappa[5] = gyro[2] - (arm[0] * k1[1] - arm[1] * k1[0])
    kappa[0:3] = k1
    A = A0.copy()
    B = B0.copy()
    if k1[0] != 0.0 or k1[1] != 0.0 or k1[2] != 0.0:  # R^T F = F + 2 p_eta x F + ...
        c = -2.0 / m
        A[9, 1], A[9, 2] = -c * k1[2], c * k1[1]
        A[10, 0], A[10, 2] = c * k1[2], -c * k1[0]
        A[11, 0], A[11, 1] = -c * k1[1], c * k1[0]
        A[9, 0] = A[10, 1] = A[11, 2] = 0.0
    if kinematics:  # eq. 29 at the measured p: (p_eta^x + p_mu I) / 2
        s = 1.0 if x[16] >= 0.0 else -1.0
        px, py, pz, pw = s * x[13], s * x[14], s * x[15], s * x[16]
        A[0, 3], A[0, 4], A[0, 5] = 0.5 * pw, -0.5 * pz, 0.5 * py
        A[1, 3], A[1, 4], A[1, 5] = 0.5 * pz, 0.5 * pw, -0.5 * px
        A[2, 3], A[2, 4], A[2, 5] = -0.5 * py, 0.5 * px, 0.5 * pw
    if thrust:  # R^T Q^T = C_{T<-C} C_{C<-D}
        Rp = dcm_kernel(x[13:17])
        Rq = dcm_kernel(x[9:13])
        C = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                C[i, j] = Rp[i, 0] * Rq[0, j] + Rp[i, 1] * Rq[1, j] + Rp[i, 2] * Rq[2, j]
                B[9 + i, j] = C[i, j] / m
        for j in range(3):
            kappa[j] = C[0, j] * k1[0] + C[1, j] * k1[1] + C[2, j] * k1[2]
    return A, B, kappa


@njit(cache=True)
def capture_model_kernel(code, a, b, o, c, n_work, n_out, p, wc, q, mass_d, decouple, thrust, kinematics):
    """(A (12, 12), B (12, 6), kappa^0 (6,)) of the capture MPC (hybrid_mpc.CaptureMPC.continuous_model):
    the tape of the CasADi linearisation (:class:`Tape`, inputs p (4), omega_c (3); packed output
    vec(A), vec(B), kappa, f0 in column-major order) replayed, then ``decouple`` (translational rows
    blind to the deputy's rate and attitude), ``thrust`` (force block of B and kappa_1 at the measured
    q: Q^T / m_d, Q kappa_1) and ``kinematics`` (q_eta' = (q_eta^x + q_mu I) omega / 2 at the measured q)."""
    inp = np.empty(7)
    for i in range(4):
        inp[i] = p[i]
    for i in range(3):
        inp[4 + i] = wc[i]
    out = np.zeros(n_out)
    tape_eval(code, a, b, o, c, inp, np.empty(n_work), out)
    A = np.empty((12, 12))
    B = np.empty((12, 6))
    for j in range(12):
        for i in range(12):
            A[i, j] = out[12 * j + i]
    for j in range(6):
        for i in range(12):
            B[i, j] = out[144 + 12 * j + i]
    kappa = out[216:222].copy()
    if decouple:
        for i in range(6):
            for j in range(6, 12):
                A[i, j] = 0.0
    if thrust:
        Qt = dcm_kernel(q)  # C_{C<-D} = Q^T
        k0, k1, k2 = kappa[0], kappa[1], kappa[2]
        for j in range(3):
            for i in range(3):
                B[3 + i, j] = Qt[i, j] / mass_d  # eq. 22's Q^T F_d / m_d at the measured q
            kappa[j] = Qt[0, j] * k0 + Qt[1, j] * k1 + Qt[2, j] * k2  # Q kappa_1 (D components)
    if kinematics:
        s = 1.0 if q[3] >= 0.0 else -1.0
        x, y, z, w = s * q[0], s * q[1], s * q[2], s * q[3]
        A[9, 6], A[9, 7], A[9, 8] = 0.5 * w, 0.5 * -z, 0.5 * y  # eq. 27: (q_eta^x + q_mu I) / 2
        A[10, 6], A[10, 7], A[10, 8] = 0.5 * z, 0.5 * w, 0.5 * -x
        A[11, 6], A[11, 7], A[11, 8] = 0.5 * -y, 0.5 * x, 0.5 * w
    return A, B, kappa


@njit(cache=True)
def shifted_face_rows(plan_rho, rho0, has_plan, v, N):
    """Face-term rows a_k (:func:`face_rows`) at the linearisation points rho_bar_k: the last plan's
    predicted rho shifted by one step (its last point repeated), or rho0 at every stage without a plan."""
    bar = np.empty((N, 3))
    for k in range(N):
        src = min(k + 1, N - 1)
        for i in range(3):
            bar[k, i] = plan_rho[src, i] if has_plan else rho0[i]
    return face_rows(bar, v, N)


@njit(cache=True)
def box_bounds(u_max, kappa, N):
    """(lb, ub) of the input box around the steady input over N stages: -u_max - kappa <= du_k <= u_max - kappa."""
    lb = np.empty(N * u_max.shape[0])
    ub = np.empty(N * u_max.shape[0])
    _box_bounds_into(u_max, kappa, N, lb, ub)
    return lb, ub


@njit(cache=True)
def _box_bounds_into(u_max, kappa, N, lb, ub):
    """:func:`box_bounds` written into lb, ub (N m)."""
    m = u_max.shape[0]
    for i in range(m):
        lo = -u_max[i] - kappa[i]
        hi = u_max[i] - kappa[i]
        for k in range(N):
            lb[k * m + i] = lo
            ub[k * m + i] = hi


@njit(cache=True)
def face_penalty_sum(X, n, N, v, weight):
    """sum_{k < N-1} weight (|rho_k| - v' rho_k)^2 of eq. 66 on the predicted rho_k = X[k n : k n + 3]
    (hybrid_mpc.face_pointing_penalty summed over the plan's stages but the terminal one)."""
    s = 0.0
    for k in range(N - 1):
        r0, r1, r2 = X[k * n], X[k * n + 1], X[k * n + 2]
        d = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2) - (r0 * v[0] + r1 * v[1] + r2 * v[2])
        s += weight * d * d
    return s


@njit(cache=True)
def capture_step_kernel(x, code, a, b, o, c, n_work, n_out, use_tape, mass_d, decouple, thrust, kinematics, guide,
                        P_c, v, plan_rho, has_plan, face_on, wf, rate_w, u_max, dt, N, W, r_blk,
                        A, B, kappa, dx0, target, ref, face_a, H, f, G, free, A_rate, bl, bu, lb, ub):
    """The capture MPC's QP of one step (hybrid_mpc.CaptureMPC._solve_qp) from the relative state x (32),
    written into the caller's arrays: dx0 (reduced_capture_state), the model (``use_tape``:
    :func:`capture_model_kernel` into A, B, kappa; else A, B, kappa as given), the approach target
    (``guide`` = (on, radius m, half-angle rad, retreat fraction, step rad); else 0), the reference
    rows, the face rows (``face_on``: :func:`shifted_face_rows` of ``plan_rho`` or dx0's rho), the
    input box and :func:`condensed_qp` (rate rows on omega, x[6:9])."""
    for i in range(9):
        dx0[i] = x[i]
    s = -1.0 if x[12] < 0.0 else 1.0
    for i in range(3):
        dx0[9 + i] = s * x[9 + i]
    if use_tape:
        A1, B1, k1 = capture_model_kernel(code, a, b, o, c, n_work, n_out, x[13:17], x[17:20], x[9:13], mass_d,
                                          decouple, thrust, kinematics)
        A[:, :] = A1
        B[:, :] = B1
        kappa[:] = k1
    if guide[0] > 0.0:
        t = approach_target_kernel(x[0:3], P_c, v, guide[1], guide[2], guide[3], guide[4])
        target[:] = t
    else:
        target[:] = 0.0
    n = A.shape[0]
    ref[:] = 0.0
    for k in range(N):
        for i in range(3):
            ref[k * n + i] = target[i]
    _box_bounds_into(u_max, kappa, N, lb, ub)
    if face_on:
        face_a[:, :] = shifted_face_rows(plan_rho, dx0[0:3], has_plan, v, N)
    else:
        face_a[:, :] = 0.0
    condensed_qp(A, B, dt, N, dx0, W, r_blk, ref, face_a, wf, 6, rate_w, H, f, G, free, A_rate, bl, bu)


@njit(cache=True)
def post_step_kernel(x, A0, B0, G1, G2, gyro, arm, m, kinematics, thrust, rate_w, u_max, dt, N, W, r_blk, ref,
                     face_a, kappa, dx0, H, f, G, free, A_rate, bl, bu, lb, ub):
    """The post-capture MPC's QP of one step (hybrid_mpc.PostCaptureMPC.solve) from the relative state
    x (32), written into the caller's arrays: dx0 (reduced_post_capture_state), :func:`post_model_kernel`
    (kappa), the input box and :func:`condensed_qp` (rate rows on omega_c, dx0[3:6]; no face rows)."""
    s = -1.0 if x[16] < 0.0 else 1.0
    for i in range(3):
        dx0[i] = s * x[13 + i]
        dx0[3 + i] = x[17 + i]
    for i in range(6):
        dx0[6 + i] = x[20 + i] - x[26 + i]
    A, B, k1 = post_model_kernel(x, A0, B0, G1, G2, gyro, arm, m, kinematics, thrust)
    kappa[:] = k1
    _box_bounds_into(u_max, kappa, N, lb, ub)
    condensed_qp(A, B, dt, N, dx0, W, r_blk, ref, face_a, 0.0, 3, rate_w, H, f, G, free, A_rate, bl, bu)
