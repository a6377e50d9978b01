"""Eq.-(11) MPC in the target body frame (tumbling-target-reachability.md §6).

Independent references: the QP is rebuilt here from scratch with step-by-step exact
Jacobians (BodyFrameModel.step_matrices) and solved by a different solver (PIQP,
interior point); feasibility of the returned plan is checked on the exact prediction;
soft = hard when feasible (exact-penalty theorem)."""

import numpy as np
import pytest

from proxops.constraints.los_corridor import LosCorridor
from proxops.control.los_mpc import LosMpc, LosMpcConfig
from proxops.core.constants import MU_EARTH
from proxops.dynamics.tumbling_target import BodyFrameModel, rot_z
from proxops.errors import ProxopsInputError
from proxops.solvers import PiqpQP

N_MEAN = np.sqrt(MU_EARTH / (6378137.0 + 500e3) ** 3)


def _model(w_deg=2.0, theta0=0.2):
    return BodyFrameModel(N_MEAN, np.radians(w_deg), 1.0, theta0)


def _rollout_matrices(model, t, N):
    """x_1..x_N = F x_0 + Gam U from the exact one-step Jacobians (body-axes inputs)."""
    F = np.zeros((6 * N, 6))
    Gam = np.zeros((6 * N, 3 * N))
    A_acc = np.eye(6)
    blocks = []
    for j in range(N):
        A, B = model.step_matrices(t + j)
        Bb = B @ rot_z(float(model.theta(t + j)))  # u_L = R_LB(theta_j) u_B
        A_acc = A @ A_acc
        blocks = [A @ b for b in blocks] + [Bb]
        F[6 * j : 6 * j + 6] = A_acc
        for i, b in enumerate(blocks):
            Gam[6 * j : 6 * j + 6, 3 * i : 3 * i + 3] = b
    return F, Gam


def _reference_qp(model, corridor, cfg, a_max, t, x0, ref, u_prev):
    N = cfg.horizon
    F, Gam = _rollout_matrices(model, t, N)
    W = np.tile(np.asarray(cfg.Q, float), N)
    W[-6:] *= cfg.terminal_factor
    D = np.eye(3 * N) - np.eye(3 * N, k=-3)
    rd = np.tile(cfg.R_du, N)
    P = 2 * (Gam.T @ (W[:, None] * Gam) + np.diag(np.tile(cfg.R_u, N)) + D.T @ (rd[:, None] * D))
    e = F @ x0 - np.tile(ref, N)
    c = 2 * (Gam.T @ (W * e))
    c[:3] -= 2 * np.asarray(cfg.R_du) * u_prev
    Gp = np.zeros((9 * N, 3 * N))
    hp = np.zeros(9 * N)
    for j in range(N):
        Gp[9 * j : 9 * j + 9] = corridor.G @ Gam[6 * j : 6 * j + 3]
        hp[9 * j : 9 * j + 9] = corridor.h - corridor.G @ (F[6 * j : 6 * j + 3] @ x0)
    qp = PiqpQP(eps_abs=1e-10, eps_rel=1e-10)
    qp.setup_native(P, c, G=Gp, h_l=np.full(9 * N, -np.inf), h_u=hp, x_lb=np.full(3 * N, -a_max), x_ub=np.full(3 * N, a_max))
    res = qp.solve()
    assert res.ok
    return res.x, F, Gam


