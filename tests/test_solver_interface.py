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
    make_solver,
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
    s = make_solver("QP", name)
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
    s = make_solver("QP", "daqp")
    s.setup(QuadraticProgram(P=np.eye(2), q=-p, A=np.array([[1.0, 0.0]]), bl=[1.0], bu=[np.inf]))

    def solve():
        res = s.solve()
        return (res.x, None) if res.ok else (None, str(res.status))

    def relinearize(x, _radius):
        s.update(A=(x / np.linalg.norm(x))[None, :])

    out = successive_convexification(solve, lambda x, prev: prev is not None and np.abs(x - prev).max() < 1e-10,
                                     relinearize, max_iter=100)
    assert out.converged and out.status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(out.iterate, [0.6, 0.8], atol=1e-8)
    assert np.linalg.norm(out.iterate) >= 1.0 - 1e-9


def test_successive_convexification_loop_rules():
    # failures propagate, the trust region halves when the merit grows, max_iter stops the loop
    seq = iter([(1.0, None), (2.0, None), (None, "infeasible")])
    radii = []
    out = successive_convexification(lambda: next(seq), lambda it, prev: False,
                                     lambda prev, r: radii.append(r), max_iter=5,
                                     trust=TrustRegion(4.0), merit=lambda it: it)
    assert out.status is SolveStatus.FAILED and out.failure is SolveStatus.INFEASIBLE and out.iterations == 3
    assert radii == [4.0, 2.0] and out.iterate == 2.0  # merit 1 -> 2 grew: 4 -> 2
    out = successive_convexification(lambda: (0.0, None), lambda it, prev: False, max_iter=3)
    assert out.status is SolveStatus.MAX_ITER and out.failure is SolveStatus.NONE and out.iterations == 3


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
        write_report,
    )
    from proxops import api

    assert api.run_campaign is run_campaign and api.load_campaign is load_campaign


# ---------------------------------------------------------------- the adapter base and make_solver
def test_every_adapter_derives_from_the_base_and_make_solver_checks_the_pair():
    from proxops.solvers import ClarabelSOCP, DaqpQP, PiqpQP, SolverAdapter, make_solver

    for cls in (DaqpQP, PiqpQP, ClarabelSOCP, HighsLP, HighsMILP):
        assert issubclass(cls, SolverAdapter)
    assert isinstance(make_solver("MILP", "highs"), HighsMILP)
    assert isinstance(make_solver(_ilp(True), "highs"), HighsMILP)  # an instance: kind from integrality
    # a wrong pair: one line naming the form, the name and the allowed names
    with pytest.raises(ProxopsInputError) as err:
        make_solver("SOCP", "daqp")
    msg = str(err.value)
    assert "\n" not in msg and "SOCP" in msg and "ConicProblem" in msg and "'daqp'" in msg and "clarabel" in msg
    with pytest.raises(ProxopsInputError, match="allowed: daqp, piqp, clarabel"):
        make_solver(_qp(), "highs")
    with pytest.raises(ProxopsInputError, match="MILP.*'piqp'.*allowed: highs"):
        make_solver(_ilp(True), "piqp")
    with pytest.raises(ProxopsInputError, match="setup_native"):
        make_solver("QP", "daqp").setup(np.eye(2))  # native arguments are not a form


def test_clarabel_setup_native_then_update_fast():
    """Issue 31: ``setup_native`` then ``update_fast`` raised AttributeError (``_qp`` was only set by
    ``setup``). min x s.t. x >= b (nonneg row -x <= -b): the optimum is x = b, for b = 1 then 3."""
    from proxops.solvers import ClarabelSOCP

    s = ClarabelSOCP()
    s.setup_native(None, [1.0], [[-1.0]], [-1.0], [("nonneg", 1)])
    s.update_fast(b=np.array([-3.0]))
    res = s.solve()
    assert res.status == SolveStatus.OPTIMAL
    assert res.x[0] == pytest.approx(3.0, abs=1e-7)
    # and the QP-form set-up followed by a native set-up forgets the QP (update takes the native names)
    s.setup(QuadraticProgram(P=None, q=[1.0], lb=[2.0]))
    s.setup_native(None, [1.0], [[-1.0]], [-1.0], [("nonneg", 1)])
    s.update(b=[-5.0])
    assert s.solve().x[0] == pytest.approx(5.0, abs=1e-7)


@pytest.mark.parametrize("name", ["highs", "daqp", "piqp", "clarabel"])
def test_one_lp_form_on_every_lp_solver(name):
    # The LP of _ilp(False) (vertex x = y = 2.4, value -4.8), then its cost changed through the LP's
    # own field name c: min -x s.t. the same rows -> x = 4 (3x + 2y <= 12 with y = 0), value -4.
    s = make_solver(_ilp(False), name, **({"settings": {"eps_prox": 1e-2}} if name == "daqp" else {}))
    res = s.solve()
    assert res.status == SolveStatus.OPTIMAL and res.objective == pytest.approx(-4.8, abs=1e-6)
    np.testing.assert_allclose(res.x, [2.4, 2.4], atol=1e-6)
    s.update(c=[-1.0, 0.0])
    res = s.solve()
    assert res.status == SolveStatus.OPTIMAL
    np.testing.assert_allclose(res.x, [4.0, 0.0], atol=1e-6)
    with pytest.raises(ProxopsInputError, match="allowed: c, A, rl, ru, lb, ub"):
        s.update(q=[1.0, 1.0])


