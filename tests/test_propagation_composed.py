"""Composed high-fidelity truth (Encke form), the [truth] scenario keys and ``proxops propagate``.

Independent references: scipy DOP853 integration of both absolute ECI states (the
relative state taken as their difference at the end), the unchanged J2 truth
(RelativeTruth), direct NRLMSISE-00 calls at every evaluation (reference path) for the
density table, and the exact Hill map round trip."""

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from typer.testing import CliRunner

from proxops.cli import app
from proxops.core.constants import R_EARTH
from proxops.core.twobody import accel_twobody
from proxops.environment.ephemeris import R_SUN, fitted_position
from proxops.errors import ProxopsInputError
from proxops.frames.elements import circular_orbit, orbital_period
from proxops.frames.hill import eci_offset_to_hill
from proxops.propagation import kernels_full as kf
from proxops.propagation.composed import ComposedTruth, ForceModels
from proxops.propagation.truth import RelativeTruth
from proxops.scenarios.loader import load_scenario
from proxops.systems.common import translational_plant

ORBIT = circular_orbit(altitude=500e3, inc=math.radians(51.6), raan=0.3, arg_lat=0.2)
PERIOD = orbital_period(ORBIT.sma)
EPOCH = "2022-05-01T00:00:00Z"


@pytest.mark.parametrize("gravity, j2", [("point", False), ("j2", True)])
def test_composed_point_and_j2_are_bit_identical_to_relative_truth(gravity, j2):
    x0 = np.array([10.0, 2000.0, -30.0, 0.01, -0.02, 0.03])
    plant = RelativeTruth(ORBIT, x0, j2=j2)
    composed = ComposedTruth(ORBIT, x0, ForceModels(epoch=EPOCH, gravity=gravity), rtol=plant.rtol)
    # The Hill maps agree to the last bits: the J2 truth takes the frame rate's J2 part in closed form
    # (kernels.hill_frame_rate), the composed one from the target's total acceleration (kernels_full)
    assert np.allclose(plant.initial_state(), composed.initial_state()[:12], rtol=1e-15, atol=1e-12)
    y0 = plant.initial_state()
    a = plant.propagate(0.0, y0, None, 0.5 * PERIOD)
    b = composed.propagate(0.0, np.append(y0, 0.0), None, 0.5 * PERIOD)
    assert np.array_equal(a, b[:12])  # from the same ECI states: the same arithmetic, bit for bit
    # Hill extraction: the same up to the frame rate's form, compiled separately (last-bit differences only)
    assert np.allclose(plant.relative_state(a), composed.relative_state(b), rtol=1e-13, atol=1e-15)


def test_scenario_j2_truth_is_still_the_relative_truth():
    loaded = load_scenario("station-keeping")
    sc = loaded.scenario
    plant = translational_plant(sc.orbit, sc.truth, np.array([0.0, 100.0, 0.0, 0.0, 0.0, 0.0]))
    assert type(plant) is RelativeTruth and plant.j2


def _body(which, t, p):
    """The kernels' Sun (0) or Moon (1) of the run whose parameters are ``p`` (series + fit)."""
    return np.array(fitted_position(which, p[kf.I_D0] + t / 86400.0, t / 86400.0, p, kf.I_EPH))


def _shadow_crossings(position, duration, p, step=2.0):
    """Times (s) in (0, duration) where the spacecraft at ``position(t)`` (m, ECI) crosses a
    conical shadow boundary, from the test's own geometry (Montenbruck & Gill sec. 3.4.2:
    the Sun's and the Earth's apparent radii a, b and their separation c; penumbra at
    c = a + b, umbra at c = b - a), scanned every ``step`` s and refined by brentq."""

    def g(t):
        r = position(t)
        s = _body(0, t, p) - r
        a = math.asin(R_SUN / np.linalg.norm(s))
        b = math.asin(R_EARTH / np.linalg.norm(r))
        c = math.atan2(np.linalg.norm(np.cross(-r, s)), float(-r @ s))
        return np.array([c - (a + b), c - (b - a)])

    ts = np.linspace(0.0, duration, int(duration / step) + 2)
    vals = np.array([g(t) for t in ts])
    out = []
    for k in range(2):
        for i in np.nonzero(np.sign(vals[1:, k]) != np.sign(vals[:-1, k]))[0]:
            out.append(brentq(lambda t: g(t)[k], ts[i], ts[i + 1], xtol=1e-9, rtol=1e-15))
    return sorted(out)


