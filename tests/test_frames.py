"""Frames: ECI <-> Hill (exact, with the rotating-frame velocity term), Hill <-> srf LVLH,
orbital elements. References: Vallado Example 2-5, analytic Kepler propagation with
finite differences, definitions of the frame axes."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from proxops.core.constants import MU_EARTH, R_EARTH
from proxops.environment.gravity import J2Gravity
from proxops.errors import ProxopsInputError
from proxops.frames import elements as E
from proxops.frames.hill import (
    eci_offset_to_hill,
    eci_to_hill,
    eci_vector_to_hill,
    hill_dcm,
    hill_frame_rate,
    hill_to_eci,
    hill_to_eci_offset,
    hill_vector_to_eci,
)
from proxops.frames.lvlh import (
    HILL_TO_LVLH,
    hill_to_lvlh,
    hill_vector_to_lvlh,
    lvlh_to_hill,
    lvlh_vector_to_hill,
)

RNG = np.random.default_rng(7)
TARGET_EL = E.OrbitalElements.from_deg(R_EARTH + 500e3, 0.01, 51.6, 30.0, 40.0, 75.0)
TARGET = E.elements_to_eci(TARGET_EL)


def kepler_state(el: E.OrbitalElements, t: float) -> np.ndarray:
    """Analytic two-body state after t seconds (mean anomaly advance)."""
    n = math.sqrt(MU_EARTH / el.sma**3)
    M = E.true_to_mean_anomaly(el.true_anomaly, el.ecc) + n * t
    nu = E.mean_to_true_anomaly(M, el.ecc)
    return E.elements_to_eci(E.OrbitalElements(el.sma, el.ecc, el.inc, el.raan, el.argp, nu))


# ----------------------------------------------------------------------------- Hill
def test_hill_dcm_axes_follow_cortex_eq7():
    C = hill_dcm(TARGET)
    r, v = TARGET[:3], TARGET[3:]
    h = np.cross(r, v)
    assert np.allclose(C @ C.T, np.eye(3), atol=1e-15) and np.isclose(np.linalg.det(C), 1.0)
    assert np.allclose(C @ r / np.linalg.norm(r), [1, 0, 0], atol=1e-15)
    assert np.allclose(C @ h / np.linalg.norm(h), [0, 0, 1], atol=1e-15)
    assert (C @ v)[1] > 0  # along-track axis points along the velocity


def test_round_trip_eci_hill_eci():
    for _ in range(20):
        el = E.OrbitalElements(
            R_EARTH + RNG.uniform(300e3, 2000e3), RNG.uniform(0, 0.2), RNG.uniform(0, np.pi),
            RNG.uniform(0, 2 * np.pi), RNG.uniform(0, 2 * np.pi), RNG.uniform(0, 2 * np.pi),
        )  # fmt: skip
        tgt = E.elements_to_eci(el)
        hill = np.concatenate([RNG.normal(scale=500, size=3), RNG.normal(scale=0.5, size=3)])
        accel = J2Gravity().acceleration(tgt[:3])
        for a in (None, accel):
            chaser = hill_to_eci(tgt, hill, a)
            assert np.allclose(eci_to_hill(tgt, chaser, a), hill, atol=1e-8)  # ECI subtraction ~1e-9 m
            off = hill_to_eci_offset(tgt, hill, a)
            assert np.allclose(eci_offset_to_hill(tgt, off, a), hill, atol=1e-12)
    # batched input
    hills = RNG.normal(size=(5, 6))
    tgts = np.tile(TARGET, (5, 1))
    assert np.allclose(eci_offset_to_hill(tgts, hill_to_eci_offset(tgts, hills)), hills, atol=1e-12)
    vec = RNG.normal(size=3)
    assert np.allclose(hill_vector_to_eci(TARGET, eci_vector_to_hill(TARGET, vec)), vec)


def test_rotating_frame_velocity_term():
    """A chaser displaced by rho but with the target's ECI velocity has Hill velocity
    -w x rho, w = |h| / r^2 about the orbit normal (cortex eq. 8)."""
    r, v = TARGET[:3], TARGET[3:]
    wz = np.linalg.norm(np.cross(r, v)) / np.linalg.norm(r) ** 2
    rho = np.array([100.0, -40.0, 25.0])
    chaser = np.concatenate([r + hill_dcm(TARGET).T @ rho, v])
    hill = eci_to_hill(TARGET, chaser)
    assert np.allclose(hill[:3], rho, atol=1e-8)
    assert np.allclose(hill[3:], [wz * rho[1], -wz * rho[0], 0.0], atol=1e-12)
    # co-located with equal velocity: zero relative state
    assert np.allclose(eci_to_hill(TARGET, TARGET.copy()), 0.0)


def test_hill_velocity_is_time_derivative_of_hill_position_two_body():
    """Finite difference of the Hill position of two analytically (Kepler) propagated
    spacecraft equals the Hill velocity of eci_to_hill."""
    chaser_el = E.OrbitalElements(TARGET_EL.sma + 150.0, 0.0102, TARGET_EL.inc + 1e-5, TARGET_EL.raan,
                                  TARGET_EL.argp, TARGET_EL.true_anomaly - 2e-5)  # fmt: skip
    t, eps = 1234.0, 0.5
    pos = [eci_to_hill(kepler_state(TARGET_EL, t + s), kepler_state(chaser_el, t + s))[:3] for s in (-eps, eps)]
    fd = (pos[1] - pos[0]) / (2 * eps)
    vel = eci_to_hill(kepler_state(TARGET_EL, t), kepler_state(chaser_el, t))[3:]
    assert np.linalg.norm(vel) > 0.05
    assert np.allclose(fd, vel, atol=2e-8)


def test_j2_frame_rate_term_makes_hill_velocity_exact():
    """Under J2 the Hill frame also turns about x (w_x = r a_n / |h|). With the target
    acceleration passed, the Hill velocity equals the finite-difference derivative of the
    Hill position of two J2-propagated spacecraft; without it, it is off by ~w_x |rho|."""
    grav = J2Gravity()

    def rhs(t, y):
        return np.concatenate([y[3:6], grav.acceleration(y[:3]), y[9:12], grav.acceleration(y[6:9])])

    rho = np.array([20.0, 300.0, -200.0, 0.05, -0.1, 0.2])
    y0 = np.concatenate([TARGET, hill_to_eci(TARGET, rho, grav.acceleration(TARGET[:3]))])
    eps = 0.5
    sol = solve_ivp(rhs, (0, 600 + eps), y0, method="DOP853", rtol=1e-13, atol=1e-9, dense_output=True,
                    t_eval=[600 - eps, 600, 600 + eps])  # fmt: skip
    ys = sol.y.T
    fd = (eci_to_hill(ys[2, :6], ys[2, 6:])[:3] - eci_to_hill(ys[0, :6], ys[0, 6:])[:3]) / (2 * eps)
    a_t = grav.acceleration(ys[1, :3])
    exact = eci_to_hill(ys[1, :6], ys[1, 6:], a_t)[3:]
    kepler_only = eci_to_hill(ys[1, :6], ys[1, 6:])[3:]
    wx = hill_frame_rate(ys[1, :6], a_t)[0]
    assert abs(wx) > 1e-7  # the term is not negligible here
    assert np.linalg.norm(fd - exact) < 1e-7
    assert np.linalg.norm(fd - kepler_only) > 10 * np.linalg.norm(fd - exact)


def test_hill_input_errors():
    with pytest.raises(ProxopsInputError, match="target_state shape"):
        hill_dcm(np.zeros(5))
    with pytest.raises(ProxopsInputError, match="r x v"):
        hill_dcm(np.array([7e6, 0, 0, 1.0, 0, 0]))
    with pytest.raises(ProxopsInputError, match="finite"):
        eci_to_hill(TARGET, np.full(6, np.nan))


# ----------------------------------------------------------------------------- LVLH
def test_lvlh_axes_are_vbar_minus_normal_rbar():
    # Hill along-track (along velocity) -> +x V-bar; Hill normal -> -y; Hill radial out -> -z (R-bar is down)
    assert np.allclose(hill_vector_to_lvlh([0, 1, 0]), [1, 0, 0])
    assert np.allclose(hill_vector_to_lvlh([0, 0, 1]), [0, -1, 0])
    assert np.allclose(hill_vector_to_lvlh([1, 0, 0]), [0, 0, -1])
    assert np.isclose(np.linalg.det(HILL_TO_LVLH), 1.0)
    # R-bar points to the Earth's centre: LVLH z of the ECI direction -r
    r_hat_down_hill = eci_vector_to_hill(TARGET, -TARGET[:3] / np.linalg.norm(TARGET[:3]))
    assert np.allclose(hill_vector_to_lvlh(r_hat_down_hill), [0, 0, 1])


def test_lvlh_round_trips():
    x = RNG.normal(size=(7, 6))
    assert np.allclose(lvlh_to_hill(hill_to_lvlh(x)), x)
    assert np.allclose(hill_to_lvlh(x[0])[:3], hill_vector_to_lvlh(x[0, :3]))
    assert np.allclose(hill_to_lvlh(x[0])[3:], hill_vector_to_lvlh(x[0, 3:]))
    v = RNG.normal(size=(4, 3))
    assert np.allclose(lvlh_vector_to_hill(hill_vector_to_lvlh(v)), v)
    with pytest.raises(ProxopsInputError, match="state_hill shape"):
        hill_to_lvlh(np.zeros(3))


# ----------------------------------------------------------------------------- elements
def test_rv2coe_vallado_example_2_5():
    """Vallado 4th ed. Example 2-5: a = 36127.343 km, e = 0.832853, i = 87.870 deg,
    RAAN = 227.89 deg, argp = 53.38 deg, nu = 92.335 deg."""
    state = np.array([6524.834, 6862.875, 6448.296, 4.901327, 5.533756, -1.976341]) * 1e3
    el = E.eci_to_elements(state, mu=398600.4418e9)
    assert el.sma == pytest.approx(36127.343e3, rel=1e-6)
    assert el.ecc == pytest.approx(0.832853, abs=1e-6)
    got = np.degrees([el.inc, el.raan, el.argp, el.true_anomaly])
    assert np.allclose(got, [87.870, 227.89, 53.38, 92.335], atol=0.01)


def test_elements_round_trip_and_singular_cases():
    for _ in range(30):
        el = E.OrbitalElements(
            R_EARTH + RNG.uniform(300e3, 30000e3), RNG.uniform(1e-4, 0.7), RNG.uniform(0.01, np.pi - 0.01),
            RNG.uniform(0, 2 * np.pi), RNG.uniform(0, 2 * np.pi), RNG.uniform(0, 2 * np.pi),
        )  # fmt: skip
        back = E.eci_to_elements(E.elements_to_eci(el))
        assert back.sma == pytest.approx(el.sma, rel=1e-12)
        assert back.ecc == pytest.approx(el.ecc, abs=1e-12)
        for name in ("inc", "raan", "argp", "true_anomaly"):
            d = (getattr(back, name) - getattr(el, name) + np.pi) % (2 * np.pi) - np.pi
            assert abs(d) < 1e-8, name
    # circular inclined: argp = 0 and true anomaly = argument of latitude
    circ = E.circular_orbit(altitude=500e3, inc=0.9, raan=1.0, arg_lat=2.0)
    back = E.eci_to_elements(E.elements_to_eci(circ))
    assert back.ecc == 0.0 and back.argp == 0.0
    assert np.isclose(back.true_anomaly, 2.0) and np.isclose(back.raan, 1.0)
    # circular equatorial: angle from the x axis
    eq = E.eci_to_elements(E.elements_to_eci(E.circular_orbit(sma=8.1e6, arg_lat=0.7)))
    assert eq.raan == 0.0 and np.isclose(eq.true_anomaly, 0.7)
    state = E.elements_to_eci(E.circular_orbit(sma=8.1e6))
    assert np.allclose(state, [8.1e6, 0, 0, 0, math.sqrt(MU_EARTH / 8.1e6), 0])


def test_kepler_equation():
    for e in (0.0, 0.1, 0.7, 0.95):
        for M in (0.1, 2.0, 5.5):
            nu = E.mean_to_true_anomaly(M, e)
            # independent: solve M = E - e sin E by bracketing, then nu from E
            Ecc = brentq(lambda x: x - e * np.sin(x) - M, 0, 2 * np.pi)
            nu_ref = 2 * np.arctan2(np.sqrt(1 + e) * np.sin(Ecc / 2), np.sqrt(1 - e) * np.cos(Ecc / 2)) % (2 * np.pi)
            assert np.isclose(nu, nu_ref, atol=1e-12)
            assert np.isclose(E.true_to_mean_anomaly(nu, e), M, atol=1e-12)


def test_element_validation_errors():
    with pytest.raises(ProxopsInputError, match="ecc"):
        E.OrbitalElements(7e6, 1.2, 0, 0, 0, 0)
    with pytest.raises(ProxopsInputError, match="sma"):
        E.OrbitalElements(-7e6, 0.0, 0, 0, 0, 0)
    with pytest.raises(ProxopsInputError, match="perigee altitude"):
        E.check_perigee_above_surface(E.OrbitalElements(7e6, 0.2, 0, 0, 0, 0))
    with pytest.raises(ProxopsInputError, match="elliptic"):
        E.eci_to_elements(np.array([7e6, 0, 0, 0, 20e3, 0]))
    with pytest.raises(ProxopsInputError, match="altitude"):
        E.circular_orbit(altitude=-5.0)
