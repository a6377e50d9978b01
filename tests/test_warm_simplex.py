"""Warm primal simplex (proxops.solvers.warm_simplex) against HiGHS solving each LP from scratch
(an independent engine): same optimal objective, feasible points; and the support polygons of
ConvexSection with and without it."""

import numpy as np
import pytest

from proxops.solvers import HighsLP, SolveStatus
from proxops.solvers.warm_simplex import WarmPrimalSimplex


def _random_lp(rng, m=30, n=12):
    """rl <= A x <= ru (some rows two-sided, some one-sided), box bounds; feasible by construction
    (x0 inside, rows around A x0)."""
    A = rng.normal(size=(m, n))
    x0 = rng.uniform(-0.5, 0.5, size=n)
    r0 = A @ x0
    ru = r0 + rng.uniform(0.1, 2.0, size=m)
    rl = np.where(rng.random(m) < 0.5, -np.inf, r0 - rng.uniform(0.1, 2.0, size=m))
    lb, ub = -np.ones(n), np.ones(n)
    lb[0] = -np.inf  # an unbounded-below column, bounded through the rows
    return A, rl, ru, lb, ub


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_warm_simplex_matches_cold_highs_over_many_costs(seed):
    rng = np.random.default_rng(seed)
    A, rl, ru, lb, ub = _random_lp(rng)
    n = A.shape[1]
    hot = HighsLP(settings={"presolve": "off", "solver": "simplex"})
    c0 = rng.normal(size=n)
    hot.setup(c0, A, rl, ru, lb, ub)
    first = hot.solve()
    assert first.ok
    cols, rows = hot.basis_status()
    warm = WarmPrimalSimplex(A, rl, ru, lb, ub, cols, rows, first.x)
    solved = 0
    for _ in range(60):
        c = c0 + 0.3 * rng.normal(size=n)  # nearby costs, as successive support directions
        c0 = c
        cold = HighsLP()
        cold.setup(c, A, rl, ru, lb, ub)
        ref = cold.solve()
        status, x = warm.solve(c)
        if ref.status is not SolveStatus.OPTIMAL:
            assert status is not SolveStatus.OPTIMAL or ref.status is SolveStatus.OPTIMAL
            continue
        assert status is SolveStatus.OPTIMAL
        solved += 1
        assert c @ x == pytest.approx(ref.objective, rel=1e-9, abs=1e-9)
        r = A @ x
        assert np.all(x >= lb - 1e-9) and np.all(x <= ub + 1e-9)
        assert np.all(r <= ru + 1e-9) and np.all(r >= rl - 1e-9)
    assert solved >= 50


def test_unbounded_direction_is_reported_not_returned():
    # min -x0 with x0 unbounded above and no row limiting it: the ray is reported
    A = np.array([[0.0, 1.0]])
    lb, ub = np.array([0.0, -1.0]), np.array([np.inf, 1.0])
    lp = HighsLP(settings={"presolve": "off", "solver": "simplex"})
    lp.setup(np.array([1.0, 0.0]), A, None, np.array([0.5]), lb, ub)
    res = lp.solve()
    warm = WarmPrimalSimplex(A, np.array([-np.inf]), np.array([0.5]), lb, ub, *lp.basis_status(), res.x)
    status, x = warm.solve(np.array([-1.0, 0.0]))
    assert status is SolveStatus.UNBOUNDED and x is None


def test_section_polygon_with_and_without_warm_simplex():
    """The backward section of reach (1 deg/s, 0.1 m/s^2): support points and the grid mask with
    the warm simplex equal those from HiGHS alone (every direction re-solved by HiGHS)."""
    from proxops.analysis import reach as R

    corridor = R.LosCorridor()
    grid = R.body_grid(corridor, 80, R.DEFAULT_GRID_Y_MAX_M)
    box = ((grid.x_m[0], grid.y_m[0]), (grid.x_m[-1], grid.y_m[-1]))
    masks, polys = [], []
    for use_warm in (True, False):
        sec = R.backward_section(corridor, np.radians(1.0), 0.1, box)
        if not use_warm:
            sec._start_warm = lambda x: None  # HiGHS for every support LP
        polys.append(sec.polygon(refine_tol=0.05 * (grid.x_m[1] - grid.x_m[0])))
        masks.append(sec.contains_grid(grid.x_m, grid.y_m)[0])
        assert (sec.n_warm > 0) is use_warm
    assert polys[0].vertices.shape == polys[1].vertices.shape
    np.testing.assert_allclose(polys[0].vertices, polys[1].vertices, rtol=0, atol=1e-8)
    np.testing.assert_array_equal(masks[0], masks[1])
