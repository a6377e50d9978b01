"""Solver adapters against problems whose optimum is known in closed form.

Every optimum asserted here is derived in a comment (projection formulas, LP
vertices, least-norm solutions, Cauchy-Schwarz for second-order cones) or computed
independently with numpy linear algebra; every returned x is checked for primal
feasibility, not only its status.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxops.errors import ProxopsInputError
from proxops.solvers import (
    ClarabelSOCP,
    DaqpQP,
    HighsLP,
    PiqpQP,
    QuadraticProgram,
    SolveStatus,
    build_conic_problem,
    check_conic_feasibility,
    check_feasibility,
    conic_from_qp,
    max_violation,
    solve_qp,
)

FEAS_TOL = 1e-7  # absolute, in the units of the rows (all O(1) here)
QP_SOLVERS = ("daqp", "piqp", "clarabel")


# --------------------------------------------------------------------------- problems
# P1 (QP): min 1/2||x - p||^2  s.t.  x1 + x2 <= beta  (box |x_i| <= 5 inactive).
# In QP form H = I, f = -p; objective = 1/2||x||^2 - p'x.  If a'p > beta the optimum is
# the projection onto the half-space: x* = p - (a'p - beta)/||a||^2 a.
# p = (2, 1), beta = 1: x* = (2,1) - (2/2)(1,1) = (1, 0); f* = 1/2 - 2 = -1.5.
def projection_halfspace(p, a, beta):
    p, a = np.asarray(p, float), np.asarray(a, float)
    excess = a @ p - beta
    x = p - max(excess, 0.0) / (a @ a) * a
    return x, 0.5 * x @ x - p @ x


# P1' (after update): p = (3, 0) and ub x1 <= 1.5. Guess x1 = 1.5 (bound active) and
# x1 + x2 = 1 active -> x = (1.5, -0.5). KKT: x - p + lam*(1,1) + mu*(1,0) = 0 gives
# lam = 0 - (-0.5) = 0.5 >= 0 and mu = 3 - 1.5 - 0.5 = 1 >= 0, so it is optimal.
# f* = 1/2 (2.25 + 0.25) - 3*1.5 = -3.25.
P1_UPDATED_X = np.array([1.5, -0.5])
P1_UPDATED_F = -3.25

# P2 (LP): min x1 + 2 x2  s.t.  x1 + x2 >= 1, 0 <= x <= 5. Every feasible point has
# x1 + 2x2 >= x1 + x2 >= 1 with equality only at x2 = 0, x1 = 1: x* = (1, 0), f* = 1.
# With costs (2, 1) the same argument gives x* = (0, 1), f* = 1.


def assert_feasible(A, bl, bu, x, lb=None, ub=None, tol=FEAS_TOL):
    report = check_feasibility(A, bl, bu, x, tol, lb=lb, ub=ub)
    assert report.feasible, f"infeasible: max violation {report.max_violation} at {report.worst_index}"


# --------------------------------------------------------------------------- result type
def test_status_ok_property():
    assert SolveStatus.OPTIMAL.ok and SolveStatus.OPTIMAL_INACCURATE.ok
    for status in (SolveStatus.INFEASIBLE, SolveStatus.UNBOUNDED, SolveStatus.MAX_ITER,
                   SolveStatus.TIME_LIMIT, SolveStatus.NUMERICAL_ERROR):
        assert not status.ok
    assert str(SolveStatus.OPTIMAL) == "optimal"


def test_check_feasibility_hand_values():
    # A x = (1*1 + 2*1, 1 - 1) = (3, 0) for x = (1, 1); rows 2 <= 3 <= 2.5 is violated by 0.5,
    # 0 <= 0 <= inf holds; bound x2 <= 0.8 is violated by 0.2.
    A = np.array([[1.0, 2.0], [1.0, -1.0]])
    rep = check_feasibility(A, [2.0, 0.0], [2.5, np.inf], [1.0, 1.0], 1e-9, lb=[-np.inf, 0.0], ub=[2.0, 0.8])
    assert not rep.feasible and rep.max_violation == pytest.approx(0.5) and rep.worst_index == 0
    assert max_violation(None, None, None, [1.0, 1.0], lb=[0, 0], ub=[2.0, 0.8]) == pytest.approx(0.2)
    assert check_feasibility(A, [2.0, 0.0], [3.0, 0.0], [1.0, 1.0], 1e-12).feasible
    assert not check_feasibility(A, None, [10, 10], [np.nan, 0.0]).feasible
    assert not check_feasibility(A, None, None, None).feasible


def test_check_conic_feasibility_hand_values():
    # s = b - A x with A = 0: s = b. soc (3, 4, 0): ||(4, 0)|| - 3 = 1 violation; nonneg -2: 2.
    A = np.zeros((4, 1))
    rep = check_conic_feasibility(A, [-2.0, 3.0, 4.0, 0.0], [("nonneg", 1), ("soc", 3)], [0.0])
    assert rep.max_violation == pytest.approx(2.0) and rep.worst_index == 0
    rep = check_conic_feasibility(A, [0.0, 5.0, 4.0, 3.0], [("zero", 1), ("soc", 3)], [0.0], tol=1e-12)
    assert rep.feasible  # 5 >= ||(4, 3)|| = 5


# --------------------------------------------------------------------------- DAQP
def test_daqp_qp_projection_and_warm_started_update():
    A, bu = np.array([[1.0, 1.0]]), np.array([1.0])
    lb, ub = -5 * np.ones(2), 5 * np.ones(2)
    s = DaqpQP()
    s.setup_native(np.eye(2), -np.array([2.0, 1.0]), A, None, bu, lb, ub)
    r = s.solve()
    x_ref, f_ref = projection_halfspace([2, 1], [1, 1], 1.0)
    assert r.status is SolveStatus.OPTIMAL and r.ok and r.solver == "daqp"
    np.testing.assert_allclose(r.x, x_ref, atol=1e-9)
    assert r.objective == pytest.approx(f_ref, abs=1e-9)
    assert_feasible(A, None, bu, r.x, lb, ub)
    # Same data again: the kept working set is already optimal (at most one iteration).
    assert s.solve().iterations <= 1
    # Update cost and a bound in place: new closed-form optimum P1'.
    s.update(f=-np.array([3.0, 0.0]), ub=np.array([1.5, 5.0]))
    r = s.solve()
    np.testing.assert_allclose(r.x, P1_UPDATED_X, atol=1e-9)
    assert r.objective == pytest.approx(P1_UPDATED_F, abs=1e-9)
    assert_feasible(A, None, bu, r.x, lb, [1.5, 5.0])


def test_daqp_update_fast_matches_validated_update():
    # Projection of p onto {x1 + x2 <= b}: closed form p - max(0, a'p - b) / |a|^2 a, for a
    # sequence of (p, b) written through the lean path; also after a validated update.
    A = np.array([[1.0, 1.0]])
    s = DaqpQP()
    s.setup_native(np.eye(2), -np.array([2.0, 1.0]), A, None, [1.0], -5 * np.ones(2), 5 * np.ones(2))
    s.solve()
    for p, b in (([2.0, 1.0], 0.5), ([0.2, -0.1], 1.0), ([3.0, -1.0], -1.0)):
        s.update_fast(f=-np.array(p), bu=np.array([b]))
        r = s.solve()
        np.testing.assert_allclose(r.x, projection_halfspace(p, [1, 1], b)[0], atol=1e-9)
        assert_feasible(A, None, [b], r.x, -5 * np.ones(2), 5 * np.ones(2))
    s.update(ub=[0.5, 5.0])  # validated path in between keeps the bookkeeping consistent
    s.update_fast(bu=np.array([10.0]))
    np.testing.assert_allclose(s.solve().x, [0.5, -1.0], atol=1e-9)  # p = (3, -1) clipped by x1 <= 0.5 only


def test_daqp_update_fast_hessian_and_rows_closed_form():
    # The lean path also takes H and A (hybrid MPCs: a new condensed Hessian every step).
    # min 1/2 x'Hx + f'x, H = diag(2, 8), f = (-4, -8): unconstrained x = (2, 1). With the row
    # x1 + x2 <= 1 active, KKT: 2 x1 - 4 + l = 0, 8 x2 - 8 + l = 0, x1 + x2 = 1 -> l = 3.2,
    # x = (0.4, 0.6). Then the row x1 <= 0 (A changed): x = (0, 1).
    lb, ub = -5 * np.ones(2), 5 * np.ones(2)
    s = DaqpQP()
    s.setup_native(np.eye(2), np.zeros(2), np.array([[1.0, 1.0]]), [-10.0], [10.0], lb, ub)
    assert s.solve().ok
    s.update_fast(H=np.diag([2.0, 8.0]), f=np.array([-4.0, -8.0]), A=np.array([[1.0, 1.0]]),
                  bl=np.array([-10.0]), bu=np.array([1.0]))
    r = s.solve()
    assert r.ok
    np.testing.assert_allclose(r.x, [0.4, 0.6], atol=1e-12)
    s.update_fast(A=np.array([[1.0, 0.0]]), bu=np.array([0.0]))
    r = s.solve()
    np.testing.assert_allclose(r.x, [0.0, 1.0], atol=1e-12)
    # a crossing of less than DAQP's primal tolerance seen by the checked update is reported as
    # INFEASIBLE; the lean path must then re-check (not keep that verdict once the bounds are valid)
    s.update(bl=[1e-9], bu=[0.0])
    assert s.solve().status is SolveStatus.INFEASIBLE
    s.update_fast(bl=np.array([-10.0]), bu=np.array([0.0]))
    np.testing.assert_allclose(s.solve().x, [0.0, 1.0], atol=1e-12)


def test_daqp_without_linear_term_shifted_variable():
    # f=None: min 1/2 |w|^2 with the variable shifted to the unconstrained minimiser p
    # (x = p + w): rows b - a'p, bounds lb - p, ub - p, written by update_fast. x = p + w must
    # be the closed-form projection of p onto {x1 + x2 <= b} (inside the box), as with f = -p.
    a, lb, ub = np.array([1.0, 1.0]), -5 * np.ones(2), 5 * np.ones(2)
    s = DaqpQP()
    s.setup_native(np.eye(2), None, a[None, :], None, [1.0], lb, ub)
    for p, b in (([2.0, 1.0], 0.5), ([0.2, -0.1], 1.0), ([3.0, -1.0], -1.0), ([4.0, 4.0], 1.0)):
        p = np.array(p)
        s.update_fast(bu=np.array([b - a @ p]), lb=lb - p, ub=ub - p)
        r = s.solve()
        assert r.ok
        np.testing.assert_allclose(p + r.x, projection_halfspace(p, a, b)[0], atol=1e-12)
    with pytest.raises(ProxopsInputError, match="linear term"):
        s.update(f=np.zeros(2))
    # crossed bounds through the lean path: DAQP's own check makes the solve INFEASIBLE, and the
    # next (valid) update recovers
    s.update_fast(lb=np.array([1.0, -5.0]), ub=np.array([0.0, 5.0]))
    assert s.solve().status is SolveStatus.INFEASIBLE
    s.update_fast(bu=np.array([1.0]), lb=lb, ub=ub)
    r = s.solve()
    assert r.ok
    np.testing.assert_allclose(r.x, [0.0, 0.0], atol=1e-12)  # p = 0 is feasible: w = 0


def test_daqp_small_perturbation_keeps_active_set():
    # p = (2 + e, 1 - e): a'p = 3 > 1 so the half-space row stays the only active row;
    # the warm-started solve needs no new active-set change (<= 1 iteration).
    s = DaqpQP()
    s.setup_native(np.eye(2), -np.array([2.0, 1.0]), np.array([[1.0, 1.0]]), None, [1.0])
    s.solve()
    p = np.array([2.0 + 1e-3, 1.0 - 2e-3])
    s.update(f=-p)
    r = s.solve()
    np.testing.assert_allclose(r.x, projection_halfspace(p, [1, 1], 1.0)[0], atol=1e-9)
    assert r.iterations <= 1


def test_daqp_lp_vertex_and_equality_least_norm():
    s = DaqpQP()
    s.setup_native(np.zeros((2, 2)), [1.0, 2.0], [[1.0, 1.0]], [1.0], None, [0, 0], [5, 5])
    r = s.solve()
    assert r.status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(r.x, [1.0, 0.0], atol=1e-8)
    assert r.objective == pytest.approx(1.0, abs=1e-8)
    # min 1/2||x||^2 s.t. a'x = 3, a = (1,1,1): least-norm x = 3 a/||a||^2 = (1,1,1), f = 1.5.
    s = DaqpQP()
    s.setup_native(np.eye(3), np.zeros(3), np.ones((1, 3)), [3.0], [3.0])
    r = s.solve()
    np.testing.assert_allclose(r.x, [1, 1, 1], atol=1e-10)
    assert r.objective == pytest.approx(1.5)
    assert_feasible(np.ones((1, 3)), [3.0], [3.0], r.x)


def test_daqp_infeasible_unbounded_and_recovery():
    # x >= 0 and x1 + x2 <= -1 cannot hold together.
    s = DaqpQP()
    s.setup_native(np.eye(2), np.zeros(2), [[1.0, 1.0]], None, [-1.0], [0, 0], None)
    r = s.solve()
    assert r.status is SolveStatus.INFEASIBLE and r.x is None and math.isnan(r.objective)
    # Crossed bounds during a run are a status too, and a later update recovers.
    s.update(lb=[2.0, 0.0], ub=[1.0, 1.0], bu=[10.0])
    assert s.solve().status is SolveStatus.INFEASIBLE
    s.update(lb=[0.0, 0.0])
    r = s.solve()
    assert r.status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(r.x, [0, 0], atol=1e-12)
    # LP min -x1 with x1 free above: unbounded.
    s = DaqpQP()
    s.setup_native(np.zeros((2, 2)), [-1.0, 0.0], [[1.0, 1.0]], [1.0], None, [0, 0], [np.inf, 5])
    assert s.solve().status is SolveStatus.UNBOUNDED


def test_daqp_failures_are_statuses():
    rng = np.random.default_rng(0)
    M = rng.standard_normal((30, 30))
    H, f = M @ M.T + np.eye(30), 10 * rng.standard_normal(30)
    s = DaqpQP(max_iter=2)
    s.setup_native(H, f, lb=-np.ones(30), ub=np.ones(30))
    assert s.solve().status is SolveStatus.MAX_ITER
    s = DaqpQP()
    s.setup_native(-np.eye(2), np.zeros(2), lb=[-1, -1], ub=[1, 1])  # concave: refused
    assert s.solve().status is SolveStatus.NUMERICAL_ERROR
    s = DaqpQP()
    s.setup_native(np.eye(2), np.zeros(2))
    s.update(f=[np.nan, 0.0])
    r = s.solve()
    assert r.status is SolveStatus.NUMERICAL_ERROR and "f" in r.info["error"]
    s.update(f=[1.0, 1.0])
    np.testing.assert_allclose(s.solve().x, [-1, -1], atol=1e-12)  # min 1/2||x||^2 + 1'x


def test_daqp_soft_row_relaxed_with_quadratic_penalty():
    # min 1/2 x^2 s.t. x >= 1 (soft row), x <= 0 (hard bound). DAQP relaxes the soft row with
    # slack s and cost 1/(2 rho_soft) s^2; minimising 1/2 x^2 + (1 - x)^2/(2 rho) over x <= 0
    # gives x = 0 (the unconstrained minimiser 1/(1 + rho) > 0 is cut by the bound), s = 1,
    # f* = 1/(2 rho) = 5e5 for rho = 1e-6. Without the soft flag the problem is infeasible.
    s = DaqpQP(settings={"rho_soft": 1e-6})
    s.setup_native(np.eye(1), [0.0], [[1.0]], [1.0], None, [-1.0], [0.0], soft_rows=[True])
    r = s.solve()
    assert r.status is SolveStatus.OPTIMAL and r.info["soft_relaxed"]
    np.testing.assert_allclose(r.x, [0.0], atol=1e-12)
    assert r.objective == pytest.approx(5e5, rel=1e-9)
    hard = DaqpQP()
    hard.setup_native(np.eye(1), [0.0], [[1.0]], [1.0], None, [-1.0], [0.0])
    assert hard.solve().status is SolveStatus.INFEASIBLE


def test_solver_exception_becomes_numerical_error():
    class Exploding:
        def solve(self):
            raise RuntimeError("boom")

    s = DaqpQP()
    s.setup_native(np.eye(2), np.zeros(2))
    s._model = Exploding()
    r = s.solve()
    assert r.status is SolveStatus.NUMERICAL_ERROR and "boom" in r.info["error"]


# --------------------------------------------------------------------------- PIQP
def test_piqp_lp_equality_and_update():
    # P2 with x1 + x2 = 1 as an equality: x* = (1, 0); costs (2, 1): x* = (0, 1); f* = 1.
    s = PiqpQP()
    s.setup_native(None, [1.0, 2.0], A=[[1.0, 1.0]], b=[1.0], x_lb=[0, 0], x_ub=[5, 5])
    r = s.solve()
    assert r.status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(r.x, [1, 0], atol=1e-7)
    assert r.objective == pytest.approx(1.0, abs=1e-7)
    assert_feasible([[1.0, 1.0]], [1.0], [1.0], r.x, [0, 0], [5, 5])
    s.update(c=[2.0, 1.0])
    r = s.solve()
    np.testing.assert_allclose(r.x, [0, 1], atol=1e-7)
    assert r.objective == pytest.approx(1.0, abs=1e-7)
    assert_feasible([[1.0, 1.0]], [1.0], [1.0], r.x, [0, 0], [5, 5])


def test_piqp_qp_projection_update_and_rebuild():
    G = np.array([[1.0, 1.0]])
    s = PiqpQP()
    s.setup_native(np.eye(2), -np.array([2.0, 1.0]), G=G, h_u=[1.0])
    r = s.solve()
    x_ref, f_ref = projection_halfspace([2, 1], [1, 1], 1.0)
    np.testing.assert_allclose(r.x, x_ref, atol=1e-7)
    assert r.objective == pytest.approx(f_ref, abs=1e-7)
    assert_feasible(G, None, [1.0], r.x)
    # beta = 0: x* = (2,1) - (3/2)(1,1) = (0.5, -0.5), f* = 0.25 - 0.5 = -0.25.
    s.update(h_u=[0.0])
    r = s.solve()
    np.testing.assert_allclose(r.x, [0.5, -0.5], atol=1e-7)
    assert r.objective == pytest.approx(-0.25, abs=1e-7)
    assert r.info["rebuilt"] is False
    # New sparsity pattern G = [1, 0] (x1 <= 0): x* = (0, 1), f* = 1/2 - 1 = -0.5.
    s.update(G=[[1.0, 0.0]])
    r = s.solve()
    assert r.info["rebuilt"] is True
    np.testing.assert_allclose(r.x, [0, 1], atol=1e-7)
    assert r.objective == pytest.approx(-0.5, abs=1e-7)


def test_piqp_infeasible_unbounded_maxiter():
    s = PiqpQP()
    s.setup_native(np.eye(2), np.zeros(2), A=[[1.0, 1.0]], b=[-1.0], x_lb=[0, 0])
    assert s.solve().status is SolveStatus.INFEASIBLE
    s = PiqpQP()
    s.setup_native(None, [-1.0, 0.0], A=[[1.0, 1.0]], b=[1.0])  # x1 -> inf, x2 = 1 - x1
    assert s.solve().status is SolveStatus.UNBOUNDED
    rng = np.random.default_rng(1)
    M = rng.standard_normal((30, 30))
    s = PiqpQP(max_iter=1)
    s.setup_native(M @ M.T + np.eye(30), 10 * rng.standard_normal(30), x_lb=-np.ones(30), x_ub=np.ones(30))
    assert s.solve().status is SolveStatus.MAX_ITER


# --------------------------------------------------------------------------- Clarabel
def test_clarabel_socp_ball_and_updates():
    # min c'x s.t. ||x|| <= r. Cauchy-Schwarz: c'x >= -||c|| ||x|| >= -r||c||, with equality
    # at x* = -r c/||c||. c = (1, 2), r = 2: f* = -2 sqrt(5).
    c = np.array([1.0, 2.0])
    prob = build_conic_problem(c, soc=[(np.eye(2), np.zeros(2), np.zeros(2), 2.0)])
    s = ClarabelSOCP()
    s.setup(prob)
    r = s.solve()
    assert r.status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(r.x, -2 * c / np.linalg.norm(c), atol=1e-6)
    assert r.objective == pytest.approx(-2 * np.sqrt(5), abs=1e-6)
    assert check_conic_feasibility(prob.A, prob.b, prob.cones, r.x, tol=1e-7).feasible
    # r = 3 (the cone's d entry is b[soc0][0]); c = (-3, 4): x* = 3 (3, -4)/5, f* = -15.
    b = prob.b.copy()
    b[prob.blocks["soc0"].start] = 3.0
    s.update(q=[-3.0, 4.0], b=b)
    r = s.solve()
    assert r.info["rebuilt"] is False  # same structure: updated in place
    np.testing.assert_allclose(r.x, [1.8, -2.4], atol=1e-6)
    assert r.objective == pytest.approx(-15.0, abs=1e-6)
    assert check_conic_feasibility(prob.A, b, prob.cones, r.x, tol=1e-7).feasible


def test_clarabel_socp_distance_to_line():
    # min t s.t. ||(x1 - 1, x2 - 2)|| <= t, x1 + x2 = 0: distance from (1, 2) to the line
    # x1 + x2 = 0 is |1 + 2|/sqrt(2); foot point (1,2) - (3/2)(1,1) = (-0.5, 0.5).
    F = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    prob = build_conic_problem([0, 0, 1.0], eq=([[1.0, 1.0, 0]], [0.0]),
                               soc=[(F, [-1.0, -2.0], [0, 0, 1.0], 0.0)])
    assert prob.cones == [("zero", 1), ("soc", 3)]
    s = ClarabelSOCP()
    s.setup(prob)
    res = s.solve()
    np.testing.assert_allclose(res.x, [-0.5, 0.5, 3 / np.sqrt(2)], atol=1e-6)
    assert res.objective == pytest.approx(3 / np.sqrt(2), abs=1e-6)
    assert check_conic_feasibility(prob.A, prob.b, prob.cones, res.x, tol=1e-7).feasible
    # Same pattern, new values: line x1 + 2 x2 = 0. Distance |1 + 4|/sqrt(5) = sqrt(5),
    # foot point (1,2) - (5/5)(1,2) = (0, 0).
    A_new = prob.A.copy()
    A_new[prob.blocks["eq"].start, 1] = 2.0
    s.update(A=A_new)
    res = s.solve()
    assert res.info["rebuilt"] is False
    np.testing.assert_allclose(res.x, [0.0, 0.0, np.sqrt(5)], atol=1e-6)
    assert check_conic_feasibility(A_new, prob.b, prob.cones, res.x, tol=1e-7).feasible


def test_clarabel_qp_lp_and_infinite_rows():
    prob = conic_from_qp(np.eye(2), -np.array([2.0, 1.0]), A=[[1.0, 1.0]], bu=[1.0],
                         lb=[-5, -5], ub=[5, np.inf])
    s = ClarabelSOCP()
    s.setup(prob)
    r = s.solve()
    np.testing.assert_allclose(r.x, [1.0, 0.0], atol=1e-7)
    assert r.objective == pytest.approx(-1.5, abs=1e-7)
    # Make the +inf upper bound of x2 finite and active: x2 <= -2. Minimising
    # (x1-2)^2 + (x2-1)^2 with x2 <= -2 gives x2 = -2, x1 = 2, where x1 + x2 = 0 < 1 is
    # inactive and |x1| <= 5 holds: x* = (2, -2), f* = 1/2 (4 + 4) - (4 - 2) = 2.
    b = prob.b.copy()
    b[prob.blocks["ub"]] = [5.0, -2.0]
    s.update(b=b)
    r = s.solve()
    assert r.info["rebuilt"] is True  # a +inf row became finite: set up again
    np.testing.assert_allclose(r.x, [2.0, -2.0], atol=1e-6)
    assert r.objective == pytest.approx(2.0, abs=1e-6)
    assert check_conic_feasibility(prob.A, b, prob.cones, r.x, tol=1e-7).feasible
    # LP P2 through the same path.
    lp = conic_from_qp(None, [1.0, 2.0], A=[[1.0, 1.0]], bl=[1.0], lb=[0, 0], ub=[5, 5])
    s = ClarabelSOCP()
    s.setup(lp)
    r = s.solve()
    np.testing.assert_allclose(r.x, [1.0, 0.0], atol=1e-7)
    assert r.objective == pytest.approx(1.0, abs=1e-7)


def test_clarabel_update_fast_matches_validated_update():
    """update_fast (b and A values in the set-up pattern, no checks) gives what update gives. Problem: distance
    from p to the line a . x = 0, |a . p| / ||a|| (closed form); foot point p - (a . p / |a|^2) a."""
    F = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    prob = build_conic_problem([0, 0, 1.0], eq=([[1.0, 1.0, 0]], [0.0]), soc=[(F, [-1.0, -2.0], [0, 0, 1.0], 0.0)])
    fast, slow = ClarabelSOCP(), ClarabelSOCP()
    fast.setup(prob)
    slow.setup(prob)
    A = prob.A.copy()
    A.sort_indices()
    for a, p in (((1.0, 2.0), (1.0, 2.0)), ((3.0, -1.0), (2.0, 0.5)), ((0.5, 0.5), (-1.0, 4.0))):
        A[prob.blocks["eq"].start, 0], A[prob.blocks["eq"].start, 1] = a
        b = prob.b.copy()
        b[prob.blocks["soc0"].start + 1:prob.blocks["soc0"].start + 3] = [-p[0], -p[1]]
        fast.update_fast(b=b, A_values=A.data)
        slow.update(b=b, A=A)
        rf, rs = fast.solve(), slow.solve()
        a, p = np.array(a), np.array(p)
        foot = p - (a @ p) / (a @ a) * a
        for r in (rf, rs):
            assert r.status is SolveStatus.OPTIMAL and r.info["rebuilt"] is False
            np.testing.assert_allclose(r.x, [*foot, abs(a @ p) / np.linalg.norm(a)], atol=1e-6)
        np.testing.assert_allclose(rf.x, rs.x, atol=1e-9)


def test_clarabel_update_fast_falls_back_with_removed_rows():
    """With a +inf row (removed before Clarabel sees it), update_fast takes the validated path, which sets the
    solver up again when the row becomes finite (same problem as test_clarabel_qp_lp_and_infinite_rows)."""
    prob = conic_from_qp(np.eye(2), -np.array([2.0, 1.0]), A=[[1.0, 1.0]], bu=[1.0], lb=[-5, -5], ub=[5, np.inf])
    s = ClarabelSOCP()
    s.setup(prob)
    b = prob.b.copy()
    b[prob.blocks["ub"]] = [5.0, -2.0]
    s.update_fast(b=b)
    r = s.solve()
    assert r.info["rebuilt"] is True
    np.testing.assert_allclose(r.x, [2.0, -2.0], atol=1e-6)


def test_clarabel_retry_settings_resolve_an_iteration_limited_solve():
    """A first attempt capped at 2 interior-point iterations ends MAX_ITER; retry_settings (the cap lifted) solves
    the same data again: the ball problem's optimum -r c/||c|| (Cauchy-Schwarz), both attempts reported."""
    c = np.array([1.0, 2.0])
    prob = build_conic_problem(c, soc=[(np.eye(2), np.zeros(2), np.zeros(2), 2.0)])
    plain = ClarabelSOCP(max_iter=2)
    plain.setup(prob)
    assert plain.solve().status is SolveStatus.MAX_ITER
    s = ClarabelSOCP(max_iter=2, retry_settings={"max_iter": 200})
    s.setup(prob)
    r = s.solve()
    assert r.status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(r.x, -2 * c / np.linalg.norm(c), atol=1e-6)
    assert r.info["first_attempt"]["raw_status"] == "MaxIterations"
    assert r.iterations > r.info["first_attempt"]["iterations"] == 2
    with pytest.raises(ProxopsInputError, match="clarabel settings"):
        ClarabelSOCP(retry_settings={"no_such_setting": 1})


