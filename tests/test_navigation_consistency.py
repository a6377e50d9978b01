"""Navigation consistency (issue 28): chi-square bands, the innovation-whiteness test that finds an
overconfident filter the NIS misses, the actuator's execution-error covariance, the nonlinear J2
process model, the range-bearing update on the z axis, and the NEES/NIS in a run's summary."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from proxops.core.cw import cw_stm, mean_motion
from proxops.navigation.consistency import WhitenessMonitor, chi2_band, consistency_stats, mean_band
from proxops.navigation.ekf import RelativeEKF, SensorModel, cw_process_noise, range_bearing

N_LEO = mean_motion(6378137.0 + 500e3)


def test_mean_band_is_the_issue_table_band():
    """Issue 28's table: '95 % band of a 20-run mean 4.58-7.61' for the 6-state NEES."""
    lo, hi = mean_band(20, 6)
    assert (round(lo, 2), round(hi, 2)) == (4.58, 7.61)


def test_mean_band_covers_means_of_correlated_epochs():
    """The campaign band (chi2(N d)/N) holds the mean over N runs of time-averaged chi2(6) NEES whatever the
    correlation of the epochs: 20 runs of 200 epochs, each run an AR(1) chain of Gaussian errors (rho 0.98)
    whose NEES is chi2(6) at every epoch; 500 campaigns: at least 95 % inside (the band is conservative
    for correlated epochs, module docstring), and the independent-epoch band chi2(N d K)/(N K) fails."""
    rng = np.random.default_rng(5)
    n_runs, k, rho, d, campaigns = 20, 200, 0.98, 6, 500
    lo, hi = mean_band(n_runs, d)
    lo_k, hi_k = mean_band(n_runs * k, d)
    e = rng.standard_normal((campaigns, n_runs, d))
    total = (e * e).sum(axis=2)
    for _ in range(1, k):
        e = rho * e + math.sqrt(1 - rho * rho) * rng.standard_normal((campaigns, n_runs, d))
        total += (e * e).sum(axis=2)
    m = (total / k).mean(axis=1)  # each campaign's mean over runs of the runs' time-mean NEES
    inside = int(np.sum((lo <= m) & (m <= hi)))
    inside_k = int(np.sum((lo_k <= m) & (m <= hi_k)))
    assert inside / campaigns >= 0.95
    assert inside_k / campaigns < 0.5


def test_consistency_stats_of_chi_square_draws():
    """Independent chi2(6) draws: about 95 % of the epochs inside the per-epoch band (binomial 4-sigma
    tolerance on 20000 draws) and the verdict consistent; 4x the draws (overconfident) is not."""
    rng = np.random.default_rng(2)
    v = chi2.rvs(6, size=20000, random_state=rng)
    s = consistency_stats(v, 6)
    assert s["band"] == pytest.approx(list(chi2.ppf([0.025, 0.975], 6)))
    assert abs(s["in_band"] - 0.95) < 4 * math.sqrt(0.95 * 0.05 / 20000)
    assert s["consistent"]
    assert not consistency_stats(4 * v, 6)["consistent"]


def test_whiteness_statistic_is_standard_normal_for_white_innovations():
    """z over windows of 100 i.i.d. N(0, I_3) samples: mean 0 and standard deviation 1 (3000 windows,
    4-sigma tolerances of the sample mean and of the sample standard deviation)."""
    rng = np.random.default_rng(11)
    z = np.array([WhitenessMonitor.statistic(rng.standard_normal((100, 3)), 10) for _ in range(3000)])
    tol = 4 / math.sqrt(z.size)
    assert abs(z.mean()) < tol
    assert abs(z.std() - 1.0) < 4 * math.sqrt(0.5 / z.size) + 0.02  # + O(1/W) small-sample bias