# ---------------------------------------------------------------- every consumer on two solvers by name
@pytest.mark.parametrize("solver", ["highs", "piqp", "clarabel"])
def test_thruster_allocation_on_lp_solvers_against_the_closed_form(solver):
    """Algorithm 4 on the six-thruster layout (+-x, +-y, +-z through the centre of mass, f_max 0.2 N):
    per axis the force F_i is produced exactly up to f_max and clipped beyond (the L1 error separates by
    axis), no torque can be produced (error = |tau|). Boundary: F_x = f_max needs duty exactly 1."""
    from proxops.actuators.thrusters import Allocator, six_thruster_layout

    f_max = 0.2
    alloc = Allocator(six_thruster_layout(f_max), solver=solver)
    assert alloc.lp.name == solver
    for c in ([0.2, -0.2, 0.0, 0.0, 0.0, 0.0], [0.35, -0.05, 0.12, 0.01, -0.02, 0.0], [-0.5, 0.5, -0.2, 0.0, 0.0, 0.3]):
        c = np.array(c)
        a = alloc.solve(c)
        assert a.status == "optimal", (solver, a.status)
        F = np.clip(c[:3], -f_max, f_max)
        np.testing.assert_allclose(a.achieved[:3], F, atol=1e-6)
        np.testing.assert_allclose(a.achieved[3:], 0.0, atol=1e-9)
        np.testing.assert_allclose(a.error, np.concatenate([np.abs(c[:3]) - np.abs(F), np.abs(c[3:])]), atol=1e-6)
        assert np.all(a.duty >= 0.0) and np.all(a.duty <= 1.0)
    a = alloc.solve(np.array([0.2, -0.2, 0.0, 0.0, 0.0, 0.0]))
    assert a.duty[0] == pytest.approx(1.0, abs=1e-6) and a.duty[3] == pytest.approx(1.0, abs=1e-6)
    assert a.duty[1] == pytest.approx(0.0, abs=1e-6) and a.duty[2] == pytest.approx(0.0, abs=1e-6)


# The section {p : exists u in [0, 0.5], p1 + p2 <= 1 + u, 0 <= p <= 1} is the pentagon with vertices
# (0,0), (1,0), (1,0.5), (0.5,1), (0,1): its support function is the max of d.v over those vertices.
_PENTAGON = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.5], [0.5, 1.0], [0.0, 1.0]])


def _pentagon_section(**solvers):
    from proxops.geometry.polytope import ConvexSection

    return ConvexSection(np.array([[1.0, 1.0, -1.0]]), np.array([1.0]), np.zeros(3), np.array([1.0, 1.0, 0.5]),
                         **solvers)


@pytest.mark.parametrize("support_solver", ["daqp", "highs", "clarabel"])
def test_section_support_lps_on_several_solvers_against_the_closed_form(support_solver):
    sec = _pentagon_section(support_solver=support_solver)
    assert sec.support_lp.name == support_solver
    # 10 deg steps, including the edge normals (1, 1)/sqrt2 (edge (1,0.5)-(0.5,1)), (1, 0), (0, 1), (-1, -1)
    for ang in np.radians(np.arange(0.0, 360.0, 5.0)):
        d = np.array([math.cos(ang), math.sin(ang)])
        status, p = sec.support_point(d)
        assert status is SolveStatus.OPTIMAL
        assert d @ p == pytest.approx(np.max(_PENTAGON @ d), abs=1e-6)
        assert p[0] + p[1] <= 1.5 + 1e-6 and np.all(p >= -1e-6) and np.all(p <= 1 + 1e-6)  # p is in the section
    assert sec.n_highs == 0  # every direction settled by the named support solver


@pytest.mark.parametrize("lp_solver", ["highs", "clarabel"])
def test_section_point_lps_on_two_solvers_against_the_closed_form(lp_solver):
    # 1e-4 inside / outside the slanted edge p1 + p2 = 1.5 (the point LP fixes p by its bounds, so the box
    # itself is not tested here: contains() settles points beyond it by the outer half-planes)
    sec = _pentagon_section(support_solver=None, lp_solver=lp_solver)
    assert sec.support_lp is None and sec.lp.name == lp_solver
    for p, inside in (([0.75, 0.7499], True), ([0.75, 0.7501], False), ([1.0, 0.4999], True), ([1.0, 0.5001], False),
                      ([0.0, 0.0], True), ([0.5, 1.0], True)):
        assert sec._point_feasible(np.array(p)) is inside, (lp_solver, p)
        sec._set(lb=sec.lb, ub=sec.ub)
    poly = sec.polygon(n_directions=16)  # all support LPs on lp_solver (support_solver=None)
    assert sec.n_highs == len(poly.support)
    np.testing.assert_allclose(poly.support, np.max(poly.directions @ _PENTAGON.T, axis=1), atol=1e-6)


