"""Attitude navigation in the closed loops (issue 28 items 4-5): the pose-attitude sensor's noise and
field of view, the los body-frame estimate in the estimated target frame, the planar pose EKF's
consistency against an independent solve_ivp truth, and navigation.model = ekf for los and
underactuated through the CLI."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.stats import chi2
from typer.testing import CliRunner

from proxops.cli import app
from proxops.core.quaternion import quat_from_axis_angle, quat_multiply, quat_to_axis_angle
from proxops.navigation.consistency import mean_band
from proxops.navigation.mekf import PoseAttitudeSensor, attitude_error


def test_pose_sensor_noise_has_the_stated_sigma():
    """4000 draws: the error rotation vectors v (q_meas = q (x) exp(v/2)) have sum |v|^2 / sigma^2 inside
    the 99.9 % two-sided chi2(3 N) bounds and a mean within 4 standard errors of 0."""
    sigma, n = math.radians(0.5), 4000
    s = PoseAttitudeSensor(sigma_rad=sigma)
    rng = np.random.default_rng(1)
    q = quat_from_axis_angle([1.0, 2.0, -1.0], 1.3)
    v = np.array([attitude_error(q, s.draw(0.0, q, np.zeros(3), [0, 1, 0], rng)[0]) for _ in range(n)])
    lo, hi = chi2.ppf([0.0005, 0.9995], 3 * n)
    assert lo <= np.sum(v * v) / sigma ** 2 <= hi
    assert np.all(np.abs(v.mean(axis=0)) < 4 * sigma / math.sqrt(n))


def test_pose_sensor_fov_boundary_and_fixed_draws():
    """60 deg full cone about +y: 29.9 deg off axis is seen, 30.1 deg is not; a lost measurement draws
    the same numbers as a kept one (the stream is at the same place after both)."""
    s = PoseAttitudeSensor(sigma_rad=0.01, rate_sigma_rad_s=0.001, fov_rad=math.radians(60.0),
                           boresight=np.array([0.0, 2.0, 0.0]))
    q, w = np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)
    a, b = np.random.default_rng(3), np.random.default_rng(3)
    inside = [math.sin(math.radians(29.9)), math.cos(math.radians(29.9)), 0.0]
    outside = [math.sin(math.radians(30.1)), math.cos(math.radians(30.1)), 0.0]
    qa, wa = s.draw(0.0, q, w, inside, a)
    qb, wb = s.draw(0.0, q, w, outside, b)
    assert qa is not None and wa is not None and qb is None and wb is None
    assert a.random() == b.random()


def _truth(t):
    """A target spinning at 2 deg/s about body z from a tilted initial attitude."""
    w = np.array([0.0, 0.0, math.radians(2.0)])
    q0 = quat_from_axis_angle([0.3, -0.2, 1.0], 0.7)
    return quat_multiply(q0, quat_from_axis_angle([0.0, 0.0, 1.0], w[2] * t)), w


def test_los_state_in_the_estimated_frame():
    """With the estimate off by a yaw psi about z_B (and no measurement to correct it), the navigation
    returns r_B^ = R_z(psi)^T r_B, v_B^ = R_z(psi)^T v_B (the spin commutes with R_z), reports psi, and the
    controller's Hill reconstruction R_z(theta + psi) r_B^ equals the true R_z(theta) r_B."""
    from proxops.navigation.target_attitude import TargetAttitudeNavigation
    from proxops.dynamics.tumbling_target import rot_z

    sensor = PoseAttitudeSensor(sigma_rad=0.01, outage_probability=1.0)  # never measured
    nav = TargetAttitudeNavigation(_truth, sensor, np.eye(6) * 1e-30, np.ones(3), 0.0)
    rng = np.random.default_rng(0)
    x = np.array([3.0, 40.0, -2.0, 0.1, -0.2, 0.05])
    np.testing.assert_allclose(nav.measure(0.0, x, rng), x, atol=1e-9)
    psi = math.radians(4.0)
    q0, w = _truth(0.0)
    nav.filter.reset(quat_multiply(q0, quat_from_axis_angle([0.0, 0.0, 1.0], psi)), w, np.eye(6) * 1e-6)
    est = nav.measure(7.0, x, rng)
    R = rot_z(psi)
    np.testing.assert_allclose(est[:3], R.T @ x[:3], atol=1e-9)
    np.testing.assert_allclose(est[3:], R.T @ x[3:], atol=1e-9)
    assert nav.frame_angle_error() == pytest.approx(psi, abs=1e-8)  # RK4 over 7 s
    theta = 0.8
    np.testing.assert_allclose(rot_z(theta + psi) @ est[:3], rot_z(theta) @ x[:3], atol=1e-9)
    axis, ang = quat_to_axis_angle(quat_multiply(_truth(7.0)[0] * [-1, -1, -1, 1], nav.filter.q))
    assert ang == pytest.approx(psi, abs=1e-8)


