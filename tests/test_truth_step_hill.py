"""The full truth's per-step shortcuts of the closed loops (ComposedTruth.propagate / relative_state,
kernels_full.integrate_full_hill, the re-entry screen) give the numbers of the plain path.

Independent checks: the Hill state recomputed by hill_from_y_full (a fresh right-hand side for the
target's acceleration) on the propagated state, bit for bit; the FSAL derivative against the right-hand
side evaluated by the test at the final time and state; the WGS-84 closed form geodetic_to_ecef for
points just below the re-entry floors at every latitude.
"""

import math

import numpy as np
import pytest

from proxops.core.constants import KARMAN_LINE_KM
from proxops.environment.earth import WGS84_A, geodetic_height, geodetic_to_ecef
from proxops.errors import PlantEnded, ProxopsInputError
from proxops.frames.elements import circular_orbit
from proxops.propagation import kernels_full as kf
from proxops.propagation.kernels import apply_hill_impulse
from proxops.propagation.composed import DECAYING_ALTITUDE_KM, REENTRY_SCREEN, ComposedTruth, ForceModels

ORBIT = circular_orbit(altitude=500e3, inc=math.radians(98.0), raan=0.1, arg_lat=0.2)
X0 = np.array([0.0, -40.0, 5.0, 0.01, 0.0, -0.002])  # Hill, m and m/s: a proximity-operations start


def _truth():
    """cortex-nominal's model set: 20x20 field, drag, Sun and Moon."""
    models = ForceModels(epoch="2022-05-01T00:00:00Z", gravity="harmonics", degree=20, order=20, drag=True,
                         sun=True, moon=True)
    return ComposedTruth(ORBIT, X0, models, horizon_s=3600.0)


def _direct_hill(truth, state):
    return kf.hill_from_y_full(state[12], state[:12].copy(), truth.p, *truth._arrays(), truth._dens)


@pytest.mark.parametrize("dt", [2.0, 30.0, 250.0])  # one DOP853 step, and spans of several steps (< 324 s: DOP853)
def test_hill_of_a_propagation_is_the_direct_one_bit_for_bit(dt):
    """Impulse, propagate, relative_state as the engine calls them: the Hill state handed out from the
    propagation equals hill_from_y_full on the returned state, at every step; it is handed out once."""
    truth = _truth()
    state = truth.initial_state()
    rng = np.random.default_rng(3)
    for k in range(12):
        state = truth.apply_impulse(k * dt, state, 1e-3 * rng.standard_normal(3))
        state = truth.propagate(k * dt, state, np.zeros(3), dt)
        assert state[12] == (k + 1) * dt
        expect = _direct_hill(truth, state)
        got = truth.relative_state(state)
        assert np.array_equal(got, expect)
        again = truth.relative_state(state)  # a second call recomputes: equal numbers, a new array
        assert np.array_equal(again, expect) and again is not got


def test_fsal_of_the_last_step_is_the_right_hand_side_at_the_end():
    """integrate_full_crossings' f_end: the derivative at the final state and its time, equal to the
    right-hand side the test evaluates there (the acceleration the Hill frame rate needs)."""
    truth = _truth()
    y0 = truth.initial_state()[:12]
    for span in (2.0, 250.0):
        grid = np.array([0.0, span])
        out = np.empty((2, 12))
        f_end = np.empty(13)
        status, n_steps, _, _ = kf.integrate_full_crossings(y0, grid, np.zeros(3), truth.p, *truth._arrays(),
                                                            truth._dens, truth.rtol, truth.atol, out, np.empty(0),
                                                            f_end)  # fmt: skip
        assert status == 0 and n_steps >= 1
        assert f_end[12] == span  # the last (clipped) step ends on the grid time
        rhs = np.empty(12)
        kf.rhs_full(span, out[-1].copy(), np.zeros(3), truth.p, *truth._arrays(), truth._dens, rhs)
        assert np.array_equal(f_end[:12], rhs)


