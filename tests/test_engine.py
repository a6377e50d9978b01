"""Closed-loop engine: exactness on a plant with a closed-form solution, records, events, save/load."""

import numpy as np
import pytest

from proxops.actuators import ThrusterModel
from proxops.navigation import GaussianNavigation
from proxops.sim.engine import Setup, simulate
from proxops.contracts import Command
from proxops.sim.result import SimResult
from proxops.dynamics.plant import PlantBase


class DoubleIntegrator(PlantBase):
    """3-D double integrator: exact ZOH solution r += v dt + a dt^2/2, v += a dt."""

    n_x, n_u = 6, 3

    def __init__(self, x0):
        self.x0 = np.asarray(x0, float)

    def initial_state(self):
        return self.x0.copy()

    def relative_state(self, s):
        return s

    def propagate(self, t, s, u, dt):
        r, v = s[:3], s[3:]
        return np.concatenate([r + v * dt + 0.5 * u * dt * dt, v + u * dt])

    def apply_impulse(self, t, s, dv):
        return np.concatenate([s[:3], s[3:] + dv])


class ConstantAccel:
    def __init__(self, a, dt=1.0, kind="acceleration", status="ok"):
        self.a, self.dt, self.kind, self.status = np.asarray(a, float), dt, kind, status

    def reset(self, t0, x0):
        self.reset_called = True

    def step(self, t, x):
        mode = "early" if t < 5 else "late"
        return Command(u=self.a, kind=self.kind, status=self.status, mode=mode, info={"t_seen": t})


class Sphere:
    name = "keep-out"

    def __init__(self, radius):
        self.radius = radius

    def violation(self, t, x):
        return max(0.0, self.radius - float(np.linalg.norm(x[:3])))


def test_constant_acceleration_matches_kinematics():
    a = np.array([0.01, -0.02, 0.005])
    setup = Setup(plant=DoubleIntegrator(np.zeros(6)), controller=ConstantAccel(a, dt=2.0), duration_s=20.0)
    res = simulate(setup)
    t_end = 20.0
    np.testing.assert_allclose(res.t[-1], t_end)
    np.testing.assert_allclose(res.x_true[-1, :3], 0.5 * a * t_end**2, rtol=1e-12)
    np.testing.assert_allclose(res.x_true[-1, 3:], a * t_end, rtol=1e-12)
    # cumulative dv of a constant acceleration = |a| t
    np.testing.assert_allclose(res.dv_cum[-1], np.linalg.norm(a) * t_end, rtol=1e-12)
    assert res.events_of("mode") and res.events_of("mode")[0][0] == pytest.approx(6.0)
    assert res.info["t_seen"][3] == pytest.approx(6.0)


def test_impulses_add_velocity_and_count_dv():
    dv = np.array([0.0, 0.1, 0.0])
    setup = Setup(plant=DoubleIntegrator(np.zeros(6)), controller=ConstantAccel(dv, dt=1.0, kind="impulse"), duration_s=5.0)
    res = simulate(setup)
    # 5 impulses of 0.1 m/s; position = sum_k 0.1 k * 1 s for k = 1..5
    np.testing.assert_allclose(res.dv_cum[-1], 0.5)
    np.testing.assert_allclose(res.x_true[-1, 1], 0.1 * (1 + 2 + 3 + 4 + 5))


def test_actuator_limit_and_min_impulse():
    rng = np.random.default_rng(0)
    th = ThrusterModel(max_per_axis=0.05, min_impulse=0.01)
    np.testing.assert_allclose(th.apply(0, np.array([0.2, -0.2, 0.0]), "impulse", rng), [0.05, -0.05, 0.0])
    np.testing.assert_allclose(th.apply(0, np.array([0.005, 0.0, 0.0]), "impulse", rng), 0.0)
    norm_limited = ThrusterModel(max_norm=1.0).apply(0, np.array([3.0, 4.0, 0.0]), "impulse", rng)
    np.testing.assert_allclose(norm_limited, [0.6, 0.8, 0.0])


def test_execution_errors_statistics():
    rng = np.random.default_rng(1)
    th = ThrusterModel(magnitude_sigma=0.05, pointing_sigma_rad=0.01, missed_probability=0.2)
    u = np.array([1.0, 0.0, 0.0])
    out = np.array([th.apply(0, u, "impulse", rng) for _ in range(20000)])
    fired = np.linalg.norm(out, axis=1) > 0
    assert abs(1 - fired.mean() - 0.2) < 0.01  # binomial sd 0.003
    mags = np.linalg.norm(out[fired], axis=1)
    assert abs(mags.std() - 0.05) < 0.003
    # pointing: angle from x axis ~ Rayleigh over the two perpendicular axes, rms = sqrt(2) sigma
    ang = np.arccos(np.clip(out[fired, 0] / mags, -1, 1))
    assert abs(np.sqrt(np.mean(ang**2)) - np.sqrt(2) * 0.01) < 0.001