def _absolute_reference(models: ForceModels, x0_hill, duration, rtol=1e-13):
    """Final Hill state from scipy DOP853 on the absolute 12-state [target, chaser] (no drag).
    With SRP, integrated piecewise between the shadow crossings of either spacecraft (found
    by :func:`_shadow_crossings` on a first pass at rtol 1e-11): a step over a crossing is not
    of order 8 and the result would depend on where the steps fall (measured: 0.09-20 mm at
    20 km for rtol 1e-13 x 0.8 .. 1.25; piecewise, rtol 1e-12 .. 3e-14 agree to 0.5 um)."""
    truth = ComposedTruth(ORBIT, x0_hill, models)
    y0 = truth.initial_state()
    absolute = np.concatenate([y0[:6], y0[:6] + y0[6:12]])
    p, arrays = truth.p, truth._arrays()

    def one(t, s, chaser):
        sun = tuple(_body(0, t, p))
        moon = tuple(_body(1, t, p))
        a0 = accel_twobody(s[0], s[1], s[2], p[kf.I_MU])
        ap = kf.accel_perturbations(t, s[0], s[1], s[2], s[3], s[4], s[5], chaser, 0.0, sun, moon, p, *arrays)
        return np.array(a0) + np.array(ap)

    def fun(t, s):
        return np.concatenate([s[3:6], one(t, s[:6], False), s[9:12], one(t, s[6:], True)])

    edges = [0.0, duration]
    if models.srp:
        assert models.shadow == "conical"
        first = solve_ivp(fun, (0.0, duration), absolute, method="DOP853", rtol=1e-11, atol=1e-8, dense_output=True)
        edges = [0.0] + _shadow_crossings(lambda t: first.sol(t)[:3], duration, p) + \
            _shadow_crossings(lambda t: first.sol(t)[6:9], duration, p) + [duration]  # fmt: skip
        edges.sort()
    end = absolute
    for t_a, t_b in zip(edges[:-1], edges[1:]):
        end = solve_ivp(fun, (t_a, t_b), end, method="DOP853", rtol=rtol, atol=1e-10).y[:, -1]
    a_t = one(duration, end[:6], False)
    return eci_offset_to_hill(end[:6], end[6:] - end[:6], a_t), truth


@pytest.mark.parametrize("sep", [100.0, 2000.0, 20000.0])
def test_relative_state_sub_millimetre_against_absolute_integration(sep):
    models = ForceModels(epoch=EPOCH, gravity="harmonics", degree=20, order=20, sun=True, moon=True, srp=True)
    x0 = np.array([0.2 * sep, sep, 0.1 * sep, 0.0, -2.0 * 1.1e-3 * 0.2 * sep, 0.0])
    ref, truth = _absolute_reference(models, x0, PERIOD)
    ours = truth.relative_state(truth.propagate(0.0, truth.initial_state(), None, PERIOD))
    assert np.linalg.norm(ours[:3] - ref[:3]) < 1e-3  # m, one orbit
    assert np.linalg.norm(ours[3:] - ref[3:]) < 1e-6  # m/s


def test_default_tolerance_at_the_20km_boundary_with_100x100():
    """The default rtol (3e-11) and step safety (0.8) are set by the roughest forcing, the
    100x100 field (degree 100 varies on ~57 s along the track): at the boundary, 20 km, one
    orbit, 100x100 + Sun/Moon + SRP against scipy DOP853 on both absolute states (rtol
    1e-13, piecewise between the shadow crossings, whose own uncorrelated error is part of
    the difference: 0.16 mm against rtol 3e-14). Measured 0.071 mm (2026-11-27; 2.19 mm when
    neither integration stopped at the crossings, where a 1-ulp change of one initial
    coordinate moved the result by 1-3 mm)."""
    models = ForceModels(epoch=EPOCH, gravity="harmonics", degree=100, order=100, sun=True, moon=True, srp=True)
    sep = 20000.0
    x0 = np.array([0.2 * sep, sep, 0.1 * sep, 0.0, -2.0 * 1.1e-3 * 0.2 * sep, 0.0])
    ref, truth = _absolute_reference(models, x0, PERIOD)
    ours = truth.relative_state(truth.propagate(0.0, truth.initial_state(), None, PERIOD))
    assert np.linalg.norm(ours[:3] - ref[:3]) < 1e-3  # m, one orbit


