"""Idle-step coasting (issue 18): a controller that announces its next decision
(``Command.next_decision_s`` + ``idle``) lets the engine skip its idle ticks and propagate the gap
in one call. The result must be the SimResult of the step-by-step path (``simulate(coast=False)``,
which calls ``step`` on every tick) BIT FOR BIT: the coast runs the same floating-point operations
(the jitted coast repeats the per-step DOP853 call, navigation draws the same stream in one block,
constraints are screened vectorised and decided by the scalar check near zero, the controller's
per-step bookkeeping is summed in the same order). Compared: every array (the solver's measured wall times only where they are non-zero), status, mode, plant mode,
info series, the events (times, kinds, messages, order) and the meta (except the wall time).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxops.constraints.keep_out import KeepOutSphere
from proxops.navigation import GaussianNavigation
from proxops.propagation.truth import CWPlant
from proxops.sim.engine import Setup, simulate
from proxops.contracts import Command
from proxops.status import Status

N_ORB = 0.0011  # rad/s


def assert_same_result(a, b) -> None:
    for name in ("t", "x_true", "x_est", "u_cmd", "u_applied", "dv_cum"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape, name
        assert np.array_equal(x, y), f"{name}: max diff {np.max(np.abs(x - y))}"
    assert np.array_equal(a.solve_time_s > 0, b.solve_time_s > 0)  # measured wall times: where, not how long
    assert [str(s) for s in a.status] == [str(s) for s in b.status]
    assert a.mode == b.mode
    assert a.plant_mode == b.plant_mode
    assert a.info.keys() == b.info.keys()
    for key in a.info:
        assert np.array_equal(a.info[key], b.info[key], equal_nan=True), key
    assert a.events == b.events
    strip = lambda m: {k: v for k, v in m.items() if k != "wall_time_s"}  # noqa: E731
    assert strip(a.meta) == strip(b.meta)
    assert _timeless(a.summary()) == _timeless(b.summary())


def _timeless(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in ("wall_time_s", "solve_time_ms", "mpc_solve_ms")}


class Pulser:
    """Fires a small impulse every ``every`` ticks, idle in between; records what it was shown (observe_coast must see every estimate)."""

    def __init__(self, dt: float, every: int, announce: bool = True):
        self.dt, self.every, self.announce = dt, every, announce

    def reset(self, t0, x0):
        self.seen: list[tuple[float, float]] = []
        self.sum = 0.0

    def _see(self, t, x):
        self.seen.append((float(t), float(x[0])))
        self.sum += float(x[1])

    def step(self, t, x):
        self._see(t, x)
        k = int(round(t / self.dt))
        idle = Command(np.zeros(3), "impulse", Status.OK, mode=f"leg {k // self.every}", info={"fired": 0.0})
        if k % self.every:
            return idle
        dv = np.array([1e-4, -2e-4, 1e-4]) * (1.0 + 0.1 * np.sign(x[0]))
        nxt = (k + self.every) * self.dt if self.announce else None
        return Command(dv, "impulse", Status.OK, 1e-4, mode=f"leg {k // self.every}", info={"fired": 1.0},
                       next_decision_s=nxt, idle=idle if self.announce else None)

    def observe_coast(self, t, xs):
        for ti, xi in zip(t, xs):
            self._see(ti, xi)


def _toy_setup(check_substeps=1, stop_at_s=None, noise=True, every=7, range_scale_m=None):
    x0 = np.array([1.0, 60.0, 0.0, 0.0, -0.2, 0.0])  # passes through both spheres, entering between decisions
    nav = (GaussianNavigation(position_sigma_m=0.3, velocity_sigma_mps=1e-3, range_scale_m=range_scale_m,
                              range_floor=0.02) if noise else GaussianNavigation())
    stop = (lambda t, x: "timeout" if t >= stop_at_s else None) if stop_at_s is not None else None
    return Setup(plant=CWPlant(N_ORB, x0), controller=Pulser(5.0, every), duration_s=900.0, navigation=nav,
                 constraints=(KeepOutSphere(20.0, name="koz"), KeepOutSphere(6.0, (-55.0, -21.0, 0.0), name="koz2")),
                 stop_condition=stop, check_substeps=check_substeps)


@pytest.mark.parametrize("substeps", [1, 3])
def test_toy_coast_equals_step_by_step_with_violations_noise_and_substeps(substeps):
    a_setup, b_setup = _toy_setup(substeps), _toy_setup(substeps)
    a = simulate(a_setup, seed=3, coast=False)
    b = simulate(b_setup, seed=3, coast=True)
    assert_same_result(a, b)
    # the boundary cases this run must contain to mean anything: violations that start inside a
    # coast, noise on every sample, mode changes at decisions
    violations = a.events_of("violation")
    assert len(violations) >= 2
    assert any(round(t / 5.0) % 7 != 0 for t, _, _ in violations)  # entered between two decisions
    assert a.meta["max_violation"]["koz"] > 0.0 and a.meta["max_violation"]["koz2"] > 0.0
    assert np.any(a.x_est != a.x_true)
    # the controller saw every estimate, in order, on both paths
    assert a_setup.controller.seen == b_setup.controller.seen
    assert a_setup.controller.sum == b_setup.controller.sum
    assert len(b_setup.controller.seen) == len(a.t) - 1


def test_toy_range_scaled_noise_and_no_noise():
    """Range-dependent sigmas (cortex's navigation model): the per-row factor of the vectorised
    draw is the scalar one; and a noiseless model draws nothing on either path."""
    for kw in ({"range_scale_m": 80.0}, {"noise": False}):
        a = simulate(_toy_setup(**kw), seed=5, coast=False)
        b = simulate(_toy_setup(**kw), seed=5, coast=True)
        assert_same_result(a, b)


def test_toy_stop_inside_a_coast():
    a = simulate(_toy_setup(2, stop_at_s=402.0), seed=1, coast=False)
    b = simulate(_toy_setup(2, stop_at_s=402.0), seed=1, coast=True)
    assert_same_result(a, b)
    assert b.meta["outcome"] == "timeout" and b.t[-1] == pytest.approx(405.0)  # first sample at or after 402 s
    assert round(b.t[-1] / 5.0) % 7 != 0  # the stop sample lies inside a coast


def test_coast_skips_the_idle_steps():
    """The coasting path calls step only at decisions (the saving is real, not just equal results)."""
    calls = {"n": 0}
    setup = _toy_setup()
    step = setup.controller.step

    def counted(t, x):
        calls["n"] += 1
        return step(t, x)

    setup.controller.step = counted
    res = simulate(setup, seed=0)
    assert calls["n"] == math.ceil((len(res.t) - 1) / 7)


def test_no_coast_without_announcement_or_with_a_drawing_actuator():
    from proxops.actuators import ThrusterModel

    a = simulate(_toy_setup(), seed=2, coast=False)
    setup = _toy_setup()
    setup.actuator = ThrusterModel(missed_probability=0.5, missed_window_s=20.0)  # draws on zero commands
    assert not setup.actuator.zero_passthrough
    calls = {"n": 0}
    step = setup.controller.step
    setup.controller.step = lambda t, x: (calls.__setitem__("n", calls["n"] + 1), step(t, x))[1]
    b = simulate(setup, seed=2)
    assert calls["n"] == len(b.t) - 1  # every tick stepped
    assert len(a.t) == len(b.t)


@pytest.mark.parametrize("name", ["srf-vbar", "srf-rbar", "srf-vbar-ekf"])
def test_srf_coast_equals_step_by_step(name):
    """srf on J2 truth with navigation noise: V-bar samples its J2-aware drift invariant on every
    step (observe_coast gets the skipped ones), R-bar has no drift rows, srf-vbar-ekf runs the
    relative-navigation filter (measured and told the idle command on every skipped tick, its
    events drained in order). Full runs."""
    from proxops.scenarios.loader import load_scenario

    loaded = load_scenario(name)
    sc, system = loaded.scenario, loaded.system
    a = simulate(system.build(sc), seed=sc.sim.seed, coast=False)
    b = simulate(system.build(sc), seed=sc.sim.seed, coast=True)
    assert_same_result(a, b)
    assert np.any(a.x_est != a.x_true)  # noisy navigation: the stream is drawn identically
    solved = np.nan_to_num(a.info["solved"])
    assert 0 < solved.sum() < 0.1 * len(a.t)  # decisions are rare: most steps were coasted
    assert _timeless(system.summarize(sc, a)) == _timeless(system.summarize(sc, b))