def test_clarabel_infeasible_and_unbounded():
    # ||x|| <= 1 and x1 >= 2 (-x1 <= -2) are incompatible.
    prob = build_conic_problem([0.0, 0.0], ineq=([[-1.0, 0.0]], [-2.0]),
                               soc=[(np.eye(2), np.zeros(2), np.zeros(2), 1.0)])
    s = ClarabelSOCP()
    s.setup(prob)
    assert s.solve().status is SolveStatus.INFEASIBLE
    s = ClarabelSOCP()
    s.setup(build_conic_problem([-1.0, 0.0], ineq=([[0.0, 1.0]], [1.0])))
    assert s.solve().status is SolveStatus.UNBOUNDED


# --------------------------------------------------------------------------- HiGHS
def test_highs_lp_vertex_and_hot_start():
    s = HighsLP()
    s.setup_native([1.0, 2.0], A=[[1.0, 1.0]], rl=[1.0], lb=[0, 0], ub=[5, 5])
    r = s.solve()
    assert r.status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(r.x, [1, 0], atol=1e-9)
    assert r.objective == pytest.approx(1.0)
    s.update(c=[2.0, 1.0])
    r = s.solve()
    np.testing.assert_allclose(r.x, [0, 1], atol=1e-9)
    assert r.objective == pytest.approx(1.0)
    # Costs (2.5, 1) keep the basis optimal: the hot start needs no simplex iteration.
    s.update(c=[2.5, 1.0])
    r = s.solve()
    np.testing.assert_allclose(r.x, [0, 1], atol=1e-9)
    assert r.iterations == 0
    # Row bound 10 <= x1 + x2 with x <= 5: only (5, 5); f* = 2.5*5 + 5 = 17.5.
    s.update(rl=[10.0])
    r = s.solve()
    np.testing.assert_allclose(r.x, [5, 5], atol=1e-9)
    assert r.objective == pytest.approx(17.5)
    assert_feasible([[1.0, 1.0]], [10.0], None, r.x, [0, 0], [5, 5])
    # New matrix 2 x1 + x2 >= 1 with costs (1, 2): cost per unit of row is 1/2 for x1 and
    # 2 for x2, so x* = (0.5, 0), f* = 0.5.
    s.update(c=[1.0, 2.0], rl=[1.0], A=[[2.0, 1.0]])
    r = s.solve()
    np.testing.assert_allclose(r.x, [0.5, 0.0], atol=1e-9)
    assert r.objective == pytest.approx(0.5)
    assert_feasible([[2.0, 1.0]], [1.0], None, r.x, [0, 0], [5, 5])


