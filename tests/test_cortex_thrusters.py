"""Thruster chain of cortex-convex-guidance.md §4.1.3-4.1.4: Algorithm 4 allocation, eq. 33, eq. 32."""

import math

import numpy as np
import pytest

from proxops.actuators.thrusters import (ThrusterLayout, allocate, burn_sequence, main_engine_on_time, pwm_on,
                                         six_thruster_layout)
from proxops.core.constants import G0
from proxops.errors import ProxopsInputError


def _canted_layout():
    """Eight canted thrusters at the corners of a 1 m cube (full 6-DOF authority, like a classic RCS)."""
    pos, dirs = [], []
    for sx in (-1, 1):
        for sy in (-1, 1):
            for sz in (-1, 1):
                pos.append([0.5 * sx, 0.5 * sy, 0.5 * sz])
                d = np.array([-sx, -sy * 0.5, -sz * 0.25 * sx * sy], float)
                dirs.append(d)
    return ThrusterLayout(np.array(pos), np.array(dirs), np.full(8, 1.0))


@pytest.mark.parametrize("seed", range(5))
def test_allocation_exact_for_achievable_commands(seed):
    """c = A F d* for a random duty d* in [0, 1] is achievable: the LP must reproduce it exactly
    (error 0 to the solver tolerance) with duties inside [0, 1]."""
    rng = np.random.default_rng(seed)
    for layout in (six_thruster_layout(), _canted_layout()):
        d_true = rng.uniform(0, 1, layout.n)
        c = (layout.actuation_matrix() * layout.f_max_n) @ d_true
        a = allocate(layout, c)
        assert a.status == "optimal"
        assert np.all(a.duty >= 0) and np.all(a.duty <= 1)
        np.testing.assert_allclose(a.achieved, c, atol=1e-8)


def test_allocation_least_error_when_not_achievable():
    """Six thrusters through the centre of mass: a force beyond the +x thruster and any torque are not
    achievable. Closed form of the least-L1 error: the +x thruster saturates (error 3 - 0.2 = 2.8 N),
    the other forces are exact, no torque can be made (error = |tau|_1)."""
    lay = six_thruster_layout(f_max_n=0.2)
    c = np.array([3.0, -0.1, 0.05, 0.2, -0.3, 0.4])
    a = allocate(lay, c)
    assert a.status == "optimal"
    np.testing.assert_allclose(a.error, [2.8, 0, 0, 0.2, 0.3, 0.4], atol=1e-9)
    assert a.duty[0] == pytest.approx(1.0)
    # no other duty vector does better: brute force over a grid of the relevant duties
    best = min(abs(3 - 0.2 * d) for d in np.linspace(0, 1, 101))
    assert a.error[0] <= best + 1e-9


def test_layout_that_cannot_push_along_an_axis_is_rejected():
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.0]])  # no -z thruster
    with pytest.raises(ProxopsInputError, match="-z"):
        ThrusterLayout(np.zeros((5, 3)), dirs, np.full(5, 0.2))


def test_pwm_law_eq33_duty_fraction():
    """The fraction of on-time over one control period equals the duty (eq. 33)."""
    duty = np.array([0.0, 0.25, 0.5, 1.0])
    t = np.linspace(0, 2.0, 20001)[:-1]  # two periods of 1 s
    on = np.array([pwm_on(tt, duty, 1.0) for tt in t])
    np.testing.assert_allclose(on.mean(axis=0), duty, atol=2e-4)


def test_rocket_equation_on_time_against_integration():
    """Eq. 32 vs a numerical integration of a constant-thrust burn with mass depletion:
    dv = int F / m(t) dt with m(t) = m0 - mdot t."""
    m0, F, isp, dv = 500.0, 22.0, 220.0, 3.0
    t_on, mf = main_engine_on_time(dv, m0, F, isp)
    mdot = F / (isp * G0)
    tt = np.linspace(0, t_on, 200001)
    dv_num = np.trapezoid(F / (m0 - mdot * tt), tt)
    assert dv_num == pytest.approx(dv, rel=1e-9)
    assert mf == pytest.approx(m0 - mdot * t_on, rel=1e-12)
    # mass depletion: the same dv later (lighter) takes less time
    t_seq, masses = burn_sequence([dv, dv], m0, F, isp)
    assert t_seq[1] < t_seq[0] and masses[-1] == pytest.approx(m0 * math.exp(-2 * dv / (isp * G0)))


@pytest.mark.parametrize("bad", [(-1.0, 500, 1, 200), (1.0, 0.0, 1, 200), (1.0, 500, 1, math.nan)])
def test_rocket_equation_bad_input(bad):
    with pytest.raises(ProxopsInputError):
        main_engine_on_time(*bad)