def test_fsal_time_is_nan_without_a_step():
    truth = _truth()
    y0 = truth.initial_state()[:12]
    f_end = np.zeros(13)
    status, n_steps, _, _ = kf.integrate_full_crossings(y0, np.array([5.0, 5.0]), np.zeros(3), truth.p,
                                                        *truth._arrays(), truth._dens, truth.rtol, truth.atol,
                                                        np.empty((2, 12)), np.empty(0), f_end)  # fmt: skip
    assert status == 0 and n_steps == 0 and math.isnan(f_end[12])


@pytest.mark.parametrize("floor_km", [KARMAN_LINE_KM, DECAYING_ALTITUDE_KM])
def test_reentry_screen_never_skips_a_point_below_the_floor(floor_km):
    """The screen skips the geodetic iteration only beyond (a + floor) / (1 - REENTRY_SCREEN) from the
    centre; a point 1 m below the floor (WGS-84 closed form) lies inside that radius at every latitude."""
    r_screen = (WGS84_A + 1e3 * floor_km) / (1.0 - REENTRY_SCREEN)
    for lat_deg in np.linspace(-90.0, 90.0, 181):
        r = geodetic_to_ecef(math.radians(lat_deg), 0.7, 1e3 * floor_km - 1.0)
        assert float(np.linalg.norm(r)) < r_screen
        assert geodetic_height(*r) < 1e3 * floor_km


def test_reentry_below_the_karman_line_still_ends_the_run():
    """A target state 1 km below the Karman line (closed form, 45 deg latitude) ends the run."""
    truth = _truth()
    y = truth.initial_state()[:12].copy()
    y[:3] = geodetic_to_ecef(math.radians(45.0), 0.3, 1e3 * (KARMAN_LINE_KM - 1.0))
    with pytest.raises(PlantEnded, match="target re-entered"):
        truth._end_if_reentering(0.0, y, KARMAN_LINE_KM)
    y[:3] = geodetic_to_ecef(math.radians(45.0), 0.3, 1e3 * (KARMAN_LINE_KM + 1.0))
    truth._end_if_reentering(0.0, y, KARMAN_LINE_KM)  # 1 km above: no stop (the chaser is 40 m away)


@pytest.mark.parametrize("dt", [2.0, 250.0])
def test_one_call_propagation_is_the_grid_integration_bit_for_bit(dt):
    """propagate's one kernel call (impulse applied on the 13-state first) gives the numbers of the plain
    path: the 12-state impulse kernel, then _integrate on the grid [t, t + dt] (integrate_full)."""
    truth = _truth()
    state = truth.initial_state()
    rng = np.random.default_rng(5)
    for k in range(6):
        dv = 1e-3 * rng.standard_normal(3)
        kicked = truth.apply_impulse(k * dt, state, dv)
        plain = apply_hill_impulse(state[:12].copy(), dv)
        assert np.array_equal(kicked[:12], plain) and kicked[12] == state[12]
        state = truth.propagate(k * dt, kicked, np.zeros(3), dt)
        expect = truth._integrate(plain, np.array([k * dt, k * dt + dt]), np.zeros(3))[-1]
        assert np.array_equal(state[:12], expect) and state[12] == k * dt + dt


def test_time_range_is_checked_past_the_last_checked_time():
    """Without drag the ephemeris' range is checked once per new end time: a propagation that ends past
    2099-12-31 still fails after shorter ones passed (the range kept is only the times checked)."""
    truth = ComposedTruth(ORBIT, X0, ForceModels(epoch="2099-12-31T12:00:00Z", gravity="harmonics", degree=4,
                                                 order=4))  # fmt: skip
    state = truth.propagate(0.0, truth.initial_state(), None, 2.0)
    state = truth.propagate(2.0, state, None, 2.0)  # inside the range checked before: no new check needed
    assert state[12] == 4.0
    with pytest.raises(ProxopsInputError, match="supported range"):
        truth.propagate(4.0, state, None, 12 * 3600.0)  # ends 2100-01-01T00:00:04