def _cw_run(q_true, q_filter, seed, steps=400, dt=10.0):
    """Filter alone on CW truth driven by white acceleration of PSD q_true; range-bearing sensor whose
    noise dominates S. Returns (mean NEES, mean NIS, the filter)."""
    rng = np.random.default_rng(seed)
    sensor = SensorModel(kind="range-bearing", range_sigma_m=0.5, angle_sigma_rad=1e-3)
    p0 = np.diag([1.0] * 3 + [1e-4] * 3)
    ekf = RelativeEKF(N_LEO, sensor, p0, q_m2_s3=q_filter, gate_probability=1 - 1e-12)
    lq, phi = np.linalg.cholesky(cw_process_noise(N_LEO, dt, q_true)), cw_stm(N_LEO, dt)
    x = np.array([30.0, -300.0, 10.0, 0.0, 0.0, 0.0])
    ekf.reset(0.0, x + np.linalg.cholesky(p0) @ rng.standard_normal(6))
    nees = []
    for k in range(steps):
        t = (k + 1) * dt
        x = phi @ x + lq @ rng.standard_normal(6)
        ekf.propagate(t)
        ekf.update(t, sensor.draw(t, x, rng))
        e = x - ekf.x
        nees.append(e @ np.linalg.solve(ekf.P, e))
    return float(np.mean(nees)), float(np.mean(ekf.nis)), ekf


def test_filter_with_100x_too_little_process_noise_is_flagged():
    """Issue 28: process noise 100x too small. Its NEES is far above the 6-state band, its NIS per
    epoch mostly inside its band (measurement noise dominates S), but the innovation-whiteness test
    flags it in every one of 6 runs of 400 samples (z of the whole run above the 99.99 % bound, at least
    one window event). The correctly tuned filter on the same truth and draws: no window flagged in 6 runs
    (false alarm 0.01 % per window by construction, 4 windows a run) and its NEES inside the 6-run band."""
    q = 1e-9
    bad = [_cw_run(q, q / 100, seed) for seed in range(6)]
    good = [_cw_run(q, q, seed) for seed in range(6)]
    assert np.mean([b[0] for b in bad]) > 10 * mean_band(6, 6)[1]
    for _, nis, ekf in bad:
        assert consistency_stats(ekf.nis, 3)["in_band"] > 0.9  # the per-epoch NIS does not see it
        assert ekf.monitor.z_all() > ekf.monitor.bound
        assert ekf.overconfident_windows >= 1
        assert any(kind == "nav-overconfident" for kind, _ in ekf.events)
    lo, hi = mean_band(6, 6)
    assert lo <= np.mean([g[0] for g in good]) <= hi
    assert sum(g[2].overconfident_windows for g in good) == 0


def test_execution_covariance_matches_sampled_errors():
    """ThrusterModel.execution_covariance against the sample second moment of apply() - limited():
    10 % magnitude, 1 deg pointing, eq. (29) angles 1 deg / 2 deg, 5 % missed thrusts; 40000 draws,
    tolerance 5 % of the largest entry (sampling ~1 %, first-order angles ~0.1 %)."""
    from proxops.actuators import ThrusterModel

    act = ThrusterModel(magnitude_sigma=0.1, pointing_sigma_rad=math.radians(1.0), missed_probability=0.05,
                        elevation_sigma_rad=math.radians(1.0), azimuth_sigma_rad=math.radians(2.0))
    u = np.array([0.3, -0.5, 0.2])
    rng = np.random.default_rng(4)
    d = np.array([act.apply(0.0, u, "impulse", rng) - u for _ in range(40000)])
    sample = d.T @ d / len(d)
    cov = act.execution_covariance(u)
    np.testing.assert_allclose(cov, sample, atol=0.05 * np.abs(sample).max())
    assert not act.execution_covariance(np.zeros(3)).any()


