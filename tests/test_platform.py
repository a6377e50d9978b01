"""Platform pieces: multi-rate schedule, per-component random streams, state layouts and
per-block navigation noise, status vocabulary."""

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from proxops.core.layout import Block, StateLayout
from proxops.core.quaternion import quat_angle_between
from proxops.dynamics.plant import PlantBase
from proxops.errors import ProxopsInputError
from proxops.navigation import GaussianNavigation, PerfectNavigation
from proxops.sim.engine import Setup, component_streams, schedule, simulate
from proxops.contracts import Command
from proxops.sim.result import SimResult
from proxops.status import Status, StopReason
from proxops.solvers import SolveStatus


class DoubleIntegrator(PlantBase):
    """3-D double integrator, exact ZOH flow."""

    n_x, n_u = 6, 3

    def initial_state(self):
        return np.array([100.0, -50.0, 20.0, 0.0, 0.1, 0.0])

    def relative_state(self, s):
        return s

    def propagate(self, t, s, u, dt):
        return np.concatenate([s[:3] + s[3:] * dt + 0.5 * u * dt * dt, s[3:] + u * dt])

    def apply_impulse(self, t, s, dv):
        return np.concatenate([s[:3], s[3:] + dv])


class PD:
    """PD to the origin at 10 s; records the times it is called."""

    def __init__(self, dt=10.0):
        self.dt, self.calls = dt, []

    def reset(self, t0, x0):
        pass

    def step(self, t, x):
        self.calls.append(t)
        return Command(u=-1e-3 * x[:3] - 3e-2 * x[3:], info={"x0": x[0]})


@dataclass
class CountingNav(PerfectNavigation):
    times: list = field(default_factory=list)

    def measure(self, t, x, rng):
        self.times.append(t)
        return super().measure(t, x, rng)


