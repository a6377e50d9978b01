"""The numba kernels of the hybrid loop (control/hybrid_kernels.py, the relative-state kernel)
against independent numpy / scipy / CasADi computations of the same quantities."""

import math

import numpy as np
import pytest
import scipy.linalg

from proxops.control.hybrid_kernels import approach_target_kernel, condensed_qp, face_rows
from proxops.core.small_linalg import expm_pade13, matmul, matmul_into, matmul_tn, matmul_tn_into, matvec
from proxops.control.hybrid_mpc import CaptureMPC, CaptureMPCConfig
from proxops.core.quaternion import quat_conjugate, quat_multiply, quat_to_dcm
from proxops.dynamics.hybrid_relative import relative_from_truth
from proxops.dynamics.two_rigid_bodies import HybridParams

PARAMS = HybridParams()
RNG = np.random.default_rng(7)


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def test_tape_replays_casadi_exactly():
    """The capture linearisation replayed from CasADi's instruction list equals CasADi's own
    evaluation (same operations in the same order: bitwise, or at worst 1 ulp)."""
    lin = CaptureMPC(PARAMS).linearization
    assert lin._tape.ok
    for _ in range(20):
        p = _unit(RNG.standard_normal(4))
        wc = 0.05 * RNG.standard_normal(3)
        ref = np.asarray(lin._fun(p, wc)).ravel()
        got = lin._tape(np.concatenate([p, wc]))
        np.testing.assert_allclose(got, ref, rtol=1e-15, atol=1e-300)


