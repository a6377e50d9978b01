"""PiqpQP(drop_fixed=True): variables fixed by x_lb == x_ub are removed from the problem PIQP
factors and put back in x. Checked against the same adapter without it and against Clarabel (an
independent interior-point solver) on random strictly convex QPs with fixed variables at zero and
at other values, through set-up, in-place updates and a change of the fixed set."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from proxops.solvers import QuadraticProgram, SolveStatus, make_solver, solve_qp
from proxops.solvers._util import keep_columns


def _random_qp(rng, n=14, p=2, m=9, fixed_values=True):
    L = rng.normal(size=(n, n))
    P = L @ L.T + n * np.eye(n)
    q = rng.normal(size=n)
    x0 = rng.uniform(-0.5, 0.5, n)  # a point inside every row's band: the problem is feasible
    A_eq = sp.random(p, n, density=0.6, random_state=rng.integers(1 << 30)).tocsc()
    G = sp.random(m, n, density=0.5, random_state=rng.integers(1 << 30)).tocsc()
    lb, ub = np.full(n, -1.0), np.full(n, 1.0)
    fixed = rng.random(n) < 0.4
    lb[fixed] = ub[fixed] = x0[fixed] if fixed_values else 0.0
    if not fixed_values:
        x0[fixed] = 0.0
    gx = G @ x0
    return QuadraticProgram(P=sp.csc_matrix(np.triu(P)), q=q, A_eq=A_eq, b_eq=A_eq @ x0, A=G,
                            bl=gx - rng.uniform(0.0, 0.3, m), bu=gx + rng.uniform(0.0, 0.3, m), lb=lb, ub=ub)


def _objective(pr, x):
    P = pr.P.toarray()
    P = P + np.triu(P, 1).T
    return 0.5 * x @ P @ x + pr.q @ x


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("fixed_values", [False, True])
def test_drop_fixed_solves_the_same_problem(seed, fixed_values):
    pr = _random_qp(np.random.default_rng(seed), fixed_values=fixed_values)
    dropped = make_solver("QP", "piqp", drop_fixed=True)
    dropped.setup(pr)
    full = make_solver("QP", "piqp")
    full.setup(pr)
    a, b = dropped.solve(), full.solve()
    ref = solve_qp(pr, "clarabel")
    assert a.status == b.status == ref.status == SolveStatus.OPTIMAL
    fixed = pr.lb == pr.ub
    assert np.array_equal(a.x[fixed], pr.lb[fixed])  # exactly the fixed values
    np.testing.assert_allclose(a.x, ref.x, atol=1e-6)
    np.testing.assert_allclose(a.x, b.x, atol=1e-6)
    assert a.objective == pytest.approx(_objective(pr, a.x), rel=1e-12, abs=1e-12)
    assert a.objective == pytest.approx(ref.objective, rel=1e-6, abs=1e-8)


def test_drop_fixed_updates_in_place_and_rebuilds_for_a_new_fixed_set():
    rng = np.random.default_rng(11)
    pr = _random_qp(rng, fixed_values=False)
    s = make_solver("QP", "piqp", drop_fixed=True)
    s.setup(pr)
    assert s.solve().status == SolveStatus.OPTIMAL
    # same fixed set, new right-hand sides: in place (no new set-up), same answer as Clarabel
    bl, bu = pr.bl - 0.05, pr.bu + 0.05
    s.update(bl=bl, bu=bu, q=-pr.q)
    got = s.solve()
    pr2 = QuadraticProgram(P=pr.P, q=-pr.q, A_eq=pr.A_eq, b_eq=pr.b_eq, A=pr.A, bl=bl, bu=bu, lb=pr.lb, ub=pr.ub)
    assert got.info["rebuilt"] is False
    np.testing.assert_allclose(got.x, solve_qp(pr2, "clarabel").x, atol=1e-6)
    # free one fixed variable (its bounds open): a new problem for PIQP
    lb, ub = pr.lb.copy(), pr.ub.copy()
    k = int(np.flatnonzero(lb == ub)[0])
    lb[k], ub[k] = -1.0, 1.0
    s.update(lb=lb, ub=ub)
    got = s.solve()
    pr3 = QuadraticProgram(P=pr.P, q=-pr.q, A_eq=pr.A_eq, b_eq=pr.b_eq, A=pr.A, bl=bl, bu=bu, lb=lb, ub=ub)
    assert got.info["rebuilt"] is True
    np.testing.assert_allclose(got.x, solve_qp(pr3, "clarabel").x, atol=1e-6)


def test_drop_fixed_reports_an_infeasible_problem():
    """x0 + x1 >= 3 with x1 fixed at 0 and x0 <= 1: infeasible only through the fixed variable."""
    pr = QuadraticProgram(P=sp.csc_matrix(np.eye(3)), q=np.zeros(3), A=sp.csc_matrix([[1.0, 1.0, 0.0]]),
                          bl=np.array([3.0]), bu=np.array([np.inf]), lb=np.array([-1.0, 0.0, -1.0]),
                          ub=np.array([1.0, 0.0, 1.0]))
    s = make_solver("QP", "piqp", drop_fixed=True)
    s.setup(pr)
    assert s.solve().status == SolveStatus.INFEASIBLE


@pytest.mark.parametrize("seed", range(20))
def test_keep_columns_and_rows_equal_dense_indexing(seed):
    rng = np.random.default_rng(seed)
    m, n = rng.integers(1, 25, size=2)
    M = sp.random(m, n, density=rng.uniform(0.0, 1.0), random_state=seed, format="csc")
    cols, rows = np.flatnonzero(rng.random(n) < 0.6), np.flatnonzero(rng.random(m) < 0.6)
    assert np.array_equal(keep_columns(M, cols).toarray(), M.toarray()[:, cols])
    sub = keep_columns(M, cols, rows=rows)
    assert np.array_equal(sub.toarray(), M.toarray()[np.ix_(rows, cols)]) and sub.has_canonical_format


def test_cached_column_maps_equal_dense_indexing_across_refills_and_sizes():
    """piqp_qp._kept (index maps cached per role, pattern and free set, its matrix refilled in place) gives
    the dense submatrix for every refill of a fixed pattern, for P (rows too) and for two roles with the
    same pattern (their matrices must not be shared), and for another free set of the same pattern."""
    from proxops.solvers.piqp_qp import _kept

    rng = np.random.default_rng(7)
    M = sp.random(9, 12, density=0.4, random_state=7, format="csc")
    Q = sp.random(12, 12, density=0.3, random_state=8, format="csc")
    for free in (np.flatnonzero(rng.random(12) < 0.5), np.arange(3, 12), np.arange(12)):
        for _ in range(3):
            M.data[:] = rng.normal(size=M.nnz)
            Q.data[:] = rng.normal(size=Q.nnz)
            A, G = _kept("A", M, free), _kept("G", M, free)
            assert A is not G and np.array_equal(A.toarray(), M.toarray()[:, free])
            assert np.array_equal(G.toarray(), M.toarray()[:, free])
            assert np.array_equal(_kept("P", Q, free).toarray(), Q.toarray()[np.ix_(free, free)])


def _shared_pattern(M):
    """A canonical CSC copy with read-only index arrays (a caller's fixed layout)."""
    S = sp.csc_matrix(M, copy=True)
    S.sort_indices()
    S.indices.flags.writeable = False
    S.indptr.flags.writeable = False
    return S


def test_update_fast_makes_the_calls_of_update_native_and_still_catches_bad_data():
    """update_fast (trusted: fixed patterns by identity, vectors not copied) against update_native on the same
    sequence -- new values in place, a new fixed set (re-set-up), NaN, crossed bounds, another pattern
    (falls back) -- gives bit-identical results (PIQP receives the same data), and Clarabel agrees."""
    rng = np.random.default_rng(5)
    pr = _random_qp(rng, fixed_values=False)
    A_eq, G = _shared_pattern(pr.A_eq), _shared_pattern(pr.A)
    fast, ref = (make_solver("QP", "piqp", drop_fixed=True) for _ in range(2))
    for s in (fast, ref):
        s.setup_native(pr.P, pr.q, A_eq, pr.b_eq, G, pr.bl, pr.bu, pr.lb, pr.ub)
        s.solve()
    fast.update_native(A=A_eq, G=G)  # registers the read-only pattern (the first update checks it)
    ref.update_native(A=A_eq, G=G)
    lb, ub = pr.lb.copy(), pr.ub.copy()
    k = int(np.flatnonzero(lb == ub)[0])
    steps = []
    for step in range(6):
        A_eq.data[:] = A_eq.data * rng.uniform(0.9, 1.1, A_eq.nnz)
        G.data[:] = G.data * rng.uniform(0.9, 1.1, G.nnz)
        bl, bu = pr.bl - rng.uniform(0, 0.1, pr.bl.size), pr.bu + rng.uniform(0, 0.1, pr.bu.size)
        b = A_eq @ np.where(lb == ub, 0.0, rng.uniform(-0.2, 0.2, lb.size))
        if step == 2:  # a new set of fixed variables
            lb, ub = lb.copy(), ub.copy()
            lb[k], ub[k] = -1.0, 1.0
        if step == 3:
            bl = bl.copy()
            bl[0] = np.nan
        if step == 4:
            bl, bu = bl.copy(), bu.copy()
            bl[1], bu[1] = 1.0, 0.0
        fields = dict(A=A_eq, b=b, G=G, h_l=bl, h_u=bu, x_lb=lb, x_ub=ub)
        if step == 5:  # another pattern (a plain copy with writeable indices): the checked path
            fields["G"] = G.copy()
        fast.update_fast(**fields)
        assert (fast._data["h_l"] is bl) == (step != 5)  # the trusted path keeps the caller's vector
        ref.update_native(**{k_: (v.copy() if hasattr(v, "copy") else v) for k_, v in fields.items()})
        a, r = fast.solve(), ref.solve()
        assert a.status == r.status and a.info.get("rebuilt") == r.info.get("rebuilt")
        assert (a.x is None and r.x is None) or np.array_equal(a.x, r.x)
        steps.append(a.status)
        if a.status == SolveStatus.OPTIMAL:
            pr_k = QuadraticProgram(P=pr.P, q=pr.q, A_eq=A_eq, b_eq=b, A=G, bl=bl, bu=bu, lb=lb, ub=ub)
            np.testing.assert_allclose(a.x, solve_qp(pr_k, "clarabel").x, atol=1e-5)
    assert steps[3] == SolveStatus.NUMERICAL_ERROR and steps[4] == SolveStatus.INFEASIBLE
    assert steps[0] == steps[1] == steps[2] == steps[5] == SolveStatus.OPTIMAL