def test_highs_l1_fuel_lp():
    # min sum(u+ + u-) s.t. sum(u+ - u-) = d, 0 <= u+-, <= umax: the l1 norm of any split
    # is >= |sum| = |d|, attained by one-signed firing: f* = |d|. Infeasible if |d| > N umax.
    N, umax, d = 10, 0.3, -2.2
    c = np.ones(2 * N)
    A = np.concatenate([np.ones(N), -np.ones(N)])[None, :]
    s = HighsLP()
    s.setup_native(c, A, [d], [d], np.zeros(2 * N), umax * np.ones(2 * N))
    r = s.solve()
    assert r.objective == pytest.approx(abs(d), abs=1e-9)
    assert_feasible(A, [d], [d], r.x, np.zeros(2 * N), umax * np.ones(2 * N))
    s.update(rl=[-3.5], ru=[-3.5])  # |d| = 3.5 > N umax = 3
    assert s.solve().status is SolveStatus.INFEASIBLE


def test_highs_infeasible_and_unbounded():
    s = HighsLP()
    s.setup_native([0.0, 0.0], [[1.0, 1.0]], None, [-1.0], [0, 0], None)
    assert s.solve().status is SolveStatus.INFEASIBLE
    s = HighsLP()
    s.setup_native([-1.0, 0.0], [[0.0, 1.0]], None, [1.0])
    assert s.solve().status is SolveStatus.UNBOUNDED


