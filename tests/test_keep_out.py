"""Keep-out sphere and its CBF (srf-hopping-mpc.md eqs. 26-28): values by hand, gradients by
finite differences, soundness of the supporting half-space by sampling."""

import numpy as np
import pytest

from proxops.constraints.keep_out import KeepOutSphere
from proxops.errors import ProxopsInputError


def test_barrier_values_by_hand():
    koz = KeepOutSphere(50.0, [10.0, 0.0, 0.0])
    x = np.array([10.0, 100.0, 0.0, 0.0, -1.0, 0.5])
    assert koz.h(x) == pytest.approx(100.0**2 - 50.0**2)  # eq. (26)
    assert koz.h_dot(x) == pytest.approx(2 * (100.0 * -1.0))  # eq. (27)
    assert koz.cbf_value(x, 0.01) == pytest.approx(-200.0 + 0.01 * 7500.0)  # eq. (28)


def test_violation_is_depth_inside_in_metres():
    koz = KeepOutSphere(50.0)
    assert koz.violation(0.0, np.array([0.0, 30.0, 40.0, 0, 0, 0])) == pytest.approx(0.0, abs=1e-12)
    assert koz.violation(0.0, np.array([0.0, 20.0, 0.0, 0, 0, 0])) == pytest.approx(30.0)
    assert koz.violation(0.0, np.array([0.0, 0.0, -80.0, 0, 0, 0])) == pytest.approx(-30.0)
    assert koz.contains([0.0, 49.0, 0.0]) and not koz.contains([0.0, 51.0, 0.0])


def test_halfspace_is_inside_the_outside_of_the_sphere():
    koz = KeepOutSphere(50.0, [5.0, -3.0, 2.0])
    rng = np.random.default_rng(1)
    refs = rng.normal(size=(20, 3)) * 200.0
    n, b = koz.halfspace(refs)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    for ni, bi in zip(n, b):
        pts = rng.normal(size=(2000, 3)) * 300.0
        inside_half = pts @ ni >= bi
        assert np.all(koz.distance_to_surface(pts[inside_half]) >= -1e-9)
        tangent = koz.center_m + koz.radius_m * ni  # touches the sphere
        assert tangent @ ni == pytest.approx(bi)


def test_cbf_linearization_gradient_matches_finite_differences():
    koz = KeepOutSphere(40.0, [1.0, 2.0, 3.0])
    x0 = np.array([60.0, -20.0, 10.0, 0.1, -0.3, 0.05])
    alpha = 0.02
    grad, g0 = koz.cbf_linearization(x0, alpha)
    assert g0 == pytest.approx(koz.cbf_value(x0, alpha))
    eps = 1e-5
    fd = np.array([(koz.cbf_value(x0 + eps * e, alpha) - koz.cbf_value(x0 - eps * e, alpha)) / (2 * eps)
                   for e in np.eye(6)])
    np.testing.assert_allclose(grad, fd, rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize("radius", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_radius(radius):
    with pytest.raises(ProxopsInputError, match="radius_m"):
        KeepOutSphere(radius)


def test_bad_center_and_degenerate_reference():
    with pytest.raises(ProxopsInputError, match="center_m"):
        KeepOutSphere(10.0, [0.0, 0.0])
    with pytest.raises(ProxopsInputError, match="reference"):
        KeepOutSphere(10.0).halfspace([0.0, 0.0, 0.0])


def _brute_segment_minima(t, x, center):
    """Every segment's minimum distance to ``center``: both samples and the 19 interior points of
    the cubic Hermite interpolant, evaluated in numpy (the definition, no skipping)."""
    s = np.linspace(0.0, 1.0, 21)[1:-1, None]
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    out = []
    for k in range(len(t) - 1):
        dt = t[k + 1] - t[k]
        pts = h00 * x[k, :3] + h10 * dt * x[k, 3:6] + h01 * x[k + 1, :3] + h11 * dt * x[k + 1, 3:6]
        ends = np.linalg.norm(x[k:k + 2, :3] - center, axis=1)
        out.append(min(ends.min(), np.linalg.norm(pts - center, axis=1).min()))
    return np.array(out)


@pytest.mark.parametrize("seed", range(6))
def test_hermite_minimum_and_first_entry_skip_nothing_that_matters(seed):
    """The jitted minimum and first-entry search skip segments by a bound from their samples; on
    random drifts (CW free drift plus noise, samples 10-60 s apart, some passing through the sphere)
    they give exactly the brute-force values: the minimum over every segment and the first segment
    whose minimum is below the radius."""
    from proxops.constraints.keep_out import KeepOutSphere
    from proxops.constraints.passive_safety import drift_safety, first_entry_time, hermite_min_range
    from proxops.core.cw import cw_stm

    rng = np.random.default_rng(seed)
    n = 0.00113
    x0 = np.concatenate([rng.uniform(-300, 300, 3), rng.uniform(-0.3, 0.3, 3)])
    t = np.cumsum(np.concatenate([[0.0], rng.uniform(10.0, 60.0, 400)]))
    x = np.array([cw_stm(n, tk) @ x0 for tk in t]) + rng.normal(0.0, 0.01, (t.size, 6))
    center = rng.uniform(-50, 50, 3) if seed % 2 else np.zeros(3)
    ref = _brute_segment_minima(t, x, center)
    assert hermite_min_range(t, x, center) == ref.min()
    radius = float(np.quantile(ref, 0.02 + 0.1 * seed))  # 2-52 % of the segments dip below it
    k_in = np.nonzero(np.linalg.norm(x[:, :3] - center, axis=1) < radius)[0]
    last = k_in[0] if k_in.size else len(t) - 1
    dips = np.nonzero(ref[:last] < radius)[0]
    expected = t[dips[0]] if dips.size else (t[k_in[0]] if k_in.size else np.inf)
    assert first_entry_time(t, x, center, radius) == expected
    safety = drift_safety(t, x, KeepOutSphere(radius, center))
    assert safety["min_koz_distance_m"] == ref.min() - radius
    assert safety["min_range_m"] == _brute_segment_minima(t, x, np.zeros(3)).min()