def _planar_rhs(p, u, noise):
    """Planar CubeSat dynamics written from underactuated-docking-nmpc.md eqs. 1, 2, 4 (Hill x radial),
    with an added constant disturbance ``noise`` = [a_x, a_y, alpha] over the piece."""
    n, m, D, Iz = p.mean_motion_rad_s, p.mass_kg, p.wheel_inertia_kgm2, p.body_inertia_kgm2

    def f(t, s):
        x, y, th, vx, vy, om = s
        return [vx, vy, om, 3 * n * n * x + 2 * n * vy + math.cos(th) * u[0] / m + noise[0],
                -2 * n * vx + math.sin(th) * u[0] / m + noise[1], -D * u[1] / Iz + noise[2]]

    return f


def test_planar_pose_ekf_consistent_against_independent_truth():
    """20 runs x 60 steps of 2 s with random commands (thrust, wheel acceleration) held per step: truth by
    solve_ivp (rtol 1e-11) of the planar equations with white acceleration / angular acceleration noise of
    the filter's PSDs (piecewise constant over 1 s pieces); pose measurements 2 cm, 1 deg, 10 % outages.
    The run-averaged NEES (6 dof) over all steps lies in the 95 % band of a 20-run mean; so does the
    attitude-block NEES (2 dof); NIS in the pooled 99.9 % chi2(3) band."""
    from proxops.dynamics.planar_cubesat import PlanarCubeSatParams
    from proxops.navigation.planar_ekf import PlanarPoseEKF

    p = PlanarCubeSatParams()
    runs, steps, dt, pieces = 20, 60, 2.0, 2
    qa, qw = 1e-6, 1e-6
    rng = np.random.default_rng(8)
    p0 = np.diag([0.2 ** 2] * 2 + [math.radians(3.0) ** 2] + [0.02 ** 2] * 2 + [math.radians(0.2) ** 2])
    nees = np.zeros((runs, steps))
    nees_att = np.zeros((runs, steps))
    nis = []
    for r in range(runs):
        f = PlanarPoseEKF(p, p0, 0.02, math.radians(1.0), q_accel_m2_s3=qa, q_angular_rad2_s3=qw,
                          outage_probability=0.1, gate_probability=1 - 1e-12)
        s = np.array([5.0, -30.0, 0.3, 0.1, 0.5, 0.01])
        f.measure(0.0, s, rng)
        for k in range(steps):
            u = np.array([rng.uniform(-0.2, 0.2), rng.uniform(-5.0, 5.0) * (1 if abs(s[5]) < 0.02 else -np.sign(s[5]))])
            f.command(k * dt, u, "acceleration")
            h = dt / pieces
            for j in range(pieces):
                noise = rng.standard_normal(3) * np.sqrt(np.array([qa, qa, qw]) / h)
                s = solve_ivp(_planar_rhs(p, u, noise), (0.0, h), s, method="DOP853", rtol=1e-11, atol=1e-12).y[:, -1]
            f.measure((k + 1) * dt, s, rng)
            nees[r, k] = f.record["pose_nees"][-1]
            nees_att[r, k] = f.record["nees"][-1]
        nis.extend(f.record["nis"])
    lo, hi = mean_band(runs, 6)
    assert lo <= nees.mean(axis=0).mean() <= hi, nees.mean()
    lo2, hi2 = mean_band(runs, 2)
    assert lo2 <= nees_att.mean(axis=0).mean() <= hi2, nees_att.mean()
    nis = np.asarray(nis)
    lo_n, hi_n = chi2.ppf([0.0005, 0.9995], nis.size * 3) / nis.size
    assert lo_n <= nis.mean() <= hi_n, nis.mean()


@pytest.mark.parametrize("name", ["los-tumble", "underactuated-case1"])
def test_validate_accepts_ekf_and_rejects_bad_attitude_input(name):
    ok = CliRunner().invoke(app, ["validate", name, "--set", "navigation.model=ekf"])
    assert ok.exit_code == 0, ok.stderr
    bad = CliRunner().invoke(app, ["validate", name, "--set", "navigation.model=ekf",
                                   "--set", "navigation.attitude_sigma_deg=0"])
    lines = [ln for ln in bad.stderr.splitlines() if ln.strip()]
    assert bad.exit_code == 2 and len(lines) == 1 and "navigation.attitude_sigma_deg" in lines[0], bad.stderr


def test_los_ekf_closed_loop_reports_attitude_consistency():
    """los-tumble-ekf over 150 s: the corridor holds (feasible, no violation) and the per-tick attitude
    NEES lies inside its per-epoch 95 % chi2(6) band at >= 85 % of the ticks (95 % expected); the
    attitude error stays below 3 sigma of the measurement (1.5 deg) after the first 10 s."""
    from proxops import api

    summary, results = api.run(api.load_scenario("los-tumble-ekf", ["sim.duration_s=150"]), seed=3)
    assert summary["feasible"] and summary["los_violations"] == 0
    assert summary["att_nees_band"] == pytest.approx(list(chi2.ppf([0.025, 0.975], 6)))
    assert summary["att_nees_inside_fraction"] >= 0.85, summary["att_nees_inside_fraction"]
    rec = results["run"].meta["attitude_filter"]
    assert len(rec["nees"]) == 151
    assert max(rec["att_err_rad"][10:]) < math.radians(1.5)