@pytest.mark.parametrize("make_cfg", [LosMpcConfig.monte_carlo, LosMpcConfig.single_run])
@pytest.mark.parametrize("refinements", [0, 2])
def test_matches_independent_qp_and_plan_is_feasible(make_cfg, refinements):
    model, corridor, a_max = _model(), LosCorridor(), 0.05
    cfg = make_cfg(refinements=refinements)
    mpc = LosMpc(model, corridor, a_max, cfg)
    x0 = np.array([12.0, 60.0, -3.0, 0.3, -0.4, 0.05])  # moving towards the face: constraints bind
    ref = np.array([0.0, 10.0, 0.0, 0.0, 0.0, 0.0])
    u_prev = np.array([0.01, -0.02, 0.0])
    t = 37.0
    sol = mpc.solve(t, x0, ref, u_prev)
    assert sol.status == "optimal"
    U_ref, F, Gam = _reference_qp(model, corridor, cfg, a_max, t, x0, ref, u_prev)
    # Same optimum up to the rotation-averaged input map acting on the change of plan
    # (first call: plan guess = u_prev): far-horizon inputs within 2 % of a_max, u_0 within
    # 0.05 %. Re-centring on its own plan (refinements) makes the prediction and the
    # constraint values exact at the returned plan; the remaining gap is the averaged
    # gradient (anisotropy ~1e-3), i.e. a feasible, 1e-3-suboptimal plan.
    tol_plan, tol_u0 = (2e-2 * a_max, 5e-4 * a_max) if refinements == 0 else (2e-3 * a_max, 2e-4 * a_max)
    np.testing.assert_allclose(sol.inputs.ravel(), U_ref, atol=tol_plan)
    np.testing.assert_allclose(sol.u0, U_ref[:3], atol=tol_u0)
    # feasibility of the returned plan on the *exact* prediction, not the solver status
    X = (F @ x0 + Gam @ sol.inputs.ravel()).reshape(-1, 6)
    assert np.all(np.abs(sol.inputs) <= a_max + 1e-9)
    assert corridor.violation_body(X[:, :3]).max() < (1e-4 if refinements == 0 else 1e-9)
    np.testing.assert_allclose(mpc.exact_prediction(t, x0, sol.inputs), X, atol=1e-9)
    # the LVLH command is the body command rotated by R_LB(theta_k)
    np.testing.assert_allclose(sol.u0_hill, rot_z(float(model.theta(t))) @ sol.u0, atol=1e-15)


def test_soft_equals_hard_when_feasible_exact_penalty():
    model, corridor = _model(3.0), LosCorridor()
    x0 = np.array([-8.0, 40.0, 2.0, -0.5, -0.2, 0.0])
    ref = np.array([0.0, 10.0, 0.0, 0.0, 0.0, 0.0])
    hard = LosMpc(model, corridor, 0.1, LosMpcConfig.single_run())
    soft = LosMpc(model, corridor, 0.1, LosMpcConfig.single_run(constraint_mode="soft"))
    for k in range(5):
        a = hard.solve(float(k), x0, ref)
        b = soft.solve(float(k), x0, ref)
        assert a.ok and b.ok
        assert b.max_slack_m < 1e-9
        np.testing.assert_allclose(b.inputs, a.inputs, atol=1e-7)
        x0 = model.step(float(k), x0, a.u0_hill)


