"""One persistent solver interface: the same ``setup(problem)`` / ``update`` / ``warm_start`` /
``solve`` on every adapter, the HiGHS MILP adapter, the successive-convexification helper and
the CasADi NLP adapter, against optima derived by hand in the comments."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxops.errors import ProxopsInputError
from proxops.solvers import (
    HighsLP,
    HighsMILP,
    LinearProgram,
    QuadraticProgram,
    SolveStatus,
    TrustRegion,
    check_feasibility,
    make_qp_solver,
    successive_convexification,
)
from proxops.solvers.casadi_nlp import CasadiNLP, NonlinearProgram, status_of

TOL = 1e-6


# QP with explicit equality rows: min 1/2||x - p||^2, p = (1, 2, 3), s.t. x1 + x2 + x3 = b, x3 <= u.
# b = 3, u = 1.5: x3 = 1.5 active, (x1, x2) = projection of (1, 2) on x1 + x2 = 1.5 = (0.25, 1.25);
#   KKT: lambda = 1 - 0.25 = 0.75, mu = 3 - 1.5 - 0.75 = 0.75 >= 0.
# u = 2.5: projection of p on the plane, x = p - (6 - 3)/3 = (0, 1, 2), x3 = 2 < 2.5 inactive.
# then b = 6: p itself is on the plane but x3 = 3 > 2.5, so x3 = 2.5 and (x1, x2) = (1.25, 2.25);
#   KKT: lambda = 1 - 1.25 = -0.25 (equality: any sign), mu = 3 - 2.5 + 0.25 = 0.75 >= 0.
def _qp(b=3.0, u=1.5):
    return QuadraticProgram(P=np.eye(3), q=-np.array([1.0, 2.0, 3.0]), A=np.array([[0.0, 0.0, 1.0]]),
                            bl=[-np.inf], bu=[u], A_eq=np.ones((1, 3)), b_eq=[b])


@pytest.mark.parametrize("name", ["daqp", "piqp", "clarabel"])
def test_same_calls_same_answer_on_every_qp_adapter(name):
    s = make_qp_solver(name)
    s.setup(_qp())
    steps = [({}, [0.25, 1.25, 1.5]), ({"bu": [2.5]}, [0.0, 1.0, 2.0]), ({"b_eq": [6.0]}, [1.25, 2.25, 2.5])]
    for fields, expected in steps:
        if fields:
            s.update(**fields)
        res = s.solve()
        assert res.status == SolveStatus.OPTIMAL, (name, fields, res)
        np.testing.assert_allclose(res.x, expected, atol=1e-5)
        qp = _qp(**{"b": 6.0 if "b_eq" in fields else 3.0, "u": 1.5 if not fields else 2.5})
        stacked = qp.stacked()
        assert check_feasibility(stacked.A, stacked.bl, stacked.bu, res.x, 1e-6).feasible
    assert s.warm_start() in (True, False)


def test_qp_form_with_equality_rows_matches_its_stacked_form():
    # the same problem given as A_eq rows or as rows with bl == bu: same optimum (daqp, piqp via solve_qp)
    from proxops.solvers import solve_qp

    a = solve_qp(_qp(), "piqp")
    b = solve_qp(_qp().stacked(), "piqp")
    np.testing.assert_allclose(a.x, b.x, atol=1e-7)


# Integer LP: max x + y s.t. -x + y <= 1, 3x + 2y <= 12, 2x + 3y <= 12, x, y >= 0.
# LP relaxation: vertex 3x + 2y = 2x + 3y = 12 -> x = y = 2.4, value 4.8.
# Integers: x + y = 5 is infeasible ((3,2), (2,3): 13 > 12; (4,1): 14 > 12; (1,4): -1 + 4 > 1; (5,0), (0,5)
# violate a row), (2, 2) is feasible with value 4, so the MILP optimum is 4.
def _ilp(integer: bool) -> LinearProgram:
    A = np.array([[-1.0, 1.0], [3.0, 2.0], [2.0, 3.0]])
    return LinearProgram(c=[-1.0, -1.0], A=A, ru=[1.0, 12.0, 12.0], lb=[0.0, 0.0],
                         integrality=[True, True] if integer else None)


def test_highs_milp_against_the_integer_and_relaxed_optima():
    lp = HighsLP()
    lp.setup(_ilp(False))
    res = lp.solve()
    assert res.status == SolveStatus.OPTIMAL and res.objective == pytest.approx(-4.8, abs=1e-9)
    mip = HighsMILP()
    mip.setup(_ilp(True))
    assert mip.warm_start([1.0, 1.0])  # a feasible incumbent (value 2)
    res = mip.solve()
    assert res.status == SolveStatus.OPTIMAL and res.objective == pytest.approx(-4.0, abs=1e-9)
    assert np.allclose(res.x, np.round(res.x), atol=1e-9)
    A = _ilp(True).A
    assert check_feasibility(A, [-np.inf] * 3, [1.0, 12.0, 12.0], res.x, 1e-9, lb=[0, 0]).feasible
    assert "mip_gap" in res.info
    # an infeasible MILP is a status: x + y = 0.5 with integers
    mip2 = HighsMILP()
    mip2.setup(LinearProgram(c=[1.0, 1.0], A=[[1.0, 1.0]], rl=[0.5], ru=[0.5], lb=[0, 0], ub=[1, 1],
                             integrality=[1, 1]))
    assert mip2.solve().status == SolveStatus.INFEASIBLE


def test_highs_lp_refuses_integer_variables():
    with pytest.raises(ProxopsInputError, match="HighsMILP"):
        HighsLP().setup(_ilp(True))


# Successive convexification on a non-convex constraint with a known answer: the point of
# {||x|| >= 1} nearest to p = (0.3, 0.4) (inside the unit disc) is p / ||p|| = (0.6, 0.8).
# Each subproblem linearises ||x|| >= 1 about the last iterate x_k: n_k . x >= 1, n_k = x_k/||x_k||
# (a supporting half-space of the disc's complement, so every iterate satisfies the true constraint).
def test_successive_convexification_converges_to_the_nearest_point_outside_the_disc():
    p = np.array([0.3, 0.4])
    s = make_qp_solver("daqp")
    s.setup(QuadraticProgram(P=np.eye(2), q=-p, A=np.array([[1.0, 0.0]]), bl=[1.0], bu=[np.inf]))

    def solve():
        res = s.solve()
        return (res.x, None) if res.ok else (None, str(res.status))

    def relinearize(x, _radius):
        s.update(A=(x / np.linalg.norm(x))[None, :])

    out = successive_convexification(solve, lambda x, prev: prev is not None and np.abs(x - prev).max() < 1e-10,
                                     relinearize, max_iter=100)
    assert out.converged
    np.testing.assert_allclose(out.iterate, [0.6, 0.8], atol=1e-8)
    assert np.linalg.norm(out.iterate) >= 1.0 - 1e-9


def test_successive_convexification_loop_rules():
    # failures propagate, the trust region halves when the merit grows, max_iter stops the loop
    seq = iter([(1.0, None), (2.0, None), (None, "infeasible")])
    radii = []
    out = successive_convexification(lambda: next(seq), lambda it, prev: False,
                                     lambda prev, r: radii.append(r), max_iter=5,
                                     trust=TrustRegion(4.0), merit=lambda it: it)
    assert out.status == "failed" and out.failure == "infeasible" and out.iterations == 3
    assert radii == [4.0, 2.0] and out.iterate == 2.0  # merit 1 -> 2 grew: 4 -> 2
    out = successive_convexification(lambda: (0.0, None), lambda it, prev: False, max_iter=3)
    assert out.status == "max_iter" and out.iterations == 3


def test_casadi_nlp_optimum_and_statuses():
    import casadi as ca  # a core dependency
    x = ca.SX.sym("x", 2)
    # min (x1 - 1)^2 + (x2 - 2)^2 s.t. x1 + x2 = 1: projection of (1, 2) on the line -> (0, 1), f = 2.
    prob = NonlinearProgram(x=x, f=(x[0] - 1) ** 2 + (x[1] - 2) ** 2, g=x[0] + x[1], lbg=[1.0], ubg=[1.0])
    s = CasadiNLP("ipopt", options={"print_level": 0, "sb": "yes"})
    s.setup(prob)
    assert s.warm_start(x=[0.5, 0.5])
    res = s.solve()
    assert res.status == SolveStatus.OPTIMAL and res.objective == pytest.approx(2.0, abs=1e-8)
    np.testing.assert_allclose(res.x, [0.0, 1.0], atol=1e-7)
    # x in [2, 3]^2 cannot sum to 1: infeasible is a status
    s.update(lbx=[2.0, 2.0], ubx=[3.0, 3.0])
    res = s.solve()
    assert res.status == SolveStatus.INFEASIBLE and not res.ok
    assert status_of({"success": True, "return_status": "Solved_To_Acceptable_Level"}) == SolveStatus.OPTIMAL_INACCURATE
    assert status_of({"success": False, "return_status": "Maximum_Iterations_Exceeded"}) == SolveStatus.MAX_ITER
    assert status_of({"success": False, "return_status": "something new"}) == SolveStatus.NUMERICAL_ERROR
    assert math.isfinite(res.solve_time_s)


def test_campaign_public_names_still_importable():
    from proxops.analysis.campaign import (  # noqa: F401
        CampaignInterrupted,
        is_timing_column,
        load_campaign,
        map_runs,
        read_rows,
        run_campaign,
        shutdown_pools,
    )
    from proxops.report.campaign import write_report  # noqa: F401
    from proxops import api

    assert api.run_campaign is run_campaign and api.load_campaign is load_campaign
