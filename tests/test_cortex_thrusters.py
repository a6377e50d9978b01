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


# --------------------------------------------------------------------------- the chain on the actuator slot
def _chain(**kw):
    from proxops.actuators.thrusters import ThrusterChainActuator

    return ThrusterChainActuator(six_thruster_layout(1.2), 500.0, 220.0, 2.0, **kw)


def test_chain_single_axis_impulse_is_the_rocket_equation():
    """Along +x one thruster fires for the eq. 32 on-time: the delivered dv is the command exactly and the
    propellant is m0 (1 - exp(-dv / (Isp g0))) (closed form, independent of the PWM integration)."""
    act = _chain()
    dv = np.array([4.0e-3, 0.0, 0.0])
    out = act.apply(0.0, dv, "impulse", np.random.default_rng(0))
    assert np.allclose(out, dv, rtol=0, atol=1e-12)
    ve = 220.0 * G0
    assert act.propellant_kg == pytest.approx(500.0 * (1 - math.exp(-4.0e-3 / ve)), rel=1e-12)
    assert act.on_time_s == pytest.approx(act.propellant_kg * ve / 1.2, rel=1e-9)  # t_on = dm / mdot (eq. 32)
    assert act.mass_kg == pytest.approx(500.0 - act.propellant_kg, rel=1e-15)


def test_chain_oblique_impulse_uses_the_l1_propellant_of_the_axis_thrusters():
    """An oblique command fires three +-axis thrusters: the delivered dv matches the command to 1e-5 of
    its size (eq. 32 sizes the force for the mass flow of |F|; three thrusters burn the L1 flow, so the
    mass drops slightly faster: a second-order excess, measured 7e-7), and the propellant is the L1 sum |dv_x| + |dv_y| + |dv_z| (times m / (Isp g0), to first
    order), more than the rocket equation on |dv| -- the price of the axis-aligned layout."""
    act = _chain()
    dv = np.array([2.0e-3, -3.0e-3, 1.0e-3])
    out = act.apply(0.0, dv, "impulse", np.random.default_rng(0))
    assert np.linalg.norm(out - dv) < 1e-5 * np.linalg.norm(dv)
    ve = 220.0 * G0
    assert act.propellant_kg == pytest.approx(500.0 * np.abs(dv).sum() / ve, rel=1e-5)
    assert act.propellant_kg > 500.0 * (1 - math.exp(-np.linalg.norm(dv) / ve))


def test_chain_minimum_on_time_and_saturation():
    """Duties below min_on_time / t_control fire nothing; a command beyond the layout (2 N along x with
    1.2 N thrusters) is cut to the least-error allocation (full on) and reported."""
    act = _chain(min_on_time_s=0.1)
    small = np.array([1.0e-4, 0.0, 0.0])  # 0.1 s of 1.2 N on 500 kg is 2.4e-4 m/s
    assert not act.apply(0.0, small, "impulse", np.random.default_rng(0)).any()
    big = np.array([8.0e-3, 0.0, 0.0])
    out = act.apply(2.0, big, "impulse", np.random.default_rng(0))
    ve = 220.0 * G0
    assert out[0] == pytest.approx(ve * math.log(500.0 / (500.0 - 1.2 * 2.0 / ve)), rel=1e-9)  # 2 s at 1.2 N
    assert act.max_allocation_error_n > 0.7


def test_chain_bad_input():
    from proxops.actuators.thrusters import ThrusterChainActuator

    with pytest.raises(ProxopsInputError, match="min_on_time_s"):
        ThrusterChainActuator(six_thruster_layout(1.2), 500.0, 220.0, 2.0, min_on_time_s=3.0)
    with pytest.raises(ProxopsInputError, match="isp_s"):
        ThrusterChainActuator(six_thruster_layout(1.2), 500.0, -1.0, 2.0)


def test_closed_loop_with_the_thruster_chain_docks():
    """cortex-nominal (CW truth) with [actuator] model = thrusters docks like the impulsive loop: the same
    delta-v to 1e-5 m/s (the chain reproduces every command inside the layout) and more propellant than the
    rocket equation on the total delta-v (axis thrusters, L1), by at most sqrt(3)."""
    from proxops.scenarios.loader import load_scenario
    from proxops.systems.cortex_loop import run_closed_loop

    base = ["truth.model=cw", "eclipse.model=none"]
    imp, _ = run_closed_loop(load_scenario("cortex-nominal", base).scenario)
    thr, _ = run_closed_loop(load_scenario("cortex-nominal", base + ["actuator.model=thrusters"]).scenario)
    assert thr["status"] == "docked" and thr["terminal_position_error_m"] < 1e-3
    assert thr["total_dv_mps"] == pytest.approx(imp["total_dv_mps"], abs=1e-5)
    assert imp["propellant_kg"] < thr["propellant_kg"] <= math.sqrt(3) * imp["propellant_kg"]
    assert thr["allocation_max_error_n"] < 1e-6 and thr["actuator_model"] == "thrusters"
