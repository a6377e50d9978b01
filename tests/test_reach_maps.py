"""Monte Carlo feasibility maps (tumbling-target-reachability.md §9): IC grid, classification
rule, natural-neighbour interpolation, and a tiny closed-loop campaign."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.spatial import cKDTree

from proxops.analysis import feasibility_maps as F
from proxops.analysis import reach as R
from proxops.constraints.los_corridor import LosCorridor
from proxops.errors import ProxopsInputError


def test_ic_grid_is_the_papers():
    """§9.1: 15 x 13 = 195 ICs, y in [20, 300] m, x within +-0.95 tan(30 deg) y, all inside the corridor."""
    p = F.mc_initial_positions()
    assert p.shape == (195, 3)
    ys = np.unique(p[:, 1])
    np.testing.assert_allclose(ys, np.linspace(20, 300, 15))
    t = np.tan(np.radians(30))
    for y in ys:
        xs = np.sort(p[p[:, 1] == y, 0])
        assert len(xs) == 13
        np.testing.assert_allclose([xs[0], xs[-1]], [-0.95 * t * y, 0.95 * t * y])
    assert np.all(LosCorridor().slack_body(p) > 0)
    with pytest.raises(ProxopsInputError):
        F.mc_initial_positions(fill=1.5)


def test_classification_rule():
    """§9.3: feasible only with no violation > 1e-3 m, a feasible QP throughout and no early stop."""
    rows = pd.DataFrame({
        "outcome": ["success", "failure", "failure", "failure", "error", "success"],
        "metric.los_violations": [0, 3, 0, 0, np.nan, 0],
        "metric.max_violation_m": [0.0, 0.2, 0.0, 0.0, np.nan, 5e-4],
        "metric.qp_infeasible": [False, False, True, False, np.nan, False],
        "metric.outcome": ["completed", "completed", "qp_infeasible", "stopped", None, "hold_reached"],
    })
    assert F.classify_rows(rows).tolist() == [True, False, False, False, False, True]


def _sibson_reference(sites, values, q, half=25.0, n=600):
    """Sibson coordinates by brute force: area stolen from each site's Voronoi cell by q."""
    g = np.linspace(-half, half, n)
    X, Y = np.meshgrid(q[0] + g, q[1] + g)
    P = np.column_stack([X.ravel(), Y.ravel()])
    d_old, i_old = cKDTree(sites).query(P)
    stolen = np.hypot(P[:, 0] - q[0], P[:, 1] - q[1]) < d_old
    w = np.bincount(i_old[stolen], minlength=len(sites)).astype(float)
    return float(w @ values / w.sum())


def test_natural_neighbour_against_brute_force_sibson_and_linear_precision():
    rng = np.random.default_rng(7)
    sites = rng.uniform(0, 100, (40, 2))
    values = rng.uniform(0, 1, 40)
    x = np.linspace(0, 100, 201)
    y = np.linspace(0, 100, 201)
    out = F.natural_neighbour_grid(sites, values, x, y)
    # data reproduced at sites lying on grid nodes
    on = np.array([[x[20], y[40]], [x[150], y[100]]])
    s2 = np.vstack([sites, on])
    v2 = np.append(values, [0.25, 0.75])
    out2 = F.natural_neighbour_grid(s2, v2, x, y)
    assert out2[40, 20] == pytest.approx(0.25, abs=1e-12) and out2[100, 150] == pytest.approx(0.75, abs=1e-12)
    # Sibson coordinates against the brute-force stolen-area definition (inside the hull)
    from scipy.spatial import Delaunay

    tri = Delaunay(sites)
    checked = 0
    for i, j in ((60, 60), (100, 80), (120, 140), (90, 110), (70, 130)):
        q = np.array([x[j], y[i]])
        if tri.find_simplex(q) < 0:
            continue
        assert out[i, j] == pytest.approx(_sibson_reference(sites, values, q), abs=0.01)
        checked += 1
    assert checked >= 3
    # linear precision: Sibson coordinates reproduce linear functions exactly (Sibson 1980)
    lin = F.natural_neighbour_grid(sites, 0.01 * sites[:, 0] + 0.02 * sites[:, 1], x, y)
    Xg, Yg = np.meshgrid(x, y)
    inside = tri.find_simplex(np.column_stack([Xg.ravel(), Yg.ravel()])).reshape(Xg.shape) >= 0
    assert np.max(np.abs(lin - (0.01 * Xg + 0.02 * Yg))[inside]) < 1e-9
    # outside the hull: nearest neighbour
    outside = ~inside
    _, idx = cKDTree(sites).query(np.column_stack([Xg[outside], Yg[outside]]))
    np.testing.assert_array_equal(out[outside], values[idx])