def test_infeasible_start_is_a_status_not_an_exception():
    """Co-rotating start at 3 r_sync (w = 5 deg/s, a = 0.02: r_sync = 5.3 m): the
    centripetal demand w^2 r = 0.12 m/s^2 >> a_max, the corridor cannot be held."""
    model, corridor = _model(5.0), LosCorridor()
    x0 = np.array([0.0, 16.0, 0.0, 0.0, 0.0, 0.0])
    ref = np.array([0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    hard = LosMpc(model, corridor, 0.02, LosMpcConfig.single_run())
    sol = hard.solve(0.0, x0, ref)
    assert sol.status == "infeasible" and not sol.ok
    assert sol.u0.shape == (3,) and np.all(np.isfinite(sol.u0))
    soft = LosMpc(model, corridor, 0.02, LosMpcConfig.single_run(constraint_mode="soft"))
    sol = soft.solve(0.0, x0, ref)
    assert sol.ok and sol.max_slack_m > 1e-3
    assert np.all(np.abs(sol.inputs) <= 0.02 + 1e-9)


def test_paper_configurations():
    single, mc = LosMpcConfig.single_run(), LosMpcConfig.monte_carlo()
    assert (single.horizon, single.R_du) == (40, (1e4, 1e4, 1e4))  # §6
    assert (mc.horizon, mc.R_du) == (20, (1e5, 1e4, 1e5))
    for c in (single, mc):
        assert c.Q == (15.0, 30.0, 15.0, 1.0, 1.0, 1.0) and c.terminal_factor == 30.0 and c.R_u == (1e-2,) * 3
    with pytest.raises(ProxopsInputError):
        LosMpc(_model(), LosCorridor(), 0.1, LosMpcConfig(constraint_mode="sometimes"))
    with pytest.raises(ProxopsInputError):
        LosMpc(_model(), LosCorridor(), -0.1)


@pytest.mark.parametrize("w_deg,make_cfg", [(2.0, LosMpcConfig.monte_carlo), (5.0, LosMpcConfig.single_run)])
def test_fast_prediction_equals_exact_rollout(w_deg, make_cfg):
    """The per-step prediction of the plan (the kernel's LVLH recursion, module doc) against the
    step-by-step product of exact one-step Jacobians, at several angles/times."""
    model = _model(w_deg)
    mpc = LosMpc(model, LosCorridor(), 0.1, make_cfg())
    N = mpc.N
    rng = np.random.default_rng(3)
    for t in (0.0, 13.0, 371.0):
        x0 = rng.normal(size=6) * [30.0, 100.0, 5.0, 0.3, 0.3, 0.1]
        plan = rng.uniform(-0.1, 0.1, size=(N, 3))
        F, Gam = _rollout_matrices(model, t, N)
        exact = F @ x0 + Gam @ plan.ravel()
        basis = mpc._load(float(model.theta(t)), x0, np.zeros((N, 6)), np.zeros(3), plan.ravel(), 2)
        np.testing.assert_allclose(basis[: 3 * N], plan.ravel(), rtol=0, atol=0)  # g = the plan as given
        np.testing.assert_allclose(basis[3 * N :], exact, rtol=0, atol=1e-9)


@pytest.mark.parametrize("mode", ["hard", "soft"])
def test_shifted_qp_equals_the_qp_with_its_linear_term(mode):
    """DAQP is given the QP in w = U - U_c without a linear term (module doc). The same QP
    written the direct way - H and the linear term f = H g + S'W (p_g - r) - ..., built here
    from the exact rollout matrices and the MPC's H - and solved by DAQP with f gives the same
    plan: the shift changes rounding only."""
    from proxops.solvers import DaqpQP

    model, corridor, a_max = _model(), LosCorridor(), 0.05
    cfg = LosMpcConfig.single_run(constraint_mode=mode)
    mpc = LosMpc(model, corridor, a_max, cfg)
    N, nu = mpc.N, mpc.n_u
    x0 = np.array([12.0, 60.0, -3.0, 0.3, -0.4, 0.05])
    ref = np.array([0.0, 10.0, 0.0, 0.0, 0.0, 0.0])
    u_prev = np.array([0.01, -0.02, 0.0])
    t = 37.0
    sol = mpc.solve(t, x0, ref, u_prev)
    assert sol.ok
    g = np.tile(u_prev, N)  # first call: the plan guess is u_prev held
    F, Gam = _rollout_matrices(model, t, N)
    p_g = F @ x0 + Gam @ g
    S = mpc._S_flat
    W = np.tile(np.asarray(cfg.Q, float), N)
    W[-6:] *= cfg.terminal_factor
    D = np.eye(nu) - np.eye(nu, k=-3)
    rd = np.tile(cfg.R_du, N)
    H = S.T @ (W[:, None] * S) + np.diag(np.tile(cfg.R_u, N)) + D.T @ (rd[:, None] * D)
    f = S.T @ (W * (p_g - np.tile(ref, N))) + (H - S.T @ (W[:, None] * S)) @ g  # in dU = U - g
    f[:3] -= np.asarray(cfg.R_du) * u_prev
    rows = np.vstack([corridor.G @ S[6 * j : 6 * j + 3] for j in range(N)])
    h_rows = np.concatenate([corridor.h - corridor.G @ p_g[6 * j : 6 * j + 3] for j in range(N)])
    lb, ub = -a_max - g, a_max - g
    if mode == "soft":
        Hs = np.zeros((nu + N, nu + N))
        Hs[:nu, :nu], Hs[nu:, nu:] = H, np.eye(N) * cfg.slack_quadratic
        rows = np.hstack([rows, -np.kron(np.eye(N), np.ones((corridor.G.shape[0], 1)))])
        H, f = Hs, np.concatenate([f, np.full(N, cfg.slack_penalty)])
        lb, ub = np.concatenate([lb, np.zeros(N)]), np.concatenate([ub, np.full(N, np.inf)])
    qp = DaqpQP()
    qp.setup_native(H, f, rows, None, h_rows, lb, ub)
    res = qp.solve()
    assert res.ok
    np.testing.assert_allclose(sol.inputs.ravel(), res.x[:nu] + g, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sol.states, (p_g + S @ res.x[:nu]).reshape(N, 6), rtol=0, atol=1e-9)


def test_nan_state_is_a_status_and_the_next_step_recovers():
    """A NaN body state (e.g. a diverged navigation filter) gives status numerical_error and a
    finite fallback input, not an exception; the next finite state solves normally."""
    mpc = LosMpc(_model(), LosCorridor(), 0.1, LosMpcConfig.single_run())
    x0 = np.array([1.0, 100.0, 2.0, 0.0, 0.0, 0.0])
    ref = np.array([0.0, 10.0, 0.0, 0.0, 0.0, 0.0])
    assert mpc.solve(0.0, x0, ref).ok
    bad = mpc.solve(1.0, np.array([np.nan, 100.0, 2.0, 0.0, 0.0, 0.0]), ref)
    assert bad.status == "numerical_error" and not bad.ok
    assert np.all(np.isfinite(bad.u0)) and np.all(np.abs(bad.u0) <= 0.1)
    assert mpc.solve(2.0, x0, ref).ok


def _direct_qp(mpc, t, x0, ref, u_prev, g):
    """The MPC's QP in dU = U - g written the direct way (exact rollout matrices for p_g, the MPC's
    averaged S and the weights of its config), with its linear term: an independent build of the
    QuadraticProgram the MPC hands its solver (which is shifted to w = U - U_c in hard mode)."""
    from proxops.solvers import QuadraticProgram

    cfg, corridor, N, nu = mpc.cfg, mpc.corridor, mpc.N, mpc.n_u
    F, Gam = _rollout_matrices(mpc.model, t, N)
    p_g = F @ x0 + Gam @ g
    S = mpc._S_flat
    W = np.tile(np.asarray(cfg.Q, float), N)
    W[-6:] *= cfg.terminal_factor
    D = np.eye(nu) - np.eye(nu, k=-3)
    rd = np.tile(cfg.R_du, N)
    R = np.diag(np.tile(cfg.R_u, N)) + D.T @ (rd[:, None] * D)
    H = S.T @ (W[:, None] * S) + R
    f = S.T @ (W * (p_g - np.tile(ref, N))) + R @ g
    f[:3] -= np.asarray(cfg.R_du) * u_prev
    rows = np.vstack([corridor.G @ S[6 * j : 6 * j + 3] for j in range(N)])
    h_rows = np.concatenate([corridor.h - corridor.G @ p_g[6 * j : 6 * j + 3] for j in range(N)])
    return QuadraticProgram(P=H, q=f, A=rows, bu=h_rows, lb=-mpc.a_max - g, ub=mpc.a_max - g)


@pytest.mark.parametrize("mode", ["hard", "soft"])
def test_solver_by_name_daqp_and_piqp_agree_with_an_independent_clarabel_solve(mode):
    """The same MPC on two QP solvers chosen by name (DAQP: active set, warm-started; PIQP: interior
    point), three closed-loop steps from a state that drives the plan onto the corridor faces: the
    first controls agree with each other and with Clarabel solving the independently built QP of the
    first step; the corridor binds (some predicted row within 1e-6 m of its face)."""
    from proxops.solvers import solve_qp

    model, corridor, a_max = _model(), LosCorridor(), 0.05
    x_start = np.array([12.0, 60.0, -3.0, 0.3, -0.4, 0.05])
    ref = np.array([0.0, 10.0, 0.0, 0.0, 0.0, 0.0])
    u_start = np.array([0.01, -0.02, 0.0])
    t0 = 37.0
    controls = {}
    for name, settings in (("daqp", {}), ("piqp", {"eps_abs": 1e-11, "eps_rel": 1e-11})):
        mpc = LosMpc(model, corridor, a_max, LosMpcConfig.single_run(constraint_mode=mode, solver=name,
                                                                     solver_settings=settings))
        x, u_prev, us = x_start.copy(), u_start.copy(), []
        for k in range(3):
            sol = mpc.solve(t0 + k, x, ref, u_prev)
            assert sol.ok, (name, k, sol.status)
            assert sol.max_slack_m < 1e-6
            if k == 0:
                X = sol.states
                assert corridor.slack_body(X[:, :3]).min() < 1e-6  # a face is active: the test binds
            us.append(sol.u0)
            u_prev = sol.u0
            x = model.step(t0 + k, x, sol.u0_hill)
        controls[name] = np.array(us)
    np.testing.assert_allclose(controls["piqp"], controls["daqp"], rtol=0, atol=1e-8 * a_max)
    qp = _direct_qp(mpc, t0, x_start, ref, u_start, np.tile(u_start, mpc.N))  # first call: g = u_prev held
    res = solve_qp(qp, "clarabel", tol_gap_rel=1e-12, tol_feas=1e-12)
    assert res.ok
    np.testing.assert_allclose(controls["daqp"][0], res.x[:3] + u_start, rtol=0, atol=1e-8 * a_max)
    np.testing.assert_allclose(controls["piqp"][0], res.x[:3] + u_start, rtol=0, atol=1e-8 * a_max)


def test_unknown_solver_name_is_an_input_error():
    with pytest.raises(ProxopsInputError, match="mpc.solver"):
        LosMpc(_model(), LosCorridor(), 0.1, LosMpcConfig(solver="osqp"))


@pytest.mark.parametrize("N", [20, 160])
def test_averaged_input_map_is_block_toeplitz(N):
    """The kernel uses S's N blocks K_d = S[d, :, 0:3] for every block (j, i) with j - i = d (the
    16-angle average is exact for the harmonics <= 2 of the rotated CW map, so it does not depend on
    the common shift of the angles); blocks above the diagonal are zero (causality)."""
    mpc = LosMpc(_model(5.0), LosCorridor(), 0.1, LosMpcConfig(horizon=N))
    S = mpc._S
    scale = np.abs(S).max(axis=(0, 2))  # per state component
    blocks = S.reshape(N, 6, N, 3).transpose(0, 2, 1, 3)  # [j, i] = block (j, i), (6, 3)
    lag = np.arange(N)[:, None] - np.arange(N)[None, :]  # j - i
    expected = np.where((lag >= 0)[:, :, None, None], S[:, :, 0:3][np.clip(lag, 0, None)], 0.0)
    assert np.all(np.abs(blocks - expected) <= 1e-13 * scale[None, None, :, None])


def test_kernel_writes_the_shifted_bounds_into_daqps_vectors():
    """Hard mode on DAQP: from the second solve on, the kernel writes the bounds of the QP in w = U - U_c straight
    into the vectors DAQP reads (DaqpQP.bound_vectors). They equal a plain numpy build from the direct QP
    (_direct_qp: exact rollout, H and f): U_c = g - H^-1 f, lb = -a_max - U_c, ub = a_max - U_c, corridor rows
    h - G p_g - G S (U_c - g); the row lower bounds stay DAQP's -1e30."""
    model, a_max = _model(), 0.05
    mpc = LosMpc(model, LosCorridor(), a_max, LosMpcConfig.single_run())
    N, nu = mpc.N, mpc.n_u
    x0 = np.array([12.0, 60.0, -3.0, 0.3, -0.4, 0.05])
    ref = np.array([0.0, 10.0, 0.0, 0.0, 0.0, 0.0])
    u_prev = np.array([0.01, -0.02, 0.0])
    first = mpc.solve(36.0, x0, ref, u_prev)
    assert first.ok
    x1 = np.array([11.0, 59.5, -2.9, 0.25, -0.35, 0.04])
    second = mpc.solve(37.0, x1, ref, first.u0)
    assert second.ok and mpc._lean
    plan = first.inputs.ravel()
    g = np.concatenate([plan[3:], plan[-3:]])  # the previous plan shifted by one step, its last input held
    qp = _direct_qp(mpc, 37.0, x1, ref, first.u0, g)
    U_c = g - np.linalg.solve(qp.P, qp.q)
    upper, lower = mpc._solver.bound_vectors()
    scale = np.abs(qp.bu).max()
    np.testing.assert_allclose(upper[:nu], a_max - U_c, rtol=0, atol=1e-9)
    np.testing.assert_allclose(lower[:nu], -a_max - U_c, rtol=0, atol=1e-9)
    np.testing.assert_allclose(upper[nu:], qp.bu - qp.A @ (U_c - g), rtol=0, atol=1e-9 * scale)
    assert np.all(lower[nu:] == -1e30)
    np.testing.assert_allclose(second.inputs.ravel()[:3], second.u0, rtol=0, atol=0)