def test_navigation_noise_and_events_and_roundtrip(tmp_path):
    plant = DoubleIntegrator([5.0, 0, 0, -1.0, 0, 0])
    setup = Setup(plant=plant, controller=ConstantAccel([0, 0, 0], dt=1.0, status="infeasible"), duration_s=10.0,
                  navigation=GaussianNavigation(0.5, 0.01), constraints=[Sphere(2.0)])
    res = simulate(setup, seed=3)
    err = res.x_est - res.x_true
    assert np.all(np.abs(err[:, :3]) < 0.5 * 6) and np.std(err[:, :3]) > 0.1
    kinds = [e[1] for e in res.events]
    assert "violation" in kinds and kinds.count("solver") == 10
    # crosses r = 2 m at t = 3 s and stays inside until r = -2 at t = 7 s: max violation 2 m at t = 5 s
    assert res.meta["max_violation"]["keep-out"] == pytest.approx(2.0)
    res.save(tmp_path / "r")
    back = SimResult.load(tmp_path / "r")
    np.testing.assert_array_equal(back.x_true, res.x_true)
    np.testing.assert_array_equal(back.x_est, res.x_est)
    assert back.events == res.events and back.status == res.status
    assert back.summary() == res.summary()


def test_same_seed_same_run_different_seed_differs():
    def run(seed):
        return simulate(Setup(plant=DoubleIntegrator(np.zeros(6)), controller=ConstantAccel([0, 0, 0]), duration_s=5.0,
                              navigation=GaussianNavigation(1.0, 0.1)), seed=seed).x_est

    np.testing.assert_array_equal(run(4), run(4))
    assert not np.array_equal(run(4), run(5))


def test_controller_stop_ends_run():
    class Stopper(ConstantAccel):
        def step(self, t, x):
            return Command(u=np.zeros(3), stop=t >= 3.0, mode="docked" if t >= 3.0 else "approach")

    res = simulate(Setup(plant=DoubleIntegrator(np.zeros(6)), controller=Stopper([0, 0, 0]), duration_s=100.0))
    assert res.meta["outcome"] == "docked" and res.t[-1] == pytest.approx(3.0)


def test_navigation_sigma_per_component():
    nav = GaussianNavigation(sigma=np.array([2.0, 0.0, 0.0, 0.0, 0.0, 0.5]))
    rng = np.random.default_rng(7)
    err = np.array([nav.measure(0.0, np.zeros(6), rng) for _ in range(20000)])
    np.testing.assert_array_equal(err[:, 1:5], 0.0)
    assert abs(err[:, 0].std() - 2.0) < 0.05 and abs(err[:, 5].std() - 0.5) < 0.0125


def test_units_named_from_key_suffix():
    from proxops.scenarios.loader import unit_of

    assert unit_of("mean_motion_rad_s") == "rad/s"
    assert unit_of("wheel_acc_max_deg_s2") == "deg/s^2"
    assert unit_of("tumble_rate_deg_s") == "deg/s"
    assert unit_of("a_max_mps2") == "m/s^2"
    assert unit_of("dt_s") == "s"
    assert unit_of("inertia_kgm2") == "kg m^2"
    assert unit_of("snap_impulse_Ns") == "N s"
    # _per_<unit> divides: by nothing (1/s) or by the unit of what comes before
    assert unit_of("alpha_per_s") == "1/s"
    assert unit_of("stiffness_N_per_m") == "N/m"
    assert unit_of("damping_Ns_per_m") == "N s/m"
    assert unit_of("rot_damping_Nms_per_rad") == "N m s/rad"
    # a drift per orbital period; a count per orbit stays unitless
    assert unit_of("drift_median_m_per_orbit") == "m/orbit"
    assert unit_of("samples_per_orbit") == ""


def test_pointing_rotation_matches_rotation_matrix():
    """Rodrigues on floats == the DCM of the same rotation vector (scipy's Rotation)."""
    from scipy.spatial.transform import Rotation

    from proxops.actuators import _rotate_small

    rng = np.random.default_rng(3)
    for _ in range(20):
        v, rv = rng.normal(size=3), 0.3 * rng.normal(size=3)
        np.testing.assert_allclose(_rotate_small(v, rv), Rotation.from_rotvec(rv).apply(v), atol=1e-14)
