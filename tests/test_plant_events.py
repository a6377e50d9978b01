"""Plant events and jump maps: a bouncing ball whose contact times and rebound speeds have closed
forms (t_1 = sqrt(2 h0 / g), v_k+ = e^k sqrt(2 g h0), t_{k+1} - t_k = 2 v_k+ / g), located inside
engine steps by bisection to 1e-9 s."""

import math

import numpy as np
import pytest

from proxops.dynamics.bouncing_ball import BouncingBall
from proxops.dynamics.plant import locate_guard
from proxops.sim.engine import Setup, simulate
from proxops.contracts import Command

G, E, H0 = 9.81, 0.8, 5.0


class Idle:
    dt = 0.25

    def reset(self, t0, x0):
        pass

    def step(self, t, x):
        return Command(u=np.zeros(1))


def closed_form_contacts(n):
    v1 = math.sqrt(2 * G * H0)
    times, speeds = [math.sqrt(2 * H0 / G)], [E * v1]
    for k in range(1, n):
        times.append(times[-1] + 2 * speeds[-1] / G)
        speeds.append(E * speeds[-1])
    return np.array(times), np.array(speeds)


def test_contact_times_and_rebound_speeds_match_closed_form():
    res = simulate(Setup(plant=BouncingBall(H0, g_mps2=G, restitution=E), controller=Idle(), duration_s=8.0))
    contacts = res.events_of("contact")
    t_exact, v_exact = closed_form_contacts(len(contacts))
    assert len(contacts) >= 6
    # every contact inside the 8 s run is found: the next closed-form contact is after 8 s
    assert t_exact[-1] <= 8.0 < t_exact[-1] + 2 * v_exact[-1] / G
    # each contact within 1e-9 s of the crossing of the computed flow; the rebound-speed errors
    # (<= e g 1e-9 m/s each) shift later contacts: measured max 1.7e-8 s over 9 contacts in 8 s
    np.testing.assert_allclose([c[0] for c in contacts], t_exact, rtol=0, atol=1e-7)
    # the velocity at each engine sample is the closed-form free flight after the last contact
    for t, (h, v) in zip(res.t, res.x_true):
        k = np.searchsorted(t_exact, t, side="right") - 1
        if k < 0:
            v_ref, h_ref = -G * t, H0 - 0.5 * G * t * t
        else:
            tau = t - t_exact[k]
            v_ref, h_ref = v_exact[k] - G * tau, v_exact[k] * tau - 0.5 * G * tau * tau
        # bisection to 1e-9 s per contact: each rebound speed is within e g 1e-9 m/s, compounding
        assert v == pytest.approx(v_ref, abs=1e-6) and h == pytest.approx(h_ref, abs=1e-6)
        assert h >= -1e-6  # never below the floor at a sample


def test_several_contacts_inside_one_step_and_rest_mode():
    """A 10 s step holds all contacts up to rest (Zeno time t_inf = t_1 + 2 e v_1 / (g (1 - e)))."""
    ball = BouncingBall(0.5, g_mps2=G, restitution=0.5, rest_speed_mps=1e-3)
    ctrl = Idle()
    ctrl.dt = 10.0
    res = simulate(Setup(plant=ball, controller=ctrl, duration_s=20.0))
    contacts = res.events_of("contact")
    v1 = math.sqrt(2 * G * 0.5)
    # contacts until e^k v1 < 1e-3: k = ceil(log(1e-3 / v1) / log(0.5))
    n_expected = math.ceil(math.log(1e-3 / v1) / math.log(0.5))
    assert len(contacts) == n_expected
    assert "at rest" in contacts[-1][2]
    t_inf = math.sqrt(2 * 0.5 / G) + 2 * 0.5 * v1 / (G * 0.5)
    assert contacts[-1][0] < t_inf
    assert res.plant_mode == ["flight", "rest", "rest"]
    np.testing.assert_array_equal(res.x_true[-1], [0.0, 0.0])


def test_locate_guard_tolerance_and_no_crossing():
    flow = lambda x, tau: np.array([x[0] - tau])  # noqa: E731  guard crossing at tau = x0
    hit = locate_guard(flow, lambda y: y[0], np.array([0.3]), 1.0, tol_s=1e-6)
    assert hit is not None and 0.3 <= hit[0] <= 0.3 + 1e-6
    assert locate_guard(flow, lambda y: y[0], np.array([2.0]), 1.0) is None
