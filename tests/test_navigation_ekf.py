"""Relative-navigation EKF (issue 17): models against independent references, filter consistency
by Monte Carlo (NEES/NIS in their chi-square bounds), dropouts, perfect measurements, the engine
hooks and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.stats import chi2
from typer.testing import CliRunner

from proxops.cli import app
from proxops.core.cw import cw_matrices, cw_stm, mean_motion
from proxops.navigation.ekf import RelativeEKF, SensorModel, cw_process_noise, range_bearing, range_bearing_jacobian

N_LEO = mean_motion(6378137.0 + 500e3)


def test_process_noise_matches_quadrature():
    """Van Loan Q_d against direct quadrature of int Phi(s) B q B^T Phi(s)^T ds."""
    q, dt = 3e-9, 60.0
    _, b = cw_matrices(N_LEO)
    ref, _ = quad_vec(lambda s: cw_stm(N_LEO, s) @ b @ b.T @ cw_stm(N_LEO, s).T * q, 0.0, dt, epsabs=1e-20)
    np.testing.assert_allclose(cw_process_noise(N_LEO, dt, q), ref, rtol=1e-8, atol=1e-22)


def test_range_bearing_jacobian_finite_difference():
    rho = np.array([120.0, -340.0, 55.0])
    j = range_bearing_jacobian(rho)
    for i in range(3):
        d = np.zeros(3)
        d[i] = 1e-4
        fd = (range_bearing(rho + d) - range_bearing(rho - d)) / 2e-4
        np.testing.assert_allclose(j[:, i], fd, rtol=1e-6, atol=1e-12)


def test_range_law_is_the_cortex_form():
    """cortex §5.1.2: sigma(r) = s (0.02 + 0.98 r / r_ref); at r_ref it is s, at 0 it is 0.02 s."""
    s = SensorModel(kind="pose", range_sigma_m=0.3, sigma_reference_range_m=500.0, sigma_floor_fraction=0.02)
    assert s.sigma(500.0)[0] == pytest.approx(0.3)
    assert s.sigma(0.0)[0] == pytest.approx(0.006)
    assert s.sigma(250.0)[0] == pytest.approx(0.3 * (0.02 + 0.98 * 0.5))


def test_fov_boundary():
    """A target exactly inside / outside the half cone about the boresight (60 deg full cone)."""
    s = SensorModel(fov_rad=math.radians(60.0), boresight=np.array([0.0, 1.0, 0.0]))
    inside = np.radians(29.9)
    outside = np.radians(30.1)
    for ang, vis in ((inside, True), (outside, False)):
        rho = 100.0 * np.array([math.sin(ang), math.cos(ang), 0.0])
        assert s.visible(0.0, -rho) is vis


def _monte_carlo(sensor_kw, runs=200, steps=40, dt=10.0, q=1e-9, dropout=(), seed=7):
    """Filter alone on CW truth driven by the same white acceleration it assumes. Returns NEES
    (runs, steps), NIS list, position error norms and sqrt(trace P_pos) (runs, steps)."""
    rng = np.random.default_rng(seed)
    p0 = np.diag([4.0] * 3 + [1e-4] * 3)
    nees = np.zeros((runs, steps))
    pos_err = np.zeros((runs, steps))
    pos_sig = np.zeros((runs, steps))
    nis = []
    for r in range(runs):
        sensor = SensorModel(**sensor_kw)
        ekf = RelativeEKF(N_LEO, sensor, p0, q_m2_s3=q, gate_probability=1 - 1e-12)
        qd = cw_process_noise(N_LEO, dt, q)
        lq = np.linalg.cholesky(qd)
        phi = cw_stm(N_LEO, dt)
        x = np.array([30.0, -400.0, 10.0, 0.01, 0.02, -0.01])
        ekf.reset(0.0, x + np.linalg.cholesky(p0) @ rng.standard_normal(6))
        for k in range(steps):
            t = (k + 1) * dt
            x = phi @ x + lq @ rng.standard_normal(6)
            ekf.propagate(t)
            z = sensor.draw(t, x, rng)
            if z is not None and k not in dropout:
                ekf.update(t, z)
            e = x - ekf.x
            nees[r, k] = e @ np.linalg.solve(ekf.P, e)
            pos_err[r, k] = np.linalg.norm(e[:3])
            pos_sig[r, k] = math.sqrt(np.trace(ekf.P[:3, :3]))
        nis.extend(ekf.nis)
    return nees, np.array(nis), pos_err, pos_sig


@pytest.mark.parametrize("kind", ["range-bearing", "pose"])
def test_nees_and_nis_in_chi_square_bounds(kind):
    """200 runs x 40 steps: the run-averaged NEES at every step lies in its two-sided 99% chi-square
    bounds (chi2(200*6)/200) at >= 95% of the steps, and the averages over all steps/updates
    within the 99.9% bound of a pooled chi-square (NIS updates independent)."""
    kw = {"kind": kind, "range_sigma_m": 0.5, "angle_sigma_rad": 1e-3}
    runs, steps = 200, 40
    nees, nis, _, _ = _monte_carlo(kw, runs, steps)
    lo, hi = chi2.ppf([0.005, 0.995], runs * 6) / runs
    mean_k = nees.mean(axis=0)
    inside = np.mean((mean_k >= lo) & (mean_k <= hi))
    assert inside >= 0.95, (inside, mean_k.min(), mean_k.max(), lo, hi)
    lo_n, hi_n = chi2.ppf([0.0005, 0.9995], nis.size * 3) / nis.size
    assert lo_n <= nis.mean() <= hi_n, (nis.mean(), lo_n, hi_n)


def test_an_inconsistent_filter_fails_the_nees_test():
    """The test can fail: truth driven by 100x the assumed process noise leaves the NEES bounds."""
    rng = np.random.default_rng(3)
    dt, q = 10.0, 1e-9
    sensor = SensorModel(kind="pose", range_sigma_m=0.5)
    qd_true = cw_process_noise(N_LEO, dt, 100 * q)
    lq, phi = np.linalg.cholesky(qd_true), cw_stm(N_LEO, dt)
    nees = []
    for _ in range(50):
        ekf = RelativeEKF(N_LEO, sensor, np.diag([1.0] * 3 + [1e-4] * 3), q_m2_s3=q, gate_probability=1 - 1e-12)
        x = np.array([0.0, -300.0, 0.0, 0.0, 0.0, 0.0])
        ekf.reset(0.0, x.copy())
        for k in range(40):
            x = phi @ x + lq @ rng.standard_normal(6)
            ekf.propagate((k + 1) * dt)
            ekf.update((k + 1) * dt, sensor.draw(0.0, x, rng))
        e = x - ekf.x
        nees.append(e @ np.linalg.solve(ekf.P, e))
    assert np.mean(nees) > chi2.ppf(0.995, 50 * 6) / 50


def test_error_through_a_dropout_grows_as_the_covariance_says():
    """No update for 20 steps (200 s) from step 15: at the end of the dropout the RMS position
    error over 200 runs equals the RMS of sqrt(trace P_pos) within 10%, and it has grown."""
    nees, _, err, sig = _monte_carlo({"kind": "pose", "range_sigma_m": 0.5}, runs=200, steps=35, q=1e-8,
                                     dropout=range(15, 35))
    rms_err = np.sqrt(np.mean(err[:, -1] ** 2))
    rms_sig = np.sqrt(np.mean(sig[:, -1] ** 2))
    assert rms_err == pytest.approx(rms_sig, rel=0.10)
    assert rms_sig > 2.0 * np.sqrt(np.mean(sig[:, 14] ** 2))
    lo, hi = chi2.ppf([0.0005, 0.9995], 200 * 6) / 200
    assert lo <= nees[:, -1].mean() <= hi


@pytest.mark.parametrize("kind, error, sigma", [
    ("pose", [20.0, -15.0, 10.0, 0.05, -0.03, 0.04], (1e-9, 0.0)),
    # range-bearing from a small error: an EKF with near-zero R cannot absorb the linearisation
    # error of a 20 m start at 500 m (its covariance collapses first; the gate then rejects all)
    ("range-bearing", [0.2, -0.15, 0.1, 0.005, -0.003, 0.004], (1e-4, 1e-7)),
])
def test_perfect_measurements_converge_to_the_truth(kind, error, sigma):
    """Noise-free measurements of a noise-free CW arc: after 60 updates (600 s) the estimate is
    within 1 um and 1e-8 m/s of the truth, and nothing was rejected."""
    sensor = SensorModel(kind=kind, range_sigma_m=sigma[0], angle_sigma_rad=sigma[1])
    ekf = RelativeEKF(N_LEO, sensor, np.diag([400.0] * 3 + [2.5e-3] * 3), q_m2_s3=1e-14)
    x = np.array([50.0, -500.0, 20.0, 0.0, 0.1, 0.02])
    ekf.reset(0.0, x + np.array(error))
    for k in range(60):
        t = (k + 1) * 10.0
        x = cw_stm(N_LEO, 10.0) @ x
        ekf.propagate(t)
        ekf.update(t, sensor.h(x))
    assert ekf.rejected == 0
    assert np.linalg.norm(ekf.x[:3] - x[:3]) < 1e-6
    assert np.linalg.norm(ekf.x[3:] - x[3:]) < 1e-8


def test_gate_rejects_an_outlier_and_records_an_event():
    sensor = SensorModel(kind="pose", range_sigma_m=0.1)
    ekf = RelativeEKF(N_LEO, sensor, np.eye(6) * 1e-2, q_m2_s3=0.0, gate_probability=0.999)
    x = np.array([0.0, -100.0, 0.0, 0.0, 0.0, 0.0])
    ekf.reset(0.0, x)
    assert not ekf.update(0.0, x[:3] + np.array([50.0, 0.0, 0.0]))
    assert ekf.rejected == 1 and ekf.events[0][0] == "nav-rejected"
    np.testing.assert_array_equal(ekf.x, x)  # state untouched


def test_impulse_command_is_propagated():
    """An impulse commanded at t is in the prediction at t + dt (x = Phi (x + [0; dv]))."""
    sensor = SensorModel(kind="pose")
    ekf = RelativeEKF(N_LEO, sensor, np.eye(6), q_m2_s3=0.0)
    x0 = np.array([0.0, -100.0, 0.0, 0.0, 0.0, 0.0])
    ekf.reset(0.0, x0)
    dv = np.array([0.1, 0.0, -0.05])
    ekf.command(0.0, dv, "impulse")
    ekf.propagate(30.0)
    np.testing.assert_allclose(ekf.x, cw_stm(N_LEO, 30.0) @ (x0 + np.r_[0, 0, 0, dv]), atol=1e-12)
    ekf.propagate(60.0)  # not applied twice
    np.testing.assert_allclose(ekf.x, cw_stm(N_LEO, 60.0) @ (x0 + np.r_[0, 0, 0, dv]), atol=1e-10)


SK = ["station-keeping", "--set", "truth.model=cw", "--set", "sim.duration_s=300"]
EKF = ["--set", "navigation.model=ekf"]


def _run(args):
    return CliRunner().invoke(app, ["run", *args, "--json"])


def test_station_keeping_on_the_filter_reports_navigation_errors_and_is_reproducible():
    import json

    a, b = _run([*SK, *EKF]), _run([*SK, *EKF])
    assert a.exit_code == 0, a.output
    sa, sb = json.loads(a.stdout), json.loads(b.stdout)
    for key in ("nav_position_error_m", "nav_velocity_error_mps"):
        assert set(sa[key]) == {"median", "p95", "max"}
        assert sa[key] == sb[key]  # same seed, same draws
    assert sa["nav_rejected"] >= 0
    noise = json.loads(_run(SK).stdout)
    assert "nav_position_error_m" not in noise  # the noise model's summary is unchanged


def test_noise_stays_the_default_bit_identical():
    """model = "noise" given explicitly runs exactly the default (the filter hooks do not engage)."""
    import json

    a = json.loads(_run(SK).stdout)
    b = json.loads(_run([*SK, "--set", "navigation.model=noise"]).stdout)
    for key in ("total_dv_mps", "final_range_m", "min_range_m"):
        assert a[key] == b[key]


@pytest.mark.parametrize("args, fragment", [
    (["--set", "navigation.range_sigma_m=-1"], "navigation.range_sigma_m"),
    (["--set", "navigation.angle_sigma_deg=-0.1"], "navigation.angle_sigma_deg"),
    (["--set", "navigation.fov_deg=0"], "navigation.fov_deg"),
    (["--set", "navigation.fov_deg=180.5"], "navigation.fov_deg"),
    (["--set", "navigation.update_period_s=3"], "navigation.update_period_s"),
    (["--set", "navigation.update_period_s=20"], "navigation.update_period_s"),
    (["--set", "navigation.initial_covariance=[[1,2,0,0,0,0],[2,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],"
      "[0,0,0,0,1,0],[0,0,0,0,0,1]]"], "positive definite"),
])
def test_bad_navigation_input_is_one_line_exit_2(args, fragment):
    res = CliRunner().invoke(app, ["run", *SK, *EKF, *args])
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.exit_code == 2, (res.exit_code, res.stderr, res.exception)
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in res.stderr, res.stderr
    assert fragment in lines[0], lines[0]


def test_ekf_on_a_system_without_a_hill_state_is_refused():
    """The Hill-state filter itself refuses a system whose state is not the Hill state (los and
    underactuated run their own attitude filters on navigation.model = ekf: tests/test_navigation_attitude.py)."""
    from proxops.errors import ProxopsInputError
    from proxops.systems.common import navigation_model
    from proxops.scenarios.schema import NavigationSection

    with pytest.raises(ProxopsInputError, match="allowed: noise"):
        navigation_model(NavigationSection(model="ekf"), system="underactuated (planar state)")


@pytest.mark.parametrize("kind", ["range-bearing", "pose"])
def test_fused_measurement_model_matches_h_and_jacobian(kind):
    s = SensorModel(kind=kind)
    x = np.array([120.0, -340.0, 55.0, 0.1, 0.2, 0.3])
    zhat, H = s.h_and_jacobian(x)
    np.testing.assert_allclose(zhat, s.h(x), rtol=1e-14)
    np.testing.assert_allclose(H, s.jacobian(x), rtol=1e-14)


def test_eclipse_dropout_follows_the_eclipse_profile():
    """With eclipse_dropout the sensor gives nothing while proxops.environment.eclipse says the
    target is in umbra, and measures while it is in full sunlight (500 km, i = 0, one orbit)."""
    from proxops.environment.eclipse import eclipse_profile
    from proxops.scenarios.schema import OrbitSection
    from proxops.systems.common import target_elements, target_illumination

    orbit = OrbitSection(altitude_km=500.0)
    t, illum = eclipse_profile(target_elements(orbit), orbit.epoch_utc, n_per_orbit=200)
    lit = target_illumination(orbit)
    sensor = SensorModel(kind="pose", illuminated=lit)
    rng = np.random.default_rng(0)
    x = np.array([0.0, -100.0, 0.0, 0.0, 0.0, 0.0])
    assert (illum == 0).any() and (illum == 1).any()
    for tk, ik in zip(t[::5], illum[::5]):
        if ik in (0.0, 1.0):
            assert (sensor.draw(float(tk), x, rng) is None) == (ik == 0.0), tk


def test_impulse_execution_error_enters_the_velocity_covariance():
    """command_sigma_fraction f: P_vv grows by (f |dv|)^2 per axis at the burn (before the coast)."""
    sensor = SensorModel(kind="pose")
    ekf = RelativeEKF(N_LEO, sensor, np.eye(6) * 1e-6, q_m2_s3=0.0, command_sigma_fraction=0.02)
    ekf.reset(0.0, np.zeros(6))
    dv = np.array([0.3, 0.0, -0.4])
    ekf.command(0.0, dv, "impulse")
    ekf.propagate(20.0)
    p_expected = np.eye(6) * 1e-6
    p_expected[3:, 3:] += np.eye(3) * (0.02 * 0.5) ** 2
    phi = cw_stm(N_LEO, 20.0)
    np.testing.assert_allclose(ekf.P, phi @ p_expected @ phi.T, rtol=1e-12, atol=1e-18)


def test_rejections_in_a_closed_loop_are_engine_events():
    """A tight gate (50 %) rejects consistent measurements (and, once the accepted ones are biased
    small, nearly all: the reason the default gate is 0.9999): each one is a nav-rejected event
    of the run and counted in nav_rejected."""
    import json

    res = _run([*SK, *EKF, "--set", "navigation.gate_probability=0.5", "--set", "navigation.sensor=pose"])
    s = json.loads(res.stdout)
    assert s["events"].get("nav-rejected", 0) == s["nav_rejected"]
    assert s["nav_rejected"] >= 0.2 * s["steps"]


def test_the_filter_propagates_the_saturated_command():
    """With a thruster limit the filter gets the limited command (actuator.limited), not the raw
    one: station-keeping LQR at 1e-4 m/s^2 per axis saturates, and the filter stays within its
    gate (no rejection) on a CW truth."""
    import json

    s = json.loads(_run([*SK, *EKF, "--set", "actuator.max_per_axis=1e-4"]).stdout)
    assert s["nav_rejected"] == 0
    assert s["nav_position_error_m"]["max"] < 5.0  # 1 m initial sigma per axis: |e0| < 5 m


def test_limited_is_the_deterministic_part_of_apply():
    from proxops.actuators import ThrusterModel

    act = ThrusterModel(max_per_axis=0.5, max_norm=0.6, min_impulse=0.01)
    rng = np.random.default_rng(0)
    for u in ([1.0, -2.0, 0.1], [0.001, 0.0, 0.0], [0.2, 0.1, 0.0]):
        np.testing.assert_array_equal(act.limited(np.array(u)), act.apply(0.0, np.array(u), "impulse", rng))
    np.testing.assert_allclose(np.linalg.norm(act.limited(np.array([1.0, -2.0, 0.1]))), 0.6)


def test_sensor_faster_than_the_controller_multi_rate():
    """update_period_s = 5 s under a 10 s controller: the engine runs the filter on every 5 s tick
    (propagating the held acceleration between controller samples); CW truth: no rejection, and
    the p95 position error is below 1 m (sensor: 0.1 m range, 0.05 deg ~ 0.09 m across at 100 m;
    initial error 1 m per axis)."""
    import json

    s = json.loads(_run([*SK, *EKF, "--set", "navigation.update_period_s=5"]).stdout)
    assert s["steps"] == 60 and s["nav_rejected"] == 0
    assert s["nav_position_error_m"]["p95"] < 1.0