def test_hill_predictor_is_cw_in_the_linear_limit():
    """Without J2, a 5 m offset on a circular orbit over 600 s: the nonlinear prediction equals the CW
    transition to O(rho / r) ~ 1e-6 relative (independent model: the closed-form CW STM)."""
    from proxops.frames.elements import OrbitalElements
    from proxops.propagation.relative_predictor import HillPredictor

    a = 6378137.0 + 500e3
    pred = HillPredictor(OrbitalElements(a, 0.0, 0.9, 0.1, 0.2, 0.3), j2=False)
    x0 = np.array([2.0, -4.0, 1.0, 0.001, -0.002, 0.0005])
    cw = cw_stm(mean_motion(a), 600.0) @ x0
    got = pred.predict(0.0, x0, np.zeros(3), "impulse", 600.0)
    np.testing.assert_allclose(got[:3], cw[:3], atol=5e-5)
    np.testing.assert_allclose(got[3:], cw[3:], atol=5e-8)
    # an impulse at t0 is the same as starting with the velocity changed
    dv = np.array([0.01, 0.0, -0.02])
    np.testing.assert_allclose(pred.predict(0.0, x0, dv, "impulse", 600.0),
                               pred.predict(0.0, x0 + np.r_[0, 0, 0, dv], np.zeros(3), "impulse", 600.0), atol=1e-9)


@pytest.mark.parametrize("rho_dir", [(0.0, 0.0, 1.0), (0.0, 0.0, -1.0)])
def test_range_bearing_update_on_the_z_axis(rho_dir):
    """Target exactly on the orbit normal (rho_x = rho_y = 0, the azimuth's singular point): the update
    uses the unit line of sight, stays finite, keeps P symmetric positive definite and, with a noise-free
    measurement, moves the estimate towards the truth (P^-1-norm error smaller: a Kalman update with
    z = h(x_true) contracts it)."""
    sensor = SensorModel(kind="range-bearing", range_sigma_m=0.1, angle_sigma_rad=1e-3)
    p0 = np.diag([4.0] * 3 + [1e-4] * 3)
    ekf = RelativeEKF(N_LEO, sensor, p0, q_m2_s3=0.0)
    x_true = np.r_[-100.0 * np.array(rho_dir), 0.0, 0.0, 0.0]  # chaser at -rho
    x_est = x_true + np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])  # estimate on the axis too
    ekf.reset(0.0, x_est)
    assert sensor.near_pole(ekf.x)
    z = range_bearing(-x_true[:3])  # az = atan2(0, 0) = 0, el = +-90 deg
    e0 = x_true - ekf.x
    ekf.update(0.0, z)
    assert np.all(np.isfinite(ekf.x)) and np.all(np.isfinite(ekf.P))
    np.testing.assert_allclose(ekf.P, ekf.P.T, atol=0.0)
    assert np.linalg.eigvalsh(ekf.P).min() > 0
    e1 = x_true - ekf.x
    assert e1 @ np.linalg.solve(p0, e1) < e0 @ np.linalg.solve(p0, e0)
    assert abs(e1[2]) < 0.01  # the range (along z) is measured to 0.1 m: the 1 m error is removed


def test_line_of_sight_update_agrees_with_angles_off_the_axis():
    """Where both forms are valid (0.9 deg from the z axis, inside the unit-line-of-sight zone; position
    sigma 0.01 m << the 1.6 m distance from the axis), the line-of-sight update and the azimuth/elevation
    update with the same tangent-plane noise give the same estimate to a small fraction of the posterior
    sigma (independent parametrisations of one measurement)."""
    sensor = SensorModel(kind="range-bearing", range_sigma_m=0.05, angle_sigma_rad=2e-4)
    p0 = np.diag([1e-4] * 3 + [1e-6] * 3)
    ang = math.radians(0.9)
    x_true = np.r_[-100.0 * np.array([math.sin(ang), 0.0, math.cos(ang)]), 0.0, 0.0, 0.0]
    rng = np.random.default_rng(8)
    z = range_bearing(-x_true[:3]) + np.array([0.05, 2e-4, 2e-4]) * rng.standard_normal(3)
    x_est = x_true + np.array([0.01, -0.01, 0.005, 0.0, 0.0, 0.0])
    los = RelativeEKF(N_LEO, sensor, p0, q_m2_s3=0.0)
    los.reset(0.0, x_est)
    assert sensor.near_pole(los.x)
    los.update(0.0, z)
    # the angle form, written out (the filter's update without the pole branch), with the same isotropic
    # tangent-plane noise: an azimuth sigma of sigma / cos(el) moves the line of sight by sigma
    zhat, H = sensor.h_and_jacobian(x_est)
    sig_r, sig_a, sig_e = sensor.sigma(float(np.linalg.norm(x_est[:3])))
    S = H @ p0 @ H.T + np.diag([sig_r ** 2, (sig_a / math.cos(zhat[2])) ** 2, sig_e ** 2])
    x_ang = x_est + p0 @ H.T @ np.linalg.solve(S, sensor.residual(z, zhat))
    sig = np.sqrt(np.diag(los.P))
    assert np.all(np.abs(los.x - x_ang)[:3] < 0.05 * sig[:3])