def test_multi_rate_controller_10s_navigation_1s_equals_single_rate():
    single = simulate(Setup(plant=DoubleIntegrator(), controller=PD(), duration_s=600.0, navigation=CountingNav()))
    nav = CountingNav(period_s=1.0)
    ctrl = PD()
    multi = simulate(Setup(plant=DoubleIntegrator(), controller=ctrl, duration_s=600.0, navigation=nav))
    assert len(single.t) == 61 and len(multi.t) == 601
    assert multi.meta["base_step_s"] == 1.0 and multi.meta["navigation_period_s"] == 1.0
    np.testing.assert_allclose(nav.times, np.arange(601.0))  # navigation every second
    np.testing.assert_allclose(ctrl.calls, np.arange(0.0, 600.0, 10.0))  # controller every 10 s
    rows = np.arange(0, 601, 10)
    # the same trajectory at the controller samples (10 exact 1 s pieces vs one 10 s piece: rounding only)
    np.testing.assert_allclose(multi.x_true[rows], single.x_true, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(multi.dv_cum[rows], single.dv_cum, rtol=1e-10)
    np.testing.assert_allclose(multi.info["x0"][rows[:-1]], single.info["x0"][:-1], rtol=1e-10)


def test_single_rate_is_bit_identical_when_periods_are_given_equal():
    a = simulate(Setup(plant=DoubleIntegrator(), controller=PD(), duration_s=300.0,
                       navigation=GaussianNavigation(0.5, 0.01)), seed=4)
    b = simulate(Setup(plant=DoubleIntegrator(), controller=PD(), duration_s=300.0,
                       navigation=GaussianNavigation(0.5, 0.01, period_s=10.0)), seed=4)
    np.testing.assert_array_equal(a.x_true, b.x_true)
    np.testing.assert_array_equal(a.x_est, b.x_est)


def test_schedule_grid_and_incommensurate_period():
    assert schedule(10.0, None, None) == (10.0, 1, 1, 1, ())
    assert schedule(30.0, 2.0, 0.5) == (0.5, 60, 4, 1, ())
    assert schedule(2.0, None, None, [30.0]) == (2.0, 1, 1, 1, (15,))
    with pytest.raises(ProxopsInputError, match="navigation.period_s"):
        schedule(10.0, -1.0, None)


def test_component_streams_are_independent_of_other_components():
    a = component_streams(7, ("navigation", "actuator"))
    b = component_streams(7, ("controller", "plant", "actuator", "navigation", "extra"))
    assert a["navigation"].random() == b["navigation"].random()
    assert a["actuator"].random() == b["actuator"].random()
    assert len({component_streams(7)[n].random() for n in ("navigation", "actuator", "plant", "controller")}) == 4


def test_actuator_draws_do_not_shift_navigation_noise():
    """Navigation noise is the same whether or not the actuator draws random errors."""
    from proxops.actuators import ThrusterModel

    nav = GaussianNavigation(0.5, 0.01)
    quiet = simulate(Setup(plant=DoubleIntegrator(), controller=PD(), duration_s=100.0, navigation=nav), seed=3)
    noisy = simulate(Setup(plant=DoubleIntegrator(), controller=PD(), duration_s=100.0, navigation=nav,
                           actuator=ThrusterModel(magnitude_sigma=0.1, pointing_sigma_rad=0.05)), seed=3)
    # the first sample is measured before any command: identical; the noise sequence as well
    np.testing.assert_allclose(noisy.x_est - noisy.x_true, quiet.x_est - quiet.x_true, rtol=0, atol=1e-12)


QUAT_LAYOUT = StateLayout(10, (Block("position", "position", 0, 3), Block("attitude", "quaternion", 3, 7),
                               Block("rate", "rate", 7, 10)))


def test_quaternion_block_gets_a_small_rotation():
    rng = np.random.default_rng(0)
    nav = GaussianNavigation(position_sigma_m=1.0, attitude_sigma_rad=0.01, rate_sigma_rad_s=1e-3, layout=QUAT_LAYOUT)
    q = np.array([0.1, -0.2, 0.3, 0.9])
    q /= np.linalg.norm(q)
    x = np.concatenate([[1.0, 2.0, 3.0], q, [0.0, 0.0, 0.01]])
    angles = []
    for _ in range(4000):
        y = nav.measure(0.0, x, rng)
        assert abs(np.linalg.norm(y[3:7]) - 1.0) < 1e-12  # still a unit quaternion
        angles.append(float(quat_angle_between(y[3:7], q)))
    # |phi| of a 3-D Gaussian with per-axis sigma s: E|phi| = 2 sqrt(2/pi) s (Maxwell mean)
    assert np.mean(angles) == pytest.approx(2 * math.sqrt(2 / math.pi) * 0.01, rel=0.05)
    sig = nav.additive_sigma(10)
    np.testing.assert_array_equal(sig, [1, 1, 1, 0, 0, 0, 0, 1e-3, 1e-3, 1e-3])


def test_layout_is_stored_with_the_result(tmp_path):
    res = simulate(Setup(plant=DoubleIntegrator(), controller=PD(), duration_s=50.0))
    back = SimResult.load(res.save(tmp_path / "r"))
    assert back.layout == res.layout == DoubleIntegrator.layout
    assert back.layout.names == ["x", "y", "z", "vx", "vy", "vz"]
    np.testing.assert_array_equal(back.velocity, res.x_true[:, 3:6])
    assert back.meta["stop_reason"] == StopReason.COMPLETED
    with pytest.raises(ValueError, match="overlaps"):
        StateLayout(4, (Block("a", "position", 0, 3), Block("b", "velocity", 2, 4)))


def test_status_vocabulary():
    assert SolveStatus is Status
    assert Status.parse("infeasible") is Status.INFEASIBLE and "infeasible" == Status.INFEASIBLE
    assert Status.parse("ipopt:Something_Else") is Status.FAILED
    assert Status.OPTIMAL_INACCURATE.ok and Status.OPTIMAL_INACCURATE.flagged
    assert not Status.OK.flagged and not Status.NONE.flagged and Status.INFEASIBLE.failed
    assert f"{Status.CBF_VIOLATION}" == "cbf_violation" and str(StopReason.CONTROLLER) == "controller"


class Planner:
    """Guidance every 30 s: the hold point is the current position pulled 10 % towards the origin."""

    period_s = 30.0

    def __init__(self):
        self.ref, self.times = np.zeros(3), []

    def reset(self, t0):
        self.times = []

    def update(self, t, x):
        self.times.append(t)
        self.ref = 0.9 * x[:3]
        return [("replan", f"hold point {self.ref[0]:.3f} m")]


class Tracker:
    """PD on the planner's hold point every 2 s."""

    dt = 2.0

    def __init__(self, planner):
        self.planner, self.seen = planner, []

    def reset(self, t0, x0):
        pass

    def step(self, t, x):
        self.seen.append((t, self.planner.ref.copy()))
        return Command(u=1e-3 * (self.planner.ref - x[:3]) - 5e-2 * x[3:])


def test_periodic_guidance_at_30s_feeds_a_2s_controller():
    planner = Planner()
    tracker = Tracker(planner)
    res = simulate(Setup(plant=DoubleIntegrator(), controller=tracker, duration_s=120.0, periodic=[planner]))
    np.testing.assert_allclose(planner.times, [0.0, 30.0, 60.0, 90.0])
    assert len(res.events_of("replan")) == 4 and len(res.t) == 61  # base step 2 s
    # the controller at t uses the plan of the last planner tick at or before t
    for t, ref in tracker.seen:
        k = int(np.searchsorted(res.t, 30.0 * (t // 30.0)))
        np.testing.assert_allclose(ref, 0.9 * res.x_est[k, :3])