# --------------------------------------------------------------------------- cross-checks
def double_integrator_least_energy(N=40, dt=1.0, x0=(100.0, 0.0)):
    """Condensed min sum u_k^2 to reach the origin: least-norm u* = G^+ (-A^N x0)."""
    Ad = np.array([[1.0, dt], [0.0, 1.0]])
    Bd = np.array([0.5 * dt * dt, dt])
    G = np.column_stack([np.linalg.matrix_power(Ad, N - 1 - k) @ Bd for k in range(N)])
    target = -np.linalg.matrix_power(Ad, N) @ np.asarray(x0)
    u_star = np.linalg.pinv(G) @ target  # independent: numpy SVD least-norm solution
    return G, target, u_star


@pytest.mark.parametrize("solver", QP_SOLVERS)
def test_condensed_terminal_constraint_qp_matches_least_norm(solver):
    # min 1/2 u'u s.t. G u = target (2 equality rows), |u| <= umax inactive (2x margin).
    G, target, u_star = double_integrator_least_energy()
    umax = 2 * np.abs(u_star).max()
    N = G.shape[1]
    qp = QuadraticProgram(P=np.eye(N), q=np.zeros(N), A=G, bl=target, bu=target,
                          lb=-umax * np.ones(N), ub=umax * np.ones(N))
    r = solve_qp(qp, solver)
    assert r.status is SolveStatus.OPTIMAL and r.solver == solver
    np.testing.assert_allclose(r.x, u_star, atol=1e-6 * umax)
    assert r.objective == pytest.approx(0.5 * u_star @ u_star, rel=1e-6)
    assert_feasible(G, target, target, r.x, qp.lb, qp.ub, tol=1e-6)