def test_density_table_against_direct_nrlmsise00_calls():
    models = ForceModels(epoch=EPOCH, gravity="j2", drag=True)
    x0 = np.array([500.0, 20000.0, 300.0, 0.0, -1.1e-3, 0.0])
    fast = ComposedTruth(ORBIT, x0, models, horizon_s=PERIOD)
    ref = ComposedTruth(ORBIT, x0, models, integrator="reference")
    a = fast.relative_state(fast.propagate(0.0, fast.initial_state(), None, PERIOD))
    b = ref.relative_state(ref.propagate(0.0, ref.initial_state(), None, PERIOD))
    no_drag = ComposedTruth(ORBIT, x0, ForceModels(epoch=EPOCH, gravity="j2"))
    c = no_drag.relative_state(no_drag.propagate(0.0, no_drag.initial_state(), None, PERIOD))
    assert np.linalg.norm(a[:3] - c[:3]) > 1e-2  # drag matters here (differential density)
    # table vs direct calls: 0.35 mm after one orbit at 20 km. pymsis computes in single
    # precision (float32 density, ~1e-6..1e-5 relative noise), which bounds this comparison.
    assert np.linalg.norm(a[:3] - b[:3]) < 5e-4


def test_density_table_at_the_20km_boundary_full_model():
    """Fast path (density table with height curvature and cross-track gradient) against the
    reference path (NRLMSISE-00 called at both spacecraft at every evaluation) at the
    boundary of the stated range: 20 km along-track, 4 km radial, 2 km cross-track, drifting
    to ~70 km, different A/m (differential drag and SRP real), drag + Sun + Moon + SRP, one
    orbit. Stated tolerance: < 1 mm. Measured 0.045 mm (2026-11-27, both paths restarting at
    the shadow crossings; 0.1-0.2 mm before) (without the curvature and cross-track
    terms: 5e-4 mean density error at the chaser, 16 mm here)."""
    from proxops.environment.forces import Spacecraft

    models = ForceModels(epoch=EPOCH, gravity="harmonics", degree=8, order=8, drag=True, sun=True, moon=True,
                         srp=True, target=Spacecraft(mass_kg=500.0, area_m2=2.0, name="truth.target"),
                         chaser=Spacecraft(mass_kg=100.0, area_m2=1.5, cr=1.5, name="truth.chaser"))  # fmt: skip
    x0 = np.array([4000.0, 20000.0, 2000.0, 0.0, -4.4, 0.0])
    fast = ComposedTruth(ORBIT, x0, models, horizon_s=PERIOD)
    ref = ComposedTruth(ORBIT, x0, models, integrator="reference")
    a = fast.relative_state(fast.propagate(0.0, fast.initial_state(), None, PERIOD))
    b = ref.relative_state(ref.propagate(0.0, ref.initial_state(), None, PERIOD))
    assert np.linalg.norm(a[:3] - b[:3]) < 1e-3


def test_hill_round_trip_and_zero_offset_stays_zero():
    models = ForceModels(epoch=EPOCH, gravity="harmonics", degree=8, order=8, drag=True, sun=True, moon=True)
    x0 = np.array([12.0, -300.0, 4.0, 0.01, 0.02, -0.003])
    truth = ComposedTruth(ORBIT, x0, models)
    assert np.allclose(truth.relative_state(truth.initial_state()), x0, atol=1e-12)
    zero = ComposedTruth(ORBIT, np.zeros(6), models)
    end = zero.propagate(0.0, zero.initial_state(), None, 600.0)
    assert np.all(end[6:12] == 0.0) and end[12] == 600.0


def test_epoch_errors():
    ForceModels(epoch="2022-05-01T00:00")  # seconds and zone are optional
    with pytest.raises(ProxopsInputError, match="orbit.epoch_utc = 'May 1st': ISO 8601 UTC"):
        ForceModels(epoch="May 1st")
    truth = ComposedTruth(ORBIT, np.zeros(6), ForceModels(epoch="2099-12-31T12:00:00Z", gravity="j2"))
    with pytest.raises(ProxopsInputError, match="supported range"):
        truth.propagate(0.0, truth.initial_state(), None, 86400.0)