def test_solver_names_are_checked_by_the_consumers():
    from proxops.actuators.thrusters import Allocator, six_thruster_layout
    from proxops.control.cortex_tracking import TrackingSOCP

    with pytest.raises(ProxopsInputError, match="LP.*'osqp'.*allowed: highs, daqp, piqp, clarabel"):
        Allocator(six_thruster_layout(), solver="osqp")
    with pytest.raises(ProxopsInputError, match="SOCP.*'daqp'.*allowed: clarabel, ipopt"):
        TrackingSOCP(0.001, 3, 2.0, 2.4e-3, 10.0, solver="daqp")


@pytest.mark.parametrize("plume", [False, True])
def test_cortex_tracking_socp_on_clarabel_and_ipopt(plume):
    """CP_g (eq. 27, 5 impulses, approach cone; with soft plume rows) by name on Clarabel and on IPOPT (the
    cone rows as smooth NLP constraints: an independent engine; Clarabel is the only conic solver shipped).
    Same optimum to 1e-6 relative, both answers inside the cones, for a first solve and an update of b."""
    from proxops.constraints.approach_cone import ApproachCone
    from proxops.control.cortex_tracking import TrackingSOCP
    from proxops.core.cw import mean_motion
    from proxops.solvers import check_conic_feasibility

    axis = np.array([-1.0, -1.0, 0.0]) / math.sqrt(2)
    x0 = np.concatenate([17.0 * axis, -0.02 * axis])
    xT = np.concatenate([16.0 * axis + [0.3, -0.3, 0.0], np.zeros(3)])
    out = {}
    for name in ("clarabel", "ipopt"):
        prob = TrackingSOCP(mean_motion(6878.1e3), 5, 2.0, 2.4e-3, 10.0, cone=ApproachCone(axis, math.radians(10)),
                            plume=plume, solver=name)
        if plume:
            prob.set_plume(np.tile([0.3, 0.3, 1.3], (5, 1)))
        out[name] = []
        for shift in (0.0, 0.2):
            dv, res = prob.solve(x0 + [shift, 0, 0, 0, 0, 0], xT)
            assert res.status == SolveStatus.OPTIMAL and res.solver == name and dv is not None
            form = prob.form()
            assert check_conic_feasibility(form.A, form.b, form.cones, res.x, 1e-6).feasible  # units of V, L
            out[name].append(res.objective)
    np.testing.assert_allclose(out["ipopt"], out["clarabel"], rtol=1e-6)


def test_srf_mpc_closed_loop_on_three_qp_solvers():
    """The srf V-bar loop (3 hops, tests/test_srf_mpc.run_loop) with its QP on PIQP (default), Clarabel and
    DAQP by name (SrfMpcConfig.solver): three independent engines apply the same impulses (1e-6 m/s; measured
    agreement 3e-8) and reach the handover."""
    from test_srf_mpc import run_loop

    applied = {}
    for name in ("piqp", "clarabel", "daqp"):
        res, ctrl, *_ = run_loop(0.0, 3, solver=name)
        assert ctrl._solver.name == name and res.meta["outcome"] == "handover"
        applied[name] = res.u_applied
    assert np.abs(applied["piqp"]).max() > 0.1  # the loop fires (the comparison has teeth)
    for name in ("clarabel", "daqp"):
        np.testing.assert_allclose(applied[name], applied["piqp"], atol=1e-6)


def test_default_success_reads_stop_reason_and_status():
    """SystemBase.success: a run fails only when the controller stopped it (StopReason.CONTROLLER) on a failed
    step (Status.failed); the outcome text is not read (a 'failed...' outcome of a completed run succeeds)."""
    from proxops.status import Status, StopReason
    from proxops.systems.base import SystemBase

    ok = SystemBase().success
    assert ok(None, {"stop_reason": str(StopReason.COMPLETED), "final_status": "infeasible", "status": "failed: x"})
    assert ok(None, {"stop_reason": str(StopReason.STOP_CONDITION), "final_status": "ok"})
    assert ok(None, {"stop_reason": str(StopReason.CONTROLLER), "final_status": str(Status.OK)})
    assert ok(None, {"stop_reason": str(StopReason.CONTROLLER), "final_status": str(Status.OPTIMAL_INACCURATE)})
    for bad in (Status.INFEASIBLE, Status.NUMERICAL_ERROR, Status.FAILED, Status.MAX_ITER):
        assert not ok(None, {"stop_reason": str(StopReason.CONTROLLER), "final_status": str(bad)})