def test_loop_products_match_numpy_and_fill_a_block_view():
    """small_linalg's loop products (shared by the hybrid condensing and the MEKF) against numpy's @,
    with exact zeros in A (skipped by the loops); the _into forms overwrite a block of a larger
    matrix and nothing else."""
    A = RNG.standard_normal((7, 5))
    A[A < -0.5] = 0.0
    B = RNG.standard_normal((5, 4))
    C = RNG.standard_normal((7, 4))
    np.testing.assert_allclose(matmul(A, B), A @ B, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(matmul_tn(A, C), A.T @ C, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(matvec(A, B[:, 0]), A @ B[:, 0], rtol=1e-14, atol=1e-14)
    big = np.full((12, 12), 7.0)
    matmul_into(A, B, big[2:9, 3:7])
    np.testing.assert_array_equal(big[2:9, 3:7], matmul(A, B))
    matmul_tn_into(A, C, big[0:5, 8:12])
    np.testing.assert_array_equal(big[0:5, 8:12], matmul_tn(A, C))
    untouched = np.ones((12, 12), bool)
    untouched[2:9, 3:7] = untouched[0:5, 8:12] = False
    assert np.all(big[untouched] == 7.0)


@pytest.mark.parametrize("norm", [1e-3, 0.5, 3.0, 40.0])
def test_expm_pade13_matches_scipy(norm):
    """exp(M) within 1e-13 relative of scipy.linalg.expm, with and without squaring (theta_13 = 5.37)."""
    M = RNG.standard_normal((18, 18))
    M *= norm / np.abs(M).sum(axis=0).max()
    ref = scipy.linalg.expm(M)
    assert np.abs(expm_pade13(M) - ref).max() <= 1e-13 * np.abs(ref).max()


def _dense_reference(A, B, dt, N, x0, W, r_blk, ref, face_a, wf, first, w):
    """The condensed QP formed explicitly: G and Phi from scipy's ZOH, H = G' W G + ..."""
    n, m = B.shape
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * dt)
    Ad, Bd = E[:n, :n], E[:n, n:]
    G = np.zeros((N * n, N * m))
    Phi = np.zeros((N * n, n))
    for k in range(N):
        Phi[k * n:(k + 1) * n] = np.linalg.matrix_power(Ad, k + 1)
        for j in range(k + 1):
            G[k * n:(k + 1) * n, j * m:(j + 1) * m] = np.linalg.matrix_power(Ad, k - j) @ Bd
    free = Phi @ x0
    H = G.T @ np.diag(W) @ G + np.diag(r_blk)
    f = G.T @ (W * (free - ref))
    for k in range(N):
        row = np.zeros(N * n)
        row[k * n:k * n + 3] = face_a[k]
        aG = row @ G
        H += wf * np.outer(aG, aG)
        f += wf * aG * (row @ free)
    s = 1.0 / r_blk.max()
    idx = np.array([k * n + first + i for k in range(N) for i in range(3)])
    return s * (H + H.T), 2.0 * s * f, G, free, G[idx], -w - free[idx], w - free[idx]


def test_condensed_qp_matches_explicit_condensing():
    """H, f, G, the free response and the rate rows of condensed_qp (backward recursion) equal
    the explicitly formed G' W G (+ face rows) to 1e-12 relative, on the capture model at a
    tumbling state with the (80) weights (c = 3: W spans 1e2..1e9)."""
    mpc = CaptureMPC(PARAMS)
    mpc.set_collision_count(3)
    p, wc, q = _unit([-0.5, 0.5, 0.5, 0.5]), np.array([-0.0024, 0.0024, -0.0024]), _unit([0.3, -0.2, 0.1, 0.9])
    A, B, _ = mpc.continuous_model(p, wc, q)
    N = mpc.N
    W, r_blk = mpc._weights()
    x0 = RNG.standard_normal(12) * 0.1
    ref = np.zeros(N * 12)
    ref[0::12], ref[1::12] = 0.3, -0.2
    face_a = face_rows(RNG.standard_normal((N, 3)), mpc.v, N)
    nU, nX = N * 6, N * 12
    out = (np.empty((nU, nU)), np.empty(nU), np.empty((nX, nU)), np.empty(nX), np.empty((3 * N, nU)), np.empty(3 * N),
           np.empty(3 * N))
    condensed_qp(A, B, 1.0, N, x0, W, r_blk, ref, face_a, 100.0, 6, math.radians(10.0), *out)
    expect = _dense_reference(A, B, 1.0, N, x0, W, r_blk, ref, face_a, 100.0, 6, math.radians(10.0))
    for got, exp in zip(out, expect):
        assert np.abs(got - exp).max() <= 1e-12 * max(np.abs(exp).max(), 1e-300)
    assert np.all(face_a[N - 1] == 0.0)  # terminal stage: Q_f only


def test_approach_target_kernel_matches_numpy_form():
    """Every branch (corridor, retreat, going round, exactly behind the port) as the numpy form."""
    mpc = CaptureMPC(PARAMS, CaptureMPCConfig())
    pts = [RNG.standard_normal(3) * s for s in (0.3, 1.0, 2.0, 5.0) for _ in range(10)]
    pts += [np.zeros(3) - PARAMS.P_c, 0.01 * mpc.v, -3.0 * mpc.v - PARAMS.P_c, -0.5 * mpc.v - PARAMS.P_c]
    for rho in pts:
        np.testing.assert_allclose(mpc.approach_target(rho), mpc._approach_target_numpy(rho), rtol=1e-13, atol=1e-14)


def test_relative_from_truth_kernel_matches_numpy_formulas():
    """The relative state of a random truth state, against eqs. 6-7, 18-20, 30 written in numpy."""
    for _ in range(10):
        xt = np.zeros(26)
        xt[0:12] = RNG.standard_normal(12)
        xt[12:16], xt[19:23] = _unit(RNG.standard_normal(4)), _unit(RNG.standard_normal(4))
        xt[16:19], xt[23:26] = 0.1 * RNG.standard_normal(3), 0.1 * RNG.standard_normal(3)
        ref6 = RNG.standard_normal(6)
        qc, qd = xt[12:16], xt[19:23]
        q = quat_multiply(quat_conjugate(qc), qd)
        q = -q if q[3] < 0 else q
        R, Q = quat_to_dcm(qc).T, quat_to_dcm(q).T
        omc = xt[16:19] - R @ PARAMS.omega_t
        om = xt[23:26] - Q @ xt[16:19]
        wd = om + Q @ omc
        rho = R @ (xt[6:9] - xt[0:3]) + Q.T @ PARAMS.P_d - PARAMS.P_c
        rhod = R @ (xt[9:12] - xt[3:6]) - np.cross(omc, rho + PARAMS.P_c) + Q.T @ np.cross(wd, PARAMS.P_d)
        mc, md = PARAMS.mass_chief_kg, PARAMS.mass_deputy_kg
        rn = (mc * xt[0:3] + md * xt[6:9]) / (mc + md)
        rnd = (mc * xt[3:6] + md * xt[9:12]) / (mc + md)
        expect = np.concatenate([rho, rhod, om, q, qc, omc, rn, rnd, ref6])
        np.testing.assert_allclose(relative_from_truth(xt, PARAMS, ref6), expect, rtol=1e-13, atol=1e-15)


def _eq78_relative_state():
    from proxops.dynamics.two_rigid_bodies import HybridInitialState, truth_state_from_initial

    return relative_from_truth(truth_state_from_initial(PARAMS, HybridInitialState()), PARAMS)


@pytest.mark.parametrize("solver", ["daqp", "piqp"])
def test_capture_qp_on_solver_by_name_matches_independent_solve(solver):
    """The capture MPC's QP (Problem 2, eq. 79 weights, face rows, rate rows) on a solver chosen by
    name gives the first control of an independent solve: the QP formed explicitly (scipy ZOH,
    dense G' W G) and solved as a bounded least-squares problem by scipy's BVLS; at the eq. 78
    state (deputy behind the docking face) the rate rows are inactive at that optimum (checked),
    so both solve the same problem."""
    from scipy.optimize import lsq_linear

    from proxops.control.hybrid_mpc import face_pointing_linearized, reduced_capture_state
    from proxops.solvers.front import SOLVERS_FOR

    x = _eq78_relative_state()
    cfg = CaptureMPCConfig(solver=solver)
    mpc = CaptureMPC(PARAMS, cfg)
    cmd = mpc.step(0.0, x)
    assert cmd.status.ok
    assert type(mpc._solver).__name__ == SOLVERS_FOR["QP"][solver][1]
    # independent: eq. 79 weights written out, the QP formed densely, BVLS
    N, dt = mpc.N, cfg.period_s
    far = np.linalg.norm(x[0:3]) > cfg.decouple_beyond_m
    A, B, kappa = mpc.continuous_model(x[13:17], x[17:20], x[9:13], decouple=far)
    W = np.tile(dt * np.repeat([1e2, 1e1, 1e3, 1e3], 3), N)
    W[-12:] = 1e2
    r_blk = np.full(N * 6, dt * 1e4)
    ref = np.zeros((N, 12))
    ref[:, 0:3] = mpc.approach_target(x[0:3])
    face = face_pointing_linearized(np.tile(x[0:3], (N, 1)), mpc.v)
    face[N - 1] = 0.0
    w = math.radians(cfg.rate_max_deg_s)
    H, f, G, free, Ar, bl, bu = _dense_reference(A, B, dt, N, reduced_capture_state(x), W, r_blk, ref.ravel(), face,
                                                 dt * cfg.face_weight, 6, w)
    lb = np.tile(-mpc.u_max - kappa, N)
    ub = np.tile(mpc.u_max - kappa, N)
    L = np.linalg.cholesky(H)  # 1/2 U'HU + f'U = 1/2 |L'U + L^-1 f|^2 + const
    sol = lsq_linear(L.T, -np.linalg.solve(L, f), bounds=(lb, ub), method="bvls", tol=1e-14)
    U = sol.x
    assert np.all(Ar @ U >= bl - 1e-9) and np.all(Ar @ U <= bu + 1e-9)  # rate rows inactive: same problem
    np.testing.assert_allclose(cmd.u, kappa + U[0:6], rtol=0.0, atol=1e-6)
    assert np.all(np.abs(cmd.u) <= mpc.u_max + 1e-9)  # the +-1 N / +-1 N m box (section VII)


def test_post_model_kernel_matches_numpy_model():
    """PostCaptureMPC.continuous_model (numba) against the model written in numpy (eqs. 29, 48, 65)
    at a docked state with a non-zero reference (x_ref off the origin, so kappa^1's force enters)."""
    from proxops.control.hybrid_mpc import PostCaptureMPC, post_capture_steady_inputs
    from proxops.core.quaternion import skew

    mpc = PostCaptureMPC(PARAMS)
    x = np.zeros(32)
    x[9:13] = _unit([0.01, -0.02, 0.005, 1.0])
    x[13:17] = _unit([-0.5, 0.5, 0.5, -0.5])  # scalar < 0: the kinematics take -p
    x[26:32] = [3.0, -2.0, 1.0, 0.01, 0.02, -0.03]
    A, B, kappa = mpc.continuous_model(x)
    k1, k2 = post_capture_steady_inputs(x[26:32], PARAMS)
    A0, B0 = mpc.A.copy(), mpc.B.copy()
    m = PARAMS.mass_total_kg
    if np.any(k1):
        A0[9:12, 0:3] = -2.0 * skew(k1) / m
    p = -x[13:17]
    A0[0:3, 3:6] = 0.5 * (skew(p[0:3]) + p[3] * np.eye(3))
    C_TD = quat_to_dcm(x[13:17]) @ quat_to_dcm(x[9:13])
    B0[9:12, 0:3] = C_TD / m
    np.testing.assert_allclose(A, A0, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(B, B0, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(kappa, np.concatenate([C_TD.T @ k1, k2]), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("decouple", [False, True])
def test_capture_model_kernel_matches_casadi_and_numpy(decouple):
    """CaptureMPC.continuous_model (one numba call replaying the tape) against CasADi's own
    evaluation of the linearisation followed by the numpy formulas of eqs. 22 and 27 at the
    measured q (scalar part < 0: the kinematics take -q), with and without the decoupling."""
    from proxops.core.quaternion import skew

    mpc = CaptureMPC(PARAMS)
    lin = mpc.linearization
    for _ in range(5):
        p, wc = _unit(RNG.standard_normal(4)), 0.05 * RNG.standard_normal(3)
        q = _unit(RNG.standard_normal(4))
        q[3] = -abs(q[3])
        A, B, kappa = mpc.continuous_model(p, wc, q, decouple)
        out = np.asarray(lin._fun(p, wc)).ravel()
        A0 = out[:144].reshape(12, 12, order="F")
        B0 = out[144:216].reshape(12, 6, order="F")
        k0 = out[216:222].copy()
        if decouple:
            A0[0:6, 6:12] = 0.0
        Qt = quat_to_dcm(q)  # C_{C<-D} = Q^T (q: D relative to C)
        B0[3:6, 0:3] = Qt / PARAMS.mass_deputy_kg
        k0[0:3] = Qt.T @ k0[0:3]
        qq = -q
        A0[9:12, 6:9] = 0.5 * (skew(qq[0:3]) + qq[3] * np.eye(3))
        np.testing.assert_allclose(A, A0, rtol=1e-14, atol=1e-300)
        np.testing.assert_allclose(B, B0, rtol=1e-14, atol=1e-300)
        np.testing.assert_allclose(kappa, k0, rtol=1e-14, atol=1e-16)


def test_box_bounds_shifted_face_rows_and_penalty_match_numpy():
    """The capture MPC's small kernels against their numpy forms: the input box (np.tile of
    -u_max - kappa, u_max - kappa), the face rows at the last plan shifted by one step
    (face_pointing_linearized, terminal row 0) or at the measured rho without a plan, and the
    summed eq. 66 penalty of a plan (face_pointing_penalty over stages 0..N-2)."""
    from proxops.control.hybrid_kernels import box_bounds, face_penalty_sum, shifted_face_rows
    from proxops.control.hybrid_mpc import face_pointing_linearized, face_pointing_penalty

    N, n = 10, 12
    u_max, kappa = np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0]), RNG.standard_normal(6)
    lb, ub = box_bounds(u_max, kappa, N)
    np.testing.assert_array_equal(lb, np.tile(-u_max - kappa, N))
    np.testing.assert_array_equal(ub, np.tile(u_max - kappa, N))
    v = _unit([0.1, 1.0, -0.2])
    plan, rho0 = RNG.standard_normal((N, 3)), RNG.standard_normal(3)
    plan[4] = 0.0  # |rho_bar| = 0: zero row
    ref = face_pointing_linearized(np.vstack([plan[1:], plan[-1:]]), v)
    ref[N - 1] = 0.0
    np.testing.assert_allclose(shifted_face_rows(plan, rho0, True, v, N), ref, rtol=1e-15, atol=0.0)
    ref0 = face_pointing_linearized(np.tile(rho0, (N, 1)), v)
    ref0[N - 1] = 0.0
    np.testing.assert_allclose(shifted_face_rows(plan, rho0, False, v, N), ref0, rtol=1e-15, atol=0.0)
    X = RNG.standard_normal(N * n)
    rho = X.reshape(N, n)[:, 0:3]
    assert face_penalty_sum(X, n, N, v, 100.0) == pytest.approx(face_pointing_penalty(rho[:-1], v, 100.0).sum(),
                                                                 rel=1e-13)
