"""The per-step paths written on plain floats (issue 18: thruster model, navigation noise, keep-out
check) give exactly the numbers and random draws of the array formulas they replace, written here
with numpy: saturation, sum of squares, magnitude and pointing errors, missed thrusts."""

import math

import numpy as np
import pytest

from proxops.actuators import ThrusterModel, _rotate_small
from proxops.constraints.keep_out import KeepOutSphere
from proxops.navigation import GaussianNavigation


def reference_apply(model: ThrusterModel, u, rng, t: float = 0.0, window: dict | None = None) -> np.ndarray:
    """ThrusterModel.apply as array operations (the general path, no norm limit / angle errors);
    ``window`` holds the per-window missed-thrust draw (Alg. 3: one draw per guidance window)."""
    u = np.array(u, dtype=float)
    if model.missed_window_s is not None and model.missed_probability > 0.0:
        w = math.floor(t / model.missed_window_s + 1e-9)
        if window.get("w") != w:
            window["w"], window["missed"] = w, bool(rng.random() < model.missed_probability)
        if window["missed"]:
            return np.zeros(3)
    if model.max_per_axis is not None:
        u = np.clip(u, -model.max_per_axis, model.max_per_axis)
    if not math.sqrt(u @ u) != 0.0:  # norm zero (or the squares underflow)
        return np.zeros(3)
    if model.missed_window_s is None and model.missed_probability > 0.0 and rng.random() < model.missed_probability:
        return np.zeros(3)
    if model.magnitude_sigma > 0.0:
        u *= 1.0 + model.magnitude_sigma * rng.standard_normal()
    if model.pointing_sigma_rad > 0.0:
        u = _rotate_small(u, model.pointing_sigma_rad * rng.standard_normal(3))
    return u


COMMANDS = [np.zeros(3), np.array([1e-200, 0.0, 0.0]), np.array([-0.0, 0.0, 0.0]), np.array([3.0, -4.0, 0.5]),
            np.array([0.2, 1e-9, -0.7]), np.array([5.0, -5.0, 5.0])]


@pytest.mark.parametrize("kw", [
    dict(max_per_axis=1.0, magnitude_sigma=0.01, pointing_sigma_rad=1e-3),
    dict(magnitude_sigma=0.05, missed_probability=0.3),
    dict(max_per_axis=0.5, pointing_sigma_rad=0.2, missed_probability=0.1),
    dict(magnitude_sigma=0.01, pointing_sigma_rad=1e-3, missed_probability=0.3, missed_window_s=10.0),
    dict(),
])
def test_thruster_float_path_equals_array_formulas(kw):
    model = ThrusterModel(**kw)
    gen = np.random.default_rng(7)
    cmds = COMMANDS + [gen.standard_normal(3) * 10.0 ** gen.uniform(-6, 2) for _ in range(200)]
    rng_a, rng_b = np.random.default_rng(42), np.random.default_rng(42)
    window: dict = {}
    for k, u in enumerate(cmds):
        t = 2.0 * k  # five commands per 10 s window
        got = model.apply(t, u, "acceleration", rng_a)
        want = reference_apply(model, u, rng_b, t, window)
        assert got.shape == (3,) and np.array_equal(got, want), (u, got, want)
    assert rng_a.random() == rng_b.random()  # the same number of draws


def test_thruster_nan_command_stays_nan_through_the_saturation():
    got = ThrusterModel(max_per_axis=1.0).apply(0.0, np.array([np.nan, 2.0, -3.0]), "acceleration",
                                                np.random.default_rng(0))
    assert np.isnan(got[0]) and got[1:].tolist() == [1.0, -1.0]


def test_navigation_noise_equals_sigma_times_standard_normal():
    nav = GaussianNavigation(position_sigma_m=0.3, velocity_sigma_mps=2e-3)
    x = np.array([100.0, -20.0, 3.0, 0.1, -0.2, 0.01])
    rng_a, rng_b = np.random.default_rng(3), np.random.default_rng(3)
    sigma = np.array([0.3] * 3 + [2e-3] * 3)
    for _ in range(50):
        assert np.array_equal(nav.measure(0.0, x, rng_a), x + (1.0 * sigma) * rng_b.standard_normal(6))


def test_keep_out_float_violation_equals_the_vector_distance():
    koz = KeepOutSphere(10.0, (1.0, -100.0, 2.5))
    pts = np.random.default_rng(5).normal(0.0, 60.0, (500, 6)) + np.array([1.0, -100.0, 2.5, 0, 0, 0])
    for x in pts:
        d = x[:3] - np.array([1.0, -100.0, 2.5])
        assert koz.violation(0.0, x) == -(math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) - 10.0)
        assert koz.violation(0.0, x) == pytest.approx(-float(koz.distance_to_surface(x[:3])), abs=1e-12)
