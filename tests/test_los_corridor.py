"""LOS corridor of tumbling-target-reachability.md eq. (9)-(10): rows, violations, frames.

Reference values come from the cone geometry itself (points placed on/inside/outside
the faces by construction), not from the code under test."""

import numpy as np
import pytest

from proxops.constraints.los_corridor import PAPER_TOLERANCE_M, LosCorridor, body_position, corridor_rows
from proxops.errors import ProxopsInputError

ALPHA = np.radians(30.0)


def test_rows_have_paper_shape_and_form():
    G, h = corridor_rows(ALPHA, 1.0, 8)
    assert G.shape == (9, 3) and h.shape == (9,)  # eq. (9): A_c in R^{9x3}
    for i in range(8):
        th = 2 * np.pi * i / 8
        # cos(th) x + sin(th) z - tan(alpha) y <= 0
        np.testing.assert_allclose(G[i], [np.cos(th), -np.tan(ALPHA), np.sin(th)], atol=1e-15)
        assert h[i] == 0.0
    np.testing.assert_array_equal(G[8], [0.0, -1.0, 0.0])
    assert h[8] == -1.0


def test_face_touch_points_are_on_the_boundary_and_circular_cone_is_inside():
    c = LosCorridor()
    y = 40.0
    for i in range(8):
        th = 2 * np.pi * i / 8
        p = np.array([np.cos(th), 0.0, np.sin(th)]) * np.tan(ALPHA) * y + np.array([0.0, y, 0.0])
        assert abs(c.slack_body(p)[i]) < 1e-12
        assert c.violation_body(p) < 1e-12
    # every point of the circular cone (radius tan(alpha) y) satisfies the circumscribed faces
    rng = np.random.default_rng(1)
    ys = rng.uniform(1.0, 300.0, 2000)
    phi = rng.uniform(0, 2 * np.pi, 2000)
    rad = np.tan(ALPHA) * ys * np.sqrt(rng.uniform(0, 1, 2000))
    pts = np.column_stack([rad * np.cos(phi), ys, rad * np.sin(phi)])
    assert np.all(c.violation_body(pts) <= 1e-12)


def test_violation_values_and_paper_tolerance():
    c = LosCorridor()
    y = 100.0
    excess = 0.5
    p = np.array([np.tan(ALPHA) * y + excess, y, 0.0])  # beyond face theta = 0 by 0.5 m in x
    assert c.violation_body(p) == pytest.approx(excess, abs=1e-12)
    assert c.violation_body([0.0, 0.25, 0.0]) == pytest.approx(0.75)  # floor y_B >= 1 m
    assert c.violation_body([0.0, 50.0, 0.0]) == 0.0
    assert c.tolerance_m == PAPER_TOLERANCE_M == 1e-3  # §9 step 3
    assert not c.is_violated_body([0.0, 1.0 - 0.9e-3, 0.0])
    assert c.is_violated_body([0.0, 1.0 - 1.1e-3, 0.0])


def test_rotating_frame_view_matches_eq_10():
    w = np.radians(3.0)

    def r_body_from_lvlh(t):  # F_B turned by w t about z relative to F_L: R_BL = R_z(-w t)
        a = -w * t
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1.0]])

    body = LosCorridor()
    lvlh = LosCorridor(frame="lvlh", rotation_body_from_frame=r_body_from_lvlh)
    rng = np.random.default_rng(2)
    for t in (0.0, 7.0, 33.0):
        R_LB = r_body_from_lvlh(t).T
        for _ in range(20):
            p_B = rng.uniform([-60, -5, -60], [60, 120, 60])
            x_L = np.concatenate([R_LB @ p_B, np.zeros(3)])
            assert lvlh.violation(t, x_L) == pytest.approx(body.violation_body(p_B), abs=1e-9)
            G_L, h = body.rows_in_frame(r_body_from_lvlh(t))
            np.testing.assert_allclose(G_L @ x_L[:3] - h, body.G @ p_B - body.h, atol=1e-9)
    np.testing.assert_allclose(body_position(R_LB @ [1.0, 2.0, 3.0], r_body_from_lvlh(33.0)), [1, 2, 3], atol=1e-12)


@pytest.mark.parametrize(
    "kwargs",
    [dict(half_angle_rad=0.0), dict(half_angle_rad=2.0), dict(y_min_m=-1.0), dict(n_faces=2), dict(frame="lvlh")],
)
def test_bad_input_is_a_clear_error(kwargs):
    with pytest.raises(ProxopsInputError):
        LosCorridor(**kwargs)
