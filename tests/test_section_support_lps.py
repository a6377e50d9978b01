"""Support LPs of ConvexSection (proxops.geometry.polytope), solved by DAQP's LP mode, against HiGHS
solving each LP from scratch (an independent engine): same support values, feasible support
points; the section polygon and grid mask with DAQP equal those from HiGHS alone; an empty section
is reported empty (DAQP's infeasibility is confirmed by HiGHS)."""

import math

import numpy as np
import pytest

from proxops.analysis import reach as R
from proxops.geometry.polytope import ConvexSection
from proxops.solvers import HighsLP, SolveStatus
from proxops.solvers.result import SolverResult


def _reach_section(omega_deg_s, a_max, n_points=80):
    corridor = R.LosCorridor()
    grid = R.body_grid(corridor, n_points, R.DEFAULT_GRID_Y_MAX_M)
    box = ((grid.x_m[0], grid.y_m[0]), (grid.x_m[-1], grid.y_m[-1]))
    return R.backward_section(corridor, np.radians(omega_deg_s), a_max, box), grid


def _cold_support(sec, d):
    """max d.p over the section by a fresh HiGHS model (default settings, presolve on)."""
    c = np.zeros(sec.n_var)
    c[:2] = -d
    lp = HighsLP()
    lp.setup_native(c, sec.A, None, sec.b, sec.lb, sec.ub)
    res = lp.solve()
    assert res.status is SolveStatus.OPTIMAL
    return -res.objective


@pytest.mark.parametrize("omega_deg_s,a_max", [(1.0, 0.1), (4.0, 0.05), (2.0, 0.2)])
def test_daqp_support_values_match_cold_highs(omega_deg_s, a_max):
    sec, _ = _reach_section(omega_deg_s, a_max)
    scale = 1.0 + np.abs(sec.ub[:2]).max()  # m: the box size
    for ang in np.linspace(0.0, 2 * np.pi, 37):  # 10 deg steps; both ends (a repeated direction)
        d = np.array([math.cos(ang), math.sin(ang)])
        status, p = sec.support_point(d)
        assert status is SolveStatus.OPTIMAL
        assert d @ p == pytest.approx(_cold_support(sec, d), abs=1e-9 * scale)
        # the support point itself lies in the section (HiGHS feasibility LP with p fixed)
        assert sec._point_feasible(p)
        sec._set(lb=sec.lb, ub=sec.ub)
    assert sec.n_highs == 0  # every direction settled by DAQP


def test_section_polygon_and_mask_with_and_without_daqp():
    """The backward section of reach (1 deg/s, 0.1 m/s^2): support values and the grid mask with
    DAQP equal those from HiGHS alone (DAQP disabled, every direction re-solved by HiGHS)."""
    masks, polys, n_highs = [], [], []
    for use_daqp in (True, False):
        sec, grid = _reach_section(1.0, 0.1)
        if not use_daqp:  # DAQP "fails" every support LP: HiGHS settles all of them
            sec.support_lp.solve = lambda: SolverResult(status=SolveStatus.NUMERICAL_ERROR, x=None,
                                                        objective=math.nan, iterations=0, solve_time_s=0.0,
                                                        solver="daqp")
        polys.append(sec.polygon(refine_tol=0.05 * (grid.x_m[1] - grid.x_m[0])))
        masks.append(sec.contains_grid(grid.x_m, grid.y_m)[0])
        n_highs.append(sec.n_highs)
    assert n_highs[0] == 0 and n_highs[1] == len(polys[1].support)
    # the same directions (the refinement depends only on support values) and support values
    np.testing.assert_allclose(polys[0].directions, polys[1].directions, rtol=0, atol=1e-12)
    np.testing.assert_allclose(polys[0].support, polys[1].support, rtol=0, atol=1e-8)
    np.testing.assert_array_equal(masks[0], masks[1])
    assert 0 < masks[0].sum() < masks[0].size  # a boundary crosses the grid: the comparison has teeth


def test_empty_section_is_reported_empty():
    # x0 + x1 <= -1 with x0, x1 >= 0: no point; DAQP says infeasible, HiGHS confirms
    sec = ConvexSection(np.array([[1.0, 1.0, 0.0]]), np.array([-1.0]), np.zeros(3), np.ones(3))
    poly = sec.polygon(n_directions=8)
    assert poly.empty and poly.vertices.shape == (0, 2)
    assert sec.n_highs == 1
    mask, n_point = sec.contains(np.array([[0.0, 0.0], [0.5, 0.5]]))
    assert not mask.any() and n_point == 0


def test_box_change_reaches_the_support_lps():
    # unit square section (no rows binding); shrinking the box moves the support point
    sec = ConvexSection(np.array([[1.0, 1.0]]), np.array([10.0]), np.zeros(2), np.ones(2))
    np.testing.assert_allclose(sec.support_point([1.0, 1.0])[1], [1.0, 1.0], atol=1e-9)
    sec.set_box(np.array([0.0, 0.0]), np.array([0.25, 0.5]))
    status, p = sec.support_point([1.0, 1.0])
    assert status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(p, [0.25, 0.5], atol=1e-9)
    assert sec.n_highs == 0


@pytest.mark.parametrize("extra", [0, 1])
def test_support_lps_beyond_the_daqp_size_go_to_highs(extra):
    """A random section with SUPPORT_DAQP_MAX_VARIABLES (+1) variables: DAQP up to the limit, HiGHS
    beyond it; support values equal cold HiGHS either way."""
    rng = np.random.default_rng(7)
    n = ConvexSection.SUPPORT_DAQP_MAX_VARIABLES + extra
    A = rng.normal(size=(30, n))
    x0 = rng.uniform(-0.5, 0.5, n)
    b = A @ x0 + rng.uniform(0.1, 1.0, 30)  # x0 strictly inside
    sec = ConvexSection(A, b, -np.ones(n), np.ones(n))
    assert (sec.support_lp is None) is bool(extra)
    dirs = [np.array([math.cos(t), math.sin(t)]) for t in np.linspace(0.0, 2 * np.pi, 6, endpoint=False)]
    for d in dirs:
        status, p = sec.support_point(d)
        assert status is SolveStatus.OPTIMAL
        assert d @ p == pytest.approx(_cold_support(sec, d), abs=1e-8)
    assert sec.n_highs == (len(dirs) if extra else 0)