def test_random_mpc_sized_qp_agrees_across_solvers():
    # A condensed-MPC-sized QP (n = 120, 240 rows); no closed form, so three independent
    # solvers must agree and every answer must be feasible.
    rng = np.random.default_rng(7)
    n, m = 120, 240
    M = rng.standard_normal((n, n))
    H = M @ M.T / n + np.eye(n)
    q = 3 * rng.standard_normal(n)
    A = rng.standard_normal((m, n)) / np.sqrt(n)
    bu = 0.5 + rng.random(m)
    qp = QuadraticProgram(P=H, q=q, A=A, bl=-bu, bu=bu, lb=-np.ones(n), ub=np.ones(n))
    results = {s: solve_qp(qp, s) for s in QP_SOLVERS}
    for s, r in results.items():
        assert r.status is SolveStatus.OPTIMAL, s
        assert_feasible(A, -bu, bu, r.x, qp.lb, qp.ub, tol=1e-6)
    objs = [r.objective for r in results.values()]
    assert max(objs) - min(objs) < 1e-6 * max(1.0, abs(objs[0]))
    np.testing.assert_allclose(results["piqp"].x, results["daqp"].x, atol=1e-5)
    np.testing.assert_allclose(results["clarabel"].x, results["daqp"].x, atol=1e-5)