# ----------------------------------------------------------------------------- scenario keys
@pytest.mark.parametrize(
    "override, match",
    [
        ("truth.gravity_degree=121", r"truth.gravity_degree = 121: must be in \[2, 120\]"),
        ("truth.gravity_order=30", r"gravity_order = 30: must be in \[0, gravity_degree = 20\]"),
        ("truth.target.area_m2=-1.0", r"truth.target.area_m2 = -1.0 m\^2: input should be greater than or equal to 0"),
        ("truth.chaser.mass_kg=-5.0", r"truth.chaser.mass_kg = -5.0 kg"),
        ("truth.chaser.cd=0.0", r"truth.chaser.cd = 0.0"),
        ("truth.chaser.cd=5.5", r"truth.chaser.cd = 5.5"),
        ('orbit.epoch_utc="2022-05-01 noon"', r"orbit.epoch_utc = '2022-05-01 noon': must be ISO 8601 UTC, e.g. 2022-05-01T00:00:00Z"),
        ('orbit.epoch_utc="2150-01-01T00:00:00Z"', r"orbit.epoch_utc = .*outside the supported range"),
    ],
)
def test_truth_section_bad_input_is_one_line(override, match):
    with pytest.raises(ProxopsInputError, match=match) as info:
        load_scenario("station-keeping", ['truth.model="full"', override])
    assert "\n" not in str(info.value)


def test_full_truth_from_scenario():
    loaded = load_scenario("station-keeping", ['truth.model="full"', "truth.gravity_degree=8", "truth.srp=true"])
    sc = loaded.scenario
    plant = translational_plant(sc.orbit, sc.truth, np.array([0.0, -100.0, 0.0, 0.0, 0.0, 0.0]))
    assert isinstance(plant, ComposedTruth)
    assert plant.models.degree == 8 and plant.models.order == 8 and plant.models.drag and plant.models.moon


# ----------------------------------------------------------------------------- CLI
def test_cli_propagate_json_and_errors():
    runner = CliRunner()
    res = runner.invoke(app, ["propagate", "--scenario", "station-keeping", "--duration-s", "600", "--model", "full",
                              "--set", "truth.gravity_degree=4", "--json"])  # fmt: skip
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["model"] == "full" and len(out["final_hill"]) == 6
    names = [r["model"] for r in out["contributions"]]
    assert names == ["harmonics above J2", "gravity n >= 2 (all)", "drag", "Sun", "Moon"]
    res = runner.invoke(app, ["propagate", "--scenario", "station-keeping", "--duration-s", "-5"])
    assert res.exit_code == 2 and res.stderr.strip().count("\n") == 0 and "--duration-s" in res.stderr
    res = runner.invoke(app, ["propagate", "--scenario", "station-keeping", "--duration-s", "60", "--model", "full",
                              "--set", "truth.gravity_order=30"])  # fmt: skip
    assert res.exit_code == 2 and "gravity_order" in res.stderr


# ----------------------------------------------------------------------------- shadow crossings
SHADOW_SEP = 20000.0
SHADOW_X0 = np.array([0.2 * SHADOW_SEP, SHADOW_SEP, 0.1 * SHADOW_SEP, 0.0, -2.0 * 1.1e-3 * 0.2 * SHADOW_SEP, 0.0])


def _srp_models(shadow="conical"):
    """20x20 + Sun/Moon + SRP with different A/m (differential SRP real, as in the density
    boundary test above)."""
    from proxops.environment.forces import Spacecraft

    return ForceModels(epoch=EPOCH, gravity="harmonics", degree=20, order=20, sun=True, moon=True, srp=True,
                       shadow=shadow, target=Spacecraft(mass_kg=500.0, area_m2=2.0, name="truth.target"),
                       chaser=Spacecraft(mass_kg=100.0, area_m2=1.5, cr=1.5, name="truth.chaser"))  # fmt: skip


def _final(truth, chunk_s=None):
    """Hill state after one orbit, in one call or in calls of ``chunk_s`` s (each a restart)."""
    state, t = truth.initial_state(), 0.0
    while t < PERIOD:
        dt = PERIOD - t if chunk_s is None else min(chunk_s, PERIOD - t)
        state, t = truth.propagate(t, state, None, dt), t + dt
    return truth.relative_state(state)


