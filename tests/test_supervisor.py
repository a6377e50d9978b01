"""Generic supervisor: hysteresis (no chattering inside the band), dwell time, absorbing modes,
every switch an engine ``mode`` event; the LOS regimes run on it."""

import numpy as np
import pytest

from proxops.control.supervisor import Hysteresis, Supervisor
from proxops.dynamics.plant import PlantBase
from proxops.errors import ProxopsInputError
from proxops.sim.engine import Setup, simulate
from proxops.contracts import Command


class Constant:
    def __init__(self, value, dt=1.0):
        self.value, self.dt, self.resets = value, dt, 0

    def reset(self, t0, x0):
        self.resets += 1

    def step(self, t, x):
        return Command(u=np.array([self.value]))


class Signal(PlantBase):
    """1-D plant whose measured state is a prescribed signal s(t) (the control is ignored)."""

    n_x, n_u = 1, 1

    def __init__(self, f):
        self.f = f

    def initial_state(self):
        return np.array([0.0, self.f(0.0)])  # [t, s]

    def relative_state(self, state):
        return state[1:]

    def propagate(self, t, state, u, dt):
        return np.array([t + dt, self.f(t + dt)])

    def apply_impulse(self, t, state, dv):
        return state

    def delta_v(self, u, kind, dt):
        return 0.0


def sup(lower=-0.5, upper=0.5, dwell_s=0.0, **kw):
    rule = Hysteresis(lambda t, x: float(x[0]), lower, upper, low="low", high="high")
    return Supervisor({"low": Constant(-1.0), "high": Constant(1.0)}, rule, dwell_s=dwell_s, **kw)


def run(ctrl, f, duration=40.0):
    return simulate(Setup(plant=Signal(f), controller=ctrl, duration_s=duration))


def test_hysteresis_no_chatter_inside_the_band():
    # s = 0.4 sin(t): always inside [-0.5, 0.5] -> never switches, stays in the first mode (low: 0 < upper)
    res = run(sup(), lambda t: 0.4 * np.sin(t))
    assert res.events_of("mode") == [] and set(res.mode[:-1]) == {"low"}
    # the same signal against a single threshold (lower = upper = 0) switches at every sign change
    res0 = run(sup(0.0, 0.0), lambda t: 0.4 * np.sin(t))
    n_sign_changes = int(np.sum(np.diff(np.sign(0.4 * np.sin(np.arange(0.0, 40.0)))) != 0))
    assert len(res0.events_of("mode")) >= n_sign_changes - 1


def test_switches_at_the_band_edges_each_one_an_event():
    # s = sin(2 pi t / 20): above 0.5 for t in (20/12, 100/12) + 20k, below -0.5 for (140/12, 220/12) + 20k
    ctrl = sup()
    res = run(ctrl, lambda t: np.sin(2 * np.pi * t / 20.0))
    events = res.events_of("mode")
    # sample times (1 s) of the first sample beyond each threshold
    expected = [(2.0, "low -> high"), (12.0, "high -> low"), (22.0, "low -> high"), (32.0, "high -> low")]
    assert [(e[0], e[2]) for e in events] == expected
    assert [(t, f"{a} -> {b}") for t, a, b in ctrl.switch_log] == expected
    # the applied command follows the mode: +1 in high, -1 in low
    u = res.u_applied[:-1, 0]
    assert np.all(u[np.array(res.mode[:-1]) == "high"] == 1.0) and np.all(u[np.array(res.mode[:-1]) == "low"] == -1.0)


def test_dwell_time_delays_the_switch_back():
    # a 3 s pulse above upper then back below lower: with 5 s dwell the switch back waits for 5 s in high
    f = lambda t: 1.0 if 10.0 <= t < 13.0 else -1.0  # noqa: E731
    assert [e[0] for e in run(sup(), f).events_of("mode")] == [10.0, 13.0]
    assert [e[0] for e in run(sup(dwell_s=5.0), f).events_of("mode")] == [10.0, 15.0]


def test_absorbing_mode_and_reset_on_entry():
    ctrl = sup(absorbing=("high",), reset_on_entry=True)
    res = run(ctrl, lambda t: np.sin(2 * np.pi * t / 20.0))
    assert [e[2] for e in res.events_of("mode")] == ["low -> high"]
    assert ctrl.controllers["high"].resets == 2  # once in reset, once on entry


def test_bad_supervisor_input():
    with pytest.raises(ProxopsInputError, match="dt"):
        Supervisor({"a": Constant(0.0, dt=1.0), "b": Constant(0.0, dt=2.0)}, lambda t, x, m: "a")
    with pytest.raises(ProxopsInputError, match="dwell_s"):
        sup(dwell_s=-1.0)
    with pytest.raises(ProxopsInputError, match="lower"):
        Hysteresis(lambda t, x: 0.0, 1.0, 0.0)


def test_los_regimes_are_a_supervisor():
    from proxops.control.los_regimes import LosGuidanceController
    from proxops.systems.los import build_setup, default_scenario

    sc = default_scenario(sim={"duration_s": 300.0, "dt_s": 1.0}, target={"tumble_rate_deg_s": 2.0},
                          chaser={"a_max_mps2": 0.1, "initial_body_position_m": [0.0, 30.0, 0.0]}, mpc={"config": "monte-carlo"})
    setup = build_setup(sc)
    assert isinstance(setup.controller, LosGuidanceController) and isinstance(setup.controller, Supervisor)
    res = simulate(setup)
    # regimes follow the rule: close inside r_sync = 2 a / w^2 = 164 m, hold latched once entered
    modes = [m for m in res.mode if m]
    assert modes[0] == "close" and "hold" in modes
    first_hold = modes.index("hold")
    assert set(modes[first_hold:]) == {"hold"}
    assert [e[2] for e in res.events_of("mode")] == [f"close -> hold"]
