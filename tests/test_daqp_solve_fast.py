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