@pytest.mark.parametrize("shadow", ["conical", "cylindrical"])
def test_shadow_crossings_do_not_depend_on_where_the_steps_fall(shadow):
    """One orbit through both shadow boundaries (20 km, 20x20 + Sun/Moon + SRP, different
    A/m): the fast path at rtol 3e-11 x 0.8 / 1 / 1.25, and in calls of 97 s and 333 s (each
    call restarts the step grid), against the reference path at rtol 1e-12 (scipy DOP853,
    crossings from scipy's own event search). Stated: all within 0.02 mm and 1e-8 m/s
    (measured <= 0.003 mm conical, <= 0.009 mm cylindrical; the paths without SRP agree to
    3-5 um). Without locating the crossings (one 85 s step held all four crossings of both
    spacecraft) the same variants were up to 0.097 mm (conical) and 0.20 mm (cylindrical) off,
    and the scipy reference path at its default rtol 0.13 / 0.11 mm."""
    models = _srp_models(shadow)
    ref = _final(ComposedTruth(ORBIT, SHADOW_X0, models, integrator="reference", rtol=1e-12))
    variants = [_final(ComposedTruth(ORBIT, SHADOW_X0, models, rtol=3e-11 * f)) for f in (0.8, 1.0, 1.25)]
    fast = ComposedTruth(ORBIT, SHADOW_X0, models)
    variants += [_final(fast, 97.0), _final(fast, 333.0)]
    for v in variants:
        assert np.linalg.norm(v[:3] - ref[:3]) < 2e-5  # m
        assert np.linalg.norm(v[3:] - ref[3:]) < 1e-8  # m/s


def test_located_shadow_crossings_match_the_geometry():
    """The fast loop restarts at the 8 boundary crossings of one orbit (penumbra and umbra,
    in and out, target and chaser), each within 1e-6 s of the crossing found by the test's
    own geometry (Montenbruck & Gill's a, b, c with atan2) on an absolute integration."""
    truth = ComposedTruth(ORBIT, SHADOW_X0, _srp_models())
    y0 = truth.initial_state()[:12]
    out = np.empty((2, 12))
    found = np.zeros(16)
    status, _, _, n = kf.integrate_full_crossings(y0, np.array([0.0, PERIOD]), np.zeros(3), truth.p, *truth._arrays(),
                                                  truth._dens, truth.rtol, truth.atol, out, found, np.empty(0))  # fmt: skip
    assert status == 0 and n == 8
    absolute = np.concatenate([y0[:6], y0[:6] + y0[6:12]])
    p, arrays = truth.p, truth._arrays()

    def fun(t, s):
        acc = []
        for chaser, r in ((False, s[:6]), (True, s[6:])):
            sun, moon = kf.third_bodies(t, p)
            a0 = accel_twobody(r[0], r[1], r[2], p[kf.I_MU])
            ap = kf.accel_perturbations(t, *r, chaser, 0.0, sun, moon, p, *arrays)
            acc.append(np.concatenate([r[3:], np.array(a0) + np.array(ap)]))
        return np.concatenate(acc)

    sol = solve_ivp(fun, (0.0, PERIOD), absolute, method="DOP853", rtol=1e-12, atol=1e-9, dense_output=True)
    expected = sorted(_shadow_crossings(lambda t: sol.sol(t)[:3], PERIOD, p)
                      + _shadow_crossings(lambda t: sol.sol(t)[6:9], PERIOD, p))  # fmt: skip
    assert len(expected) == 8
    assert np.max(np.abs(np.sort(found[:8]) - expected)) < 1e-6


def test_crossing_interpolant_is_exact_for_quintics():
    """The crossing search interpolates positions with the quintic Hermite through values,
    first and second derivatives at both step ends: exact (to rounding) for any polynomial
    of degree <= 5, here x(t) = sum c_j t^j on a 90 s step."""
    c = np.array([7.0e6, -3.0e3, 4.0, -2.0e-3, 5.0e-7, -3.0e-9])
    poly = np.polynomial.Polynomial(c)
    t0, h = 10.0, 90.0
    ends = [(poly(t), poly.deriv(1)(t), poly.deriv(2)(t)) for t in (t0, t0 + h)]
    for s in (0.0, 0.13, 0.5, 0.77, 1.0):
        value = kf._hermite5(s, h, *ends[0], *ends[1])
        assert value == pytest.approx(poly(t0 + s * h), rel=1e-14, abs=1e-6)