def test_certification_check_counts():
    grid = R.body_grid(n_points=30)
    sites = np.array([[0.0, 50.0], [0.0, 250.0], [-50.0, 150.0], [50.0, 150.0]])
    outcomes = pd.DataFrame({"omega_deg_s": 1.0, "a_max_mps2": 0.2, "x_m": sites[:, 0], "y_m": sites[:, 1],
                             "feasible": [True, False, True, False]})
    fmap = F.feasibility_map(outcomes, grid, 1.0, 0.2)
    nominal = grid.inside.copy()
    chk = F.certification_check(fmap, grid, nominal, np.array([True, True, False, False]))
    assert chk["nominal_grid_points"] == int(grid.inside.sum())
    assert chk["nominal_grid_points_mc_infeasible"] == int(np.count_nonzero(grid.inside & ~fmap.mask))
    assert chk["nominal_ics_mc_infeasible"] == 1 and chk["nominal_ics"] == 2
    with pytest.raises(ProxopsInputError):
        F.feasibility_map(outcomes, grid, 3.0, 0.2)


def test_tiny_closed_loop_campaign(tmp_path):
    """Two ICs, one combination, 40 s of J2 truth: a start deep inside the nominal region stays
    feasible; the table carries the §9 columns and the campaign is written to disk."""
    pos = np.array([[-5.0, 30.0, 0.0], [0.0, 300.0, 0.0]])
    assert R.certified_mask(LosCorridor(), pos, np.radians(1.0), 0.2).tolist() == [True, True]
    table, wall, new = F.run_mc(tmp_path / "mc", omegas_deg_s=[1.0], a_max_mps2=[0.2], positions=pos,
                                duration_s=40.0, workers=1, progress=False)
    assert len(table) == 2 and wall > 0 and new == 2
    assert set(["omega_deg_s", "a_max_mps2", "x_m", "y_m", "feasible", "outcome"]).issubset(table.columns)
    np.testing.assert_allclose(table[["x_m", "y_m"]].to_numpy(), pos[:, :2])
    assert bool(table.loc[0, "feasible"])
    again = F.read_outcomes(tmp_path / "mc")
    assert again["feasible"].tolist() == table["feasible"].tolist()


def test_cached_sibson_coordinates_serve_any_values_and_the_hull_test():
    """The Sibson coordinates are computed once per (sites, queries) and reused for other values (the
    20 combinations of §9 share the IC sites): a second value set gives, bit for bit, what a fresh
    computation gives; ``inside_hull`` agrees with an independent half-plane test of the convex hull
    (scipy ConvexHull facets) away from its edges, and is all False without a 2-D hull."""
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(11)
    sites = rng.uniform(-40, 40, (30, 2)) + [0.0, 100.0]
    x, y = np.linspace(-60, 60, 121), np.linspace(40, 160, 101)
    first = F.natural_neighbour_grid(sites, rng.uniform(0, 1, 30), x, y)
    second_values = rng.uniform(0, 1, 30)
    cached = F.natural_neighbour_grid(sites, second_values, x, y)
    F._GEOMETRY_CACHE.clear()
    fresh = F.natural_neighbour_grid(sites, second_values, x, y)
    assert np.array_equal(cached, fresh) and not np.array_equal(first, fresh)
    Xg, Yg = np.meshgrid(x, y)
    q = np.column_stack([Xg.ravel(), Yg.ravel()])
    eq = ConvexHull(sites).equations  # a x + b y + c <= 0 inside
    dist = (q @ eq[:, :2].T + eq[:, 2]).max(axis=1)
    inside = F.inside_hull(sites, q)
    clear = np.abs(dist) > 1e-9
    np.testing.assert_array_equal(inside[clear], dist[clear] < 0)
    assert inside.any() and not inside.all()
    collinear = np.column_stack([np.linspace(0, 10, 5), np.linspace(0, 20, 5)])
    assert not F.inside_hull(collinear, q).any() and not F.inside_hull(sites[:2], q).any()
