"""Relative-navigation EKF, re-initialisation after a filter collapse (issue 17): the inverse
measurement model, today's limit (an overconfident filter never recovers on its own), recovery
with re-initialisation by Monte Carlo (error bound and NEES in chi-square bounds), the windowed NIS
test (trips on a persistently high NIS, rarely on a consistent filter), the filter on a longer
state layout, and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2
from typer.testing import CliRunner

from proxops.cli import app
from proxops.core.cw import cw_stm, mean_motion
from proxops.core.layout import Block, StateLayout
from proxops.navigation.ekf import RelativeEKF, SensorModel, range_bearing

N_LEO = mean_motion(6378137.0 + 500e3)
DT = 2.0


@pytest.mark.parametrize("kind", ["pose", "range-bearing"])
def test_position_from_inverts_the_measurement_model(kind):
    """position_from(h(x)) = r exactly; its covariance J R J^T matches the sample covariance of
    positions from 5000 noisy measurements at 75 m (first order: within 8 %)."""
    s = SensorModel(kind=kind, range_sigma_m=0.05, angle_sigma_rad=1e-3)
    x = np.array([20.0, -70.0, 15.0, 0.0, 0.0, 0.0])
    r, cov = s.position_from(s.h(x))
    np.testing.assert_allclose(r, x[:3], atol=1e-9)
    rng = np.random.default_rng(11)
    sig = s.sigma(float(np.linalg.norm(x[:3])))
    pts = np.array([s.position_from(s.h(x) + sig * rng.standard_normal(3))[0] for _ in range(5000)])
    sample = np.cov(pts.T)
    assert np.linalg.norm(sample - cov) / np.linalg.norm(cov) < 0.08
    if kind == "range-bearing":  # independent check of the angles: the position reproduces [range, az, el]
        np.testing.assert_allclose(range_bearing(-r), s.h(x), atol=1e-12)


def _collapsed_run(k, kind="pose", seed=0, steps=150, err=None, sigma_truth=None, sigma_filter=0.05):
    """Filter alone on CW truth (no process noise) started with an error ``err`` far outside its
    initial covariance (1 m, 1 mm/s per axis). Returns (times, position errors, velocity errors,
    NEES) and the filter."""
    rng = np.random.default_rng(seed)
    truth_sensor = SensorModel(kind=kind, range_sigma_m=sigma_truth or sigma_filter, angle_sigma_rad=1e-3)
    sensor = SensorModel(kind=kind, range_sigma_m=sigma_filter, angle_sigma_rad=1e-3)
    ekf = RelativeEKF(N_LEO, sensor, np.diag([1.0] * 3 + [1e-6] * 3), q_m2_s3=1e-10, reinit_after_rejections=k,
                      reinit_velocity_sigma_mps=0.1)
    x = np.array([0.0, -75.0, 0.0, 0.0, 0.0, 0.0])
    ekf.reset(0.0, x + (np.r_[40.0, -30.0, 10.0, 0.05, -0.03, 0.02] if err is None else err))
    phi = cw_stm(N_LEO, DT)
    out = np.zeros((steps, 4))
    for i in range(steps):
        t = (i + 1) * DT
        x = phi @ x
        ekf.propagate(t)
        ekf.update(t, truth_sensor.draw(t, x, rng))
        e = x - ekf.x
        out[i] = (t, np.linalg.norm(e[:3]), np.linalg.norm(e[3:]), e @ np.linalg.solve(ekf.P, e))
    return out, ekf


@pytest.mark.parametrize("kind", ["pose", "range-bearing"])
def test_without_reinit_a_collapsed_filter_stays_diverged(kind):
    """Today's limit (reinit off): 51 m / 6 cm/s of initial error against a 1 m / 1 mm/s covariance;
    the gate rejects all 150 measurements (300 s) and the error never comes below its initial 51 m
    (the CW drift of the velocity error makes it grow)."""
    out, ekf = _collapsed_run(0, kind)
    assert ekf.rejected == 150 and ekf.updates == 0 and ekf.reinits == 0
    assert out[:, 1].min() >= 51.0 and out[-1, 1] > out[0, 1]
    assert not [e for e in ekf.events if e[0] == "nav-reinit"]


@pytest.mark.parametrize("kind", ["pose", "range-bearing"])
def test_reinit_recovers_within_a_stated_bound_and_time(kind):
    """50 runs, initial errors N(0, 30 m) / N(0, 3 cm/s) per axis against a 1 m / 1 mm/s covariance,
    k = 3: three rejections (2, 4, 6 s) declare the collapse and the measurement at 8 s restarts the
    filter in every run. By t = 40 s every run is within 0.25 m and 1 cm/s (sensor: 5 cm,
    1 mrad at 75 m), and from 30 s to 120 s the run-averaged NEES lies inside its two-sided 99 %
    chi-square bounds (chi2(300)/50) at >= 90 % of the steps: the re-initialised covariance is
    consistent, not only small."""
    runs = 50
    nees = []
    at_40 = []
    for seed in range(runs):
        rng = np.random.default_rng(1000 + seed)
        err = np.r_[rng.normal(0.0, 30.0, 3), rng.normal(0.0, 0.03, 3)]
        out, ekf = _collapsed_run(3, kind, seed=seed, steps=60, err=err)
        first = next(e for e in ekf.events if e[0] == "nav-reinit")
        assert "t = 8 s" in first[1], first
        at_40.append(out[out[:, 0] == 40.0][0, 1:3])
        nees.append(out[(out[:, 0] >= 30.0) & (out[:, 0] <= 120.0), 3])
    at_40 = np.array(at_40)
    assert at_40[:, 0].max() < 0.25 and at_40[:, 1].max() < 0.01, at_40.max(axis=0)
    mean_k = np.mean(nees, axis=0)
    lo, hi = chi2.ppf([0.005, 0.995], runs * 6) / runs
    assert np.mean((mean_k >= lo) & (mean_k <= hi)) >= 0.9, (mean_k.min(), mean_k.max(), lo, hi)


def test_a_persistently_high_nis_trips_the_collapse_test_without_rejections():
    """The filter assumes 5 cm but the sensor has 10 cm: NIS ~ 4 x chi2(3), so about 85 % of the single
    measurements pass the 0.9999 gate (21.1), but the mean over k = 10 (~ 12) exceeds
    chi2.ppf(0.9999, 30) / 10 = 6.0: the filter re-initialises without 10 rejections in a row."""
    _, ekf = _collapsed_run(10, "pose", seed=3, steps=100, err=np.zeros(6), sigma_truth=0.1)
    assert ekf.reinits >= 1
    assert ekf.updates > ekf.rejected  # most measurements were accepted
    bound = chi2.ppf(0.9999, 30) / 10
    assert ekf.collapse_bound == pytest.approx(bound)


def test_a_consistent_filter_rarely_reinitialises():
    """False alarms of the windowed test: a consistent filter (matched noise, initial error drawn
    from its covariance), 60 runs x 100 measurements, k = 5: each window of independent NIS trips
    with probability 1e-4 (~ 0.58 expected over the 5760 windows); at most 4 (Poisson: 99.96 %)."""
    total = 0
    for seed in range(60):
        rng = np.random.default_rng(500 + seed)
        err = np.r_[rng.normal(0.0, 1.0, 3), rng.normal(0.0, 1e-3, 3)]
        _, ekf = _collapsed_run(5, "pose", seed=seed, steps=100, err=err)
        total += ekf.reinits
    assert total <= 4, total


def test_the_filter_estimates_the_hill_blocks_of_a_longer_layout():
    """A plant whose state is [mass, r, v, extra]: the filter reads and writes the position and
    velocity blocks (same estimate as on the plain Hill state with the same draws) and passes the
    other components through."""
    layout = StateLayout(9, (Block("mass", "mass", 0, 1), Block("position", "position", 1, 4),
                             Block("velocity", "velocity", 4, 7), Block("extra", "other", 7, 9)))
    hill = np.array([5.0, -60.0, 2.0, 0.01, 0.0, -0.002])
    full = np.r_[480.0, hill, 7.0, 8.0]
    kw = dict(sensor=SensorModel(kind="range-bearing"), p0=np.eye(6) * 0.5, q_m2_s3=1e-10)
    a, b = RelativeEKF(N_LEO, layout=layout, **kw), RelativeEKF(N_LEO, **kw)
    ra, rb = np.random.default_rng(4), np.random.default_rng(4)
    for t in (0.0, 2.0, 4.0):
        ea, eb = a.measure(t, full, ra), b.measure(t, hill, rb)
        np.testing.assert_array_equal(ea[1:7], eb)
        np.testing.assert_array_equal(ea[[0, 7, 8]], full[[0, 7, 8]])


def test_a_layout_without_a_hill_state_is_refused():
    from proxops.errors import ProxopsInputError

    planar = StateLayout(4, (Block("position", "position", 0, 2), Block("velocity", "velocity", 2, 4)))
    with pytest.raises(ProxopsInputError, match="navigation.model"):
        RelativeEKF(N_LEO, SensorModel(), np.eye(6), layout=planar)


SK = ["station-keeping", "--set", "truth.model=cw", "--set", "sim.duration_s=300", "--set", "navigation.model=ekf"]


@pytest.mark.parametrize("args, fragment", [
    (["--set", "navigation.reinit_after_rejections=-1"], "navigation.reinit_after_rejections"),
    (["--set", "navigation.reinit_after_rejections=2.5"], "navigation.reinit_after_rejections"),
    (["--set", "navigation.reinit_velocity_sigma_mps=0"], "navigation.reinit_velocity_sigma_mps"),
])
def test_bad_reinit_input_is_one_line_exit_2(args, fragment):
    res = CliRunner().invoke(app, ["run", *SK, *args])
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.exit_code == 2, (res.exit_code, res.stderr, res.exception)
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in res.stderr, res.stderr
    assert fragment in lines[0], lines[0]


def test_reinit_in_a_closed_loop_is_an_engine_event():
    """station-keeping on the filter with a 50 % confidence: the collapse bound chi2.ppf(0.5, 9) / 3
    = 2.78 lies below the expected mean NIS 3, so windows trip about half the time: the run records
    nav-reinit events, counted in the summary's nav_reinits."""
    import json

    res = CliRunner().invoke(app, ["run", *SK, "--set", "navigation.reinit_after_rejections=3",
                                   "--set", "navigation.gate_probability=0.5", "--set", "navigation.sensor=pose",
                                   "--json"])
    s = json.loads(res.stdout)
    assert s["nav_reinits"] >= 1 and s["events"].get("nav-reinit", 0) == s["nav_reinits"]
    assert math.isfinite(s["nav_position_error_m"]["max"])