def test_run_records_nees_at_the_filter_ticks(tmp_path):
    """station-keeping-ekf, 600 s: the engine stores the filter's NEES on the samples of its ticks; the
    last one equals e^T P^-1 e computed here from the SimResult's x_true, x_est and the filter's final P;
    the summary's mean and bands are those of the stored series (chi2(6) / chi2(3) 95 % bands), and they
    survive save/load."""
    from proxops.scenarios.loader import load_scenario
    from proxops.sim.engine import simulate
    from proxops.sim.result import SimResult

    loaded = load_scenario("station-keeping-ekf", ["sim.duration_s=600"])
    setup = loaded.system.build(loaded.scenario)
    res = simulate(setup, seed=3)
    nees = res.info["nav_nees"]
    assert np.all(np.isfinite(nees))  # one filter tick per control sample
    e = res.x_true[-1] - res.x_est[-1]
    assert nees[-1] == pytest.approx(e @ np.linalg.solve(setup.navigation.P, e), rel=1e-9)
    s = res.summary()
    assert s["nav_nees_mean"] == pytest.approx(float(np.mean(nees)))
    assert s["nav_nees_band"] == pytest.approx(list(chi2.ppf([0.025, 0.975], 6)))
    assert s["nav_nis_band"] == pytest.approx(list(chi2.ppf([0.025, 0.975], 3)))
    assert s["nav_nis_epochs"] == int(np.isfinite(res.info["nav_nis"]).sum()) > 50
    assert s["nav_consistent"] in (True, False) and s["nav_overconfident_windows"] >= 0
    back = SimResult.load(res.save(tmp_path / "run"))
    a, b = back.consistency_summary(), res.consistency_summary()
    assert a.keys() == b.keys()
    for key in a:
        assert np.asarray(a[key], dtype=float) == pytest.approx(np.asarray(b[key], dtype=float), nan_ok=True), key


def test_campaign_consistency_uses_the_band_of_the_campaign_size():
    """navigation_consistency on a table of 30 runs: band chi2(30 d)/30; the verdict needs the mean inside
    it and >= 90 % of all epochs inside their per-epoch band."""
    import pandas as pd

    from proxops.analysis.statistics import navigation_consistency

    def table(mean, in_band):
        rows = {"outcome": ["completed"] * 30, "metric.nav_nees_mean": [mean] * 30, "metric.nav_nees_dim": [6] * 30,
                "metric.nav_nees_epochs": [100] * 30, "metric.nav_nees_in_band": [in_band] * 30}
        return pd.DataFrame(rows)

    good = navigation_consistency(table(6.1, 0.95))
    assert good["nees"]["band"] == pytest.approx(list(chi2.ppf([0.025, 0.975], 180) / 30))
    assert good["nees"]["epochs"] == 3000 and good["consistent"]
    assert not navigation_consistency(table(chi2.ppf(0.975, 180) / 30 + 0.01, 0.95))["consistent"]
    assert not navigation_consistency(table(6.0, 0.89))["consistent"]
    assert navigation_consistency(pd.DataFrame({"outcome": ["completed"]})) is None
