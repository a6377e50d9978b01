"""Farkas certificates from PIQP's duals (solvers.feasibility.farkas_margin, PiqpQP certify_after).

The margin is checked against the true least violation of the rows over the bound box, computed
independently by an LP (scipy/HiGHS): a sound certificate never exceeds it, and none exists for a
feasible problem."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import linprog

from proxops.solvers import SolveStatus, farkas_margin
from proxops.solvers.piqp_qp import PiqpQP


def least_violation(A, b, G, h_l, h_u, lb, ub):
    """min over lb <= x <= ub of the largest row violation (LP in (x, t))."""
    n = A.shape[1]
    rows, rhs = [], []
    for M, hi in ((A, b), (-A, -b), (G, h_u), (-G, -h_l)):
        keep = np.isfinite(hi)
        rows.append(np.hstack([M[keep], -np.ones((keep.sum(), 1))]))
        rhs.append(hi[keep])
    res = linprog(np.r_[np.zeros(n), 1.0], A_ub=np.vstack(rows), b_ub=np.concatenate(rhs),
                  bounds=list(zip(lb, ub)) + [(0, None)], method="highs")
    assert res.status == 0
    return res.fun


def problem(seed, shift):
    """Box [0, 1]^8 (one free column tied by an equality), 2 equalities, 12 two-sided rows; the
    rows' window moved by ``shift`` beyond what the box reaches makes it infeasible."""
    rng = np.random.default_rng(seed)
    n = 8
    A = rng.normal(size=(2, n))
    A[:, -1] = 0.0
    A[1, -1] = 1.0  # x_7 free: only in equality 1
    G = rng.normal(size=(12, n))
    G[:, -1] = 0.0
    x0 = rng.uniform(0.2, 0.8, n)
    b = A @ x0
    reach = np.abs(G[:, :-1]).sum(axis=1)  # |G x| <= reach on the box
    h_l = G @ x0 - 0.1
    h_u = G @ x0 + 0.1
    h_l[0] = reach[0] + shift  # row 0 cannot be reached from the box by `shift`
    h_u[0] = np.inf
    lb, ub = np.zeros(n), np.ones(n)
    lb[-1], ub[-1] = -np.inf, np.inf
    return A, b, G, h_l, h_u, lb, ub


def piqp_duals(data, max_iter):
    s = PiqpQP(max_iter=max_iter)
    A, b, G, h_l, h_u, lb, ub = data
    s.setup_native(sp.eye(len(lb), format="csc") * 1e-3, np.ones(len(lb)), A, b, G, h_l, h_u, lb, ub)
    res = s.solve()
    d = res.info["dual"]
    return res, d["y"], d["z_l"], d["z_u"]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_margin_is_a_lower_bound_of_the_least_violation(seed):
    data = problem(seed, shift=0.5)
    truth = least_violation(*data)
    assert truth >= 0.5 - 1e-9  # row 0 alone is short by 0.5
    _, y, z_l, z_u = piqp_duals(data, max_iter=60)
    margin = farkas_margin(*data, y, z_l, z_u)
    assert 0.0 < margin <= truth + 1e-9


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_certificate_for_a_feasible_problem(seed):
    data = problem(seed, shift=-0.5 - 1e3)  # row 0 switched to a loose bound: x0 is feasible
    assert least_violation(*data) <= 1e-9
    rng = np.random.default_rng(seed)
    _, y, z_l, z_u = piqp_duals(data, max_iter=60)
    candidates = [(y, z_l, z_u)] + [(rng.normal(size=2) * 10, rng.exponential(size=12) * 10,
                                     rng.exponential(size=12) * 10) for _ in range(200)]
    for y, z_l, z_u in candidates:
        assert farkas_margin(*data, y, z_l, z_u) == -np.inf


def test_free_column_rows_are_dropped():
    A, b, G, h_l, h_u, lb, ub = problem(0, shift=0.5)
    _, y, z_l, z_u = piqp_duals((A, b, G, h_l, h_u, lb, ub), max_iter=60)
    y = y.copy()
    y[1] = 1e6  # the free column's equality: any weight on it proves nothing and is dropped
    assert farkas_margin(A, b, G, h_l, h_u, lb, ub, y, z_l, z_u) > 0.0


def test_piqp_certify_after_reports_infeasible_and_leaves_solved_problems_unchanged():
    infeasible = problem(1, shift=0.5)
    feasible = problem(1, shift=-0.5 - 1e3)
    for data in (infeasible, feasible):
        A, b, G, h_l, h_u, lb, ub = data
        out = []
        for kw in ({}, {"certify_after": 3, "certify_margin": 1e-5}):
            s = PiqpQP(max_iter=80, **kw)
            s.setup_native(sp.eye(8, format="csc") * 1e-3, np.ones(8), A, b, G, h_l, h_u, lb, ub)
            out.append(s.solve())
        plain, certified = out
        if data is feasible:
            assert plain.iterations > 3  # the early stop happened, then the full solve
            assert plain.status == certified.status == SolveStatus.OPTIMAL
            assert plain.x.tobytes() == certified.x.tobytes()  # bit-identical to the plain solve
        else:
            assert plain.status == SolveStatus.INFEASIBLE and plain.iterations > 3
            assert certified.status == SolveStatus.INFEASIBLE and certified.iterations == 3
            assert certified.info["raw_status"] == "farkas_certificate"
            assert 1e-5 < certified.info["infeasibility_margin"] <= least_violation(*data) + 1e-9


def test_certify_settings_are_checked():
    from proxops.errors import ProxopsInputError

    with pytest.raises(ProxopsInputError, match="certify_after"):
        PiqpQP(certify_after=0)
    with pytest.raises(ProxopsInputError, match="certify_margin"):
        PiqpQP(certify_margin=-1.0)
