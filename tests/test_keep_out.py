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
