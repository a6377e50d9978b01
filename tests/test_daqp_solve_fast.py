"""DaqpQP.solve_fast (the lean per-step solve used by the los MPC, issue 32 item 2) against closed forms."""

import numpy as np

from proxops.solvers import make_solver
from proxops.status import Status


def _box_qp(c, lo, hi):
    """min 1/2 |x|^2 - c'x s.t. lo <= x <= hi and the row x0 + x1 <= 10: optimum clip(c, lo, hi) while the row
    is slack (closed form)."""
    s = make_solver("QP", "daqp")
    s.setup_native(np.eye(3), None if c is None else -np.asarray(c, float), np.array([[1.0, 1.0, 0.0]]),
                   bu=np.array([10.0]), lb=np.asarray(lo, float), ub=np.asarray(hi, float))
    return s


def test_solve_fast_returns_the_box_clipped_optimum_and_tracks_bound_updates():
    c = np.array([0.5, -2.0, 3.0])
    s = _box_qp(c, [-1.0, -1.0, -1.0], [1.0, 1.0, 1.0])
    status, x, iters, wall, info = s.solve_fast()
    assert status is Status.OPTIMAL and info is None and wall >= 0.0 and iters >= 0
    np.testing.assert_allclose(x, [0.5, -1.0, 1.0], atol=1e-12)
    for lo, hi in (([-3.0, -3.0, -0.5], [0.2, 3.0, 2.5]), ([0.7, -0.5, 3.2], [0.8, 0.5, 4.0])):
        s.update_fast(lb=np.array(lo), ub=np.array(hi))
        status, x, _, _, info = s.solve_fast()
        assert status is Status.OPTIMAL and info is None
        np.testing.assert_allclose(x, np.clip(c, lo, hi), atol=1e-12)


def test_solve_fast_reports_an_infeasible_row_like_solve():
    s = _box_qp([0.0, 0.0, 0.0], [-1.0, -1.0, -1.0], [1.0, 1.0, 1.0])
    s.update_fast(bu=np.array([-3.0]))  # x0 + x1 <= -3 with x0, x1 >= -1: empty
    status, x, _, _, info = s.solve_fast()
    assert status is Status.INFEASIBLE and x is None and info["raw_status"].startswith("-1")
    assert s.solve().status is Status.INFEASIBLE


def test_solve_fast_after_crossed_bounds_takes_the_checked_path():
    s = _box_qp([0.0, 0.0, 0.0], [-1.0, -1.0, -1.0], [1.0, 1.0, 1.0])
    s.update(lb=np.array([2.0, -1.0, -1.0]))  # lb > ub on x[0]: refused before DAQP runs
    status, x, iters, _, info = s.solve_fast()
    assert status is Status.INFEASIBLE and x is None and iters == 0 and "crossed" in info["raw_status"]


def test_bounds_written_in_place_are_re_read_by_solve_bounds_fast():
    """bound_vectors() are DAQP's full vectors [ub; bu], [lb; bl]: bounds written into them in place reach the
    solve (box optimum clip(c, lo, hi); with the row x0 + x1 <= 1 active and c = (2, 2, 0.5): the projection
    (0.5, 0.5, 0.5), closed form)."""
    c = np.array([2.0, 2.0, 0.5])
    s = _box_qp(c, [-1.0, -1.0, -1.0], [1.0, 1.0, 1.0])
    assert s.solve_fast()[0] is Status.OPTIMAL
    for lo, hi in (([-3.0, -3.0, -0.5], [0.2, 3.0, 2.5]), ([0.7, -0.5, 3.2], [0.8, 0.5, 4.0])):
        upper, lower = s.bound_vectors()
        upper[:3], lower[:3] = hi, lo
        status, x, _, _, info = s.solve_bounds_fast()
        assert status is Status.OPTIMAL and info is None
        np.testing.assert_allclose(x, np.clip(c, lo, hi), atol=1e-12)
    upper, lower = s.bound_vectors()
    upper[:3], lower[:3], upper[3] = 5.0, -5.0, 1.0
    status, x, _, _, _ = s.solve_bounds_fast()
    assert status is Status.OPTIMAL
    np.testing.assert_allclose(x, [0.5, 0.5, 0.5], atol=1e-12)
    assert s._bu[0] == 1.0 and s._ub[2] == 5.0  # the per-field bounds are views of the vectors


def test_solve_bounds_fast_recovers_after_crossed_and_infeasible_bounds():
    """Crossed bounds written in place are refused by DAQP's own check (INFEASIBLE); so is an empty row;
    the next finite, consistent bounds rebuild the model (new vectors) and solve to the closed-form optimum."""
    c = np.array([0.5, -2.0, 3.0])
    s = _box_qp(c, [-1.0, -1.0, -1.0], [1.0, 1.0, 1.0])
    upper, lower = s.bound_vectors()
    lower[0] = 2.0  # lb > ub = 1 on x[0]
    status, x, _, _, _ = s.solve_bounds_fast()
    assert status is Status.INFEASIBLE and x is None
    upper, lower = s.bound_vectors()
    lower[0] = -1.0
    status, x, _, _, _ = s.solve_bounds_fast()
    assert status is Status.OPTIMAL
    np.testing.assert_allclose(x, [0.5, -1.0, 1.0], atol=1e-12)
    upper, lower = s.bound_vectors()
    upper[3] = -3.0  # x0 + x1 <= -3 with x0, x1 >= -1: empty
    status, x, _, _, info = s.solve_bounds_fast()
    assert status is Status.INFEASIBLE and x is None and info["raw_status"].startswith("-1")
    upper, lower = s.bound_vectors()
    upper[3] = 10.0
    upper[:3], lower[:3] = [0.2, 3.0, 2.5], [-3.0, -3.0, -0.5]
    status, x, _, _, _ = s.solve_bounds_fast()
    assert status is Status.OPTIMAL
    np.testing.assert_allclose(x, np.clip(c, [-3.0, -3.0, -0.5], [0.2, 3.0, 2.5]), atol=1e-12)