def test_lp_agrees_across_all_solvers():
    qp = QuadraticProgram(P=None, q=[1.0, 2.0], A=[[1.0, 1.0]], bl=[1.0], lb=[0, 0], ub=[5, 5])
    for s in QP_SOLVERS + ("highs",):
        r = solve_qp(qp, s)
        assert r.status is SolveStatus.OPTIMAL, s
        np.testing.assert_allclose(r.x, [1, 0], atol=1e-7)
        assert r.objective == pytest.approx(1.0, abs=1e-7)


# --------------------------------------------------------------------------- bad input
def test_bad_input_raises_clear_errors():
    s = DaqpQP()
    with pytest.raises(ProxopsInputError, match=r"A\.shape"):
        s.setup_native(np.eye(2), np.zeros(2), np.ones((1, 3)))
    s.setup_native(np.eye(2), np.zeros(2), np.ones((1, 2)), None, [1.0])
    with pytest.raises(ProxopsInputError, match=r"bu\.shape"):
        s.update(bu=[1.0, 2.0])
    with pytest.raises(ProxopsInputError, match="lb/ub"):
        s.update(lb=[0.0, 0.0])  # no bounds at setup
    with pytest.raises(ProxopsInputError, match="daqp settings"):
        DaqpQP(settings={"not_a_setting": 1})
    with pytest.raises(ProxopsInputError, match="piqp settings"):
        PiqpQP(settings={"not_a_setting": 1})
    with pytest.raises(ProxopsInputError, match="cones"):
        ClarabelSOCP().setup_native(None, [0.0], np.ones((2, 1)), [1.0, 1.0], [("nonneg", 1)])
    with pytest.raises(ProxopsInputError, match="solver"):
        solve_qp(QuadraticProgram(P=None, q=[1.0]), "osqp")
    with pytest.raises(ProxopsInputError, match="LPs only"):
        solve_qp(QuadraticProgram(P=np.eye(1), q=[1.0]), "highs")


def test_piqp_bound_update_in_place():
    """min 1/2 |x - c|^2 s.t. lb <= x <= ub: the optimum is clip(c, lb, ub) (projection onto a box).
    Updating only the bounds must reuse the solver (no error, no rebuild) and move the optimum."""
    c = np.array([2.0, -3.0, 0.5])
    qp = PiqpQP()
    qp.setup_native(np.eye(3), -c, x_lb=-np.ones(3), x_ub=np.ones(3))
    first = qp.solve()
    assert first.status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(first.x, np.clip(c, -1, 1), atol=1e-6)
    qp.update(x_lb=np.array([-5.0, -5.0, 0.8]), x_ub=np.array([1.5, 5.0, 5.0]))
    second = qp.solve()
    assert second.status is SolveStatus.OPTIMAL and not second.info.get("error")
    np.testing.assert_allclose(second.x, [1.5, -3.0, 0.8], atol=1e-6)


@pytest.mark.parametrize("adapter", [DaqpQP, PiqpQP, ClarabelSOCP, HighsLP])
def test_solve_before_setup_is_a_usage_error(adapter):
    with pytest.raises(ProxopsInputError, match="call setup"):
        adapter().solve()
