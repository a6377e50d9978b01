"""Force models: spherical harmonics, Earth rotation, geodetic heights, drag, third body, SRP.

Independent references: an independent potential built from scipy's associated Legendre
functions (finite differences give the acceleration), the closed-form J2 and J3 zonal
accelerations (Vallado, *Fundamentals of Astrodynamics and Applications*, 4th ed.,
eq. 8-30 and the J3 term of sec. 8.7), Vallado Example 3-5 (GMST), the closed-form
geodetic -> ECEF map, the tidal approximation 2 GM r / d^3 of the third body, and the
drag and SRP formulas evaluated by hand."""

import math

import numpy as np
import pytest
from scipy.special import gammaln, lpmv

from proxops.core.constants import MU_EARTH, R_EARTH
from proxops.core.twobody import accel_j2
from proxops.environment.earth import earth_rotation, geodetic, geodetic_height, geodetic_to_ecef, gmst
from proxops.environment.ephemeris import AU, GM_SUN, R_SUN
from proxops.environment.epochs import parse_epoch
from proxops.environment.forces import (
    P_SUN,
    Atmosphere,
    Spacecraft,
    SpaceWeather,
    accel_drag,
    accel_srp,
    accel_third_body,
)
from proxops.environment.harmonics import (
    SHIPPED_DEGREE,
    SphericalHarmonics,
    _shipped,
    accel_harmonics,
    accel_harmonics_pair,
    read_gfc,
)
from proxops.errors import ProxopsInputError


def _potential_scipy(r, C, S, gm, re, nmax, nmin=2):
    """U = GM/r sum (R/r)^n Pbar_nm(sin phi) (C cos m lam + S sin m lam), Pbar from scipy.lpmv."""
    x, y, z = r
    rr = math.sqrt(x * x + y * y + z * z)
    sphi = z / rr
    lam = math.atan2(y, x)
    u = 0.0
    for n in range(nmin, nmax + 1):
        for m in range(0, n + 1):
            P = lpmv(m, n, sphi) * (-1) ** m  # scipy includes the Condon-Shortley phase
            N = math.sqrt((2 - (m == 0)) * (2 * n + 1) * math.exp(gammaln(n - m + 1) - gammaln(n + m + 1)))
            u += (re / rr) ** n * N * P * (C[n, m] * math.cos(m * lam) + S[n, m] * math.sin(m * lam))
    return gm / rr * u


@pytest.mark.parametrize(
    "r",
    [
        np.array([4.1e6, -3.3e6, 4.2e6]),
        np.array([-6.9e6, 0.2e6, -0.5e6]),
        np.array([1.0e3, -2.0e3, 6.9e6]),  # 0.02 deg from the pole (no singularity in V, W)
    ],
)
def test_harmonics_match_finite_differences_of_an_independent_potential(r):
    field = SphericalHarmonics(12, 12)
    a = field.acceleration(r)
    h = 20.0  # central differences: truncation ~ (h/r)^2 |a| ~ 1e-11 |a|, scipy's rounding ~ 1e-10 / h
    fd = np.array(
        [
            (_potential_scipy(r + h * e, field.C, field.S, field.gm, field.re, 12)
             - _potential_scipy(r - h * e, field.C, field.S, field.gm, field.re, 12)) / (2 * h)
            for e in np.eye(3)
        ]
    )  # fmt: skip
    assert np.max(np.abs(a - fd)) < 1e-9 * np.linalg.norm(a)  # FD truncation ~ (h/r)^2 |a|
    assert field.potential(r) == pytest.approx(_potential_scipy(r, field.C, field.S, field.gm, field.re, 12), rel=1e-12)


def test_degree_100_harmonics_match_finite_differences_of_own_potential():
    field = SphericalHarmonics(100, 100)
    r = np.array([3.2e6, 4.4e6, -4.0e6])
    a = field.acceleration(r)
    h = 5.0
    fd = np.array([(field.potential(r + h * e) - field.potential(r - h * e)) / (2 * h) for e in np.eye(3)])
    assert np.max(np.abs(a - fd)) < 1e-8 * np.linalg.norm(a)


def test_zonal_j2_j3_match_closed_forms():
    field = SphericalHarmonics(3, 0)
    gm, re = field.gm, field.re
    J2 = -field.C[2, 0] * math.sqrt(5.0)
    J3 = -field.C[3, 0] * math.sqrt(7.0)
    rng = np.random.default_rng(3)
    for _ in range(5):
        r = rng.normal(size=3)
        r *= (R_EARTH + rng.uniform(300e3, 2000e3)) / np.linalg.norm(r)
        x, y, z = r
        rn = np.linalg.norm(r)
        aj2 = np.array(accel_j2(x, y, z, gm, J2, re))
        k3 = -2.5 * J3 * gm * re**3 / rn**7
        aj3 = k3 * np.array([x * (3 * z - 7 * z**3 / rn**2), y * (3 * z - 7 * z**3 / rn**2),
                             6 * z**2 - 7 * z**4 / rn**2 - 0.6 * rn**2])  # fmt: skip
        assert np.allclose(field.acceleration(r), aj2 + aj3, rtol=0, atol=1e-14 * np.linalg.norm(aj2))


def test_central_term_is_point_mass():
    field = SphericalHarmonics(2, 0, include_central=True)
    r = np.array([7.0e6, 0.0, 0.0])
    a = field.acceleration(r)
    J2 = -field.C[2, 0] * math.sqrt(5.0)
    expected = -field.gm / 7.0e6**2 * np.array([1, 0, 0]) + np.array(accel_j2(7.0e6, 0, 0, field.gm, J2, field.re))
    assert np.allclose(a, expected, rtol=1e-14)


def _random_points(rng, k):
    """k Earth-fixed points (m) in random directions from the surface to beyond GEO."""
    r = rng.normal(size=(k, 3))
    return r * (rng.uniform(6.36e6, 4.5e7, size=k) / np.linalg.norm(r, axis=1))[:, None]


def test_pair_kernel_is_bit_identical_to_two_single_point_calls():
    """accel_harmonics_pair (both points in SIMD lanes) against two accel_harmonics calls, bit
    for bit: every degree 2..120 (the shipped maximum), orders 0, 1, a random one and the
    degree, with (nmin 0) and without (nmin 2) the central term; points in random directions,
    pairs 2 km apart (target and chaser) and unrelated, on the pole axis and on the equator
    (x' = y' = 0 and z' = 0 in the recursion), and the two points equal."""
    field = SphericalHarmonics(SHIPPED_DEGREE, SHIPPED_DEGREE, include_central=True)
    gm, re, C, S, K = field.gm, field.re, field.C, field.S, field.K  # K to degree 120 serves every lower degree
    n = SHIPPED_DEGREE
    V, W = np.zeros((n + 3, n + 3)), np.zeros((n + 3, n + 3))
    VW = np.full((3, 4 * (n + 2)), np.nan)  # the minimum size (a ring of three rows); never-written NaNs would show
    rng = np.random.default_rng(13)
    specials = [(np.array([0.0, 0.0, 6.9e6]), np.array([0.0, 0.0, -7.1e6])),
                (np.array([7.0e6, 0.0, 0.0]), np.array([0.0, -6.6e6, 0.0]))]  # fmt: skip
    checked = 0
    for degree in range(2, n + 1):
        for order in sorted({0, 1, int(rng.integers(0, degree + 1)), degree}):
            for nmin in (0, 2):
                a_pts = _random_points(rng, 2)
                pairs = [(a_pts[0], a_pts[0] + rng.normal(size=3) * 2e3), (a_pts[0], a_pts[1]), (a_pts[1], a_pts[1])]
                if degree in (2, 3, 57, n):
                    pairs += specials
                for a, b in pairs:
                    single = accel_harmonics(*a, gm, re, C, S, degree, order, nmin, K, V, W) + accel_harmonics(
                        *b, gm, re, C, S, degree, order, nmin, K, V, W
                    )
                    pair = accel_harmonics_pair(*a, *b, gm, re, degree, order, nmin, K, VW)
                    assert [v.hex() for v in pair] == [v.hex() for v in single], (degree, order, nmin, a, b)
                    checked += 1
    assert checked > 2000


def test_pair_in_the_truth_rhs_matches_two_single_calls_and_falls_back_on_small_work_arrays():
    """kernels_full._harmonics_eci_pair (ECI in and out, frame rotation per point) equals two
    _harmonics_eci calls bit for bit, with the pair layout and with work arrays too small for it
    (then it makes the two single-point calls itself)."""
    from proxops.propagation import kernels_full as kf

    field = SphericalHarmonics(30, 25)
    p = np.zeros(kf.N_P)
    p[kf.I_GM_H], p[kf.I_RE_H], p[kf.I_NMAX], p[kf.I_MMAX] = field.gm, field.re, 30, 25
    p[kf.I_THETA0], p[kf.I_OMEGA] = 1.1, 7.292115e-5
    c, s = math.cos(0.02), math.sin(0.02)
    npm = np.ascontiguousarray([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
    W = np.zeros((33, 33))
    rng = np.random.default_rng(7)
    for V in (np.zeros((33, 4 * 33)), np.zeros((33, 33))):
        assert kf.pair_arrays_fit(field.K, V, 30) == (V.shape[1] == 4 * 33)
        assert not kf.pair_arrays_fit(field.K[:8], V, 30)  # a K without the pair planes
        for i, (a, b) in enumerate(zip(_random_points(rng, 5), _random_points(rng, 5))):
            t = 613.0 * i
            pair = kf._harmonics_eci_pair(t, *a, *b, p, npm, field.C, field.S, field.K, V, W)
            single = kf._harmonics_eci(t, *a, p, npm, field.C, field.S, field.K, V, W) + kf._harmonics_eci(
                t, *b, p, npm, field.C, field.S, field.K, V, W
            )
            assert [v.hex() for v in pair] == [v.hex() for v in single]


def test_shipped_coefficients_metadata_and_source():
    C, S, gm, re = _shipped()
    assert C.shape == (SHIPPED_DEGREE + 1, SHIPPED_DEGREE + 1)
    assert gm == 3.986004415e14 and re == 6378136.3  # EGM96 (NASA/TP-1998-206861)
    assert C[2, 0] == -0.484165371736e-03  # EGM96 C20, tide-free (same paper)
    satkit_data = pytest.importorskip("satkit_data")
    import os

    path = os.path.join(os.path.dirname(satkit_data.__file__), "data", "EGM96.gfc")
    Cs, Ss, header = read_gfc(path, SHIPPED_DEGREE)
    assert header["modelname"] == "EGM96" and header["tide_system"] == "tide_free"
    assert np.array_equal(C, Cs) and np.array_equal(S, Ss)


@pytest.mark.parametrize("degree, order, match", [(121, 0, "gravity_degree"), (1, 0, "gravity_degree"),
                                                  (20, 21, "gravity_order"), (20, -1, "gravity_order")])  # fmt: skip
def test_degree_and_order_limits(degree, order, match):
    with pytest.raises(ProxopsInputError, match=match):
        SphericalHarmonics(degree, order)


# ----------------------------------------------------------------------------- Earth rotation
def test_gmst_vallado_example_3_5():
    # Vallado 4th ed. Example 3-5: 1992 Aug 20, 12:14 UT1 -> GMST = 152.578 787 886 deg
    ep = parse_epoch("1992-08-20T12:14:00Z")
    assert math.degrees(gmst(ep.days_ut1_since_j2000())) == pytest.approx(152.578787886, abs=1e-6)


def test_earth_rotation_is_a_rotation_and_pole_precesses():
    er = earth_rotation("2022-05-01T00:00:00Z")
    M = er.matrix(1234.0)
    assert np.allclose(M @ M.T, np.eye(3), atol=1e-15) and np.linalg.det(M) == pytest.approx(1.0)
    # the pole of date moves away from the J2000 pole by ~20.04"/yr (precession, 22.3 yr) +- 9" nutation
    tilt = math.degrees(math.acos(er.pole_eci[2])) * 3600.0
    assert 20.04 * 22.33 - 10.0 < tilt < 20.04 * 22.33 + 10.0
    # the Earth turns once per sidereal day, 86164.0905 s
    r = np.array([[7e6, 0.0, 0.0]])
    assert np.allclose(er.to_ecef(86164.0905, r), er.to_ecef(0.0, r), atol=1.0)


@pytest.mark.parametrize("lat", [-1.5, -0.6, 0.0, 0.785, 1.2, math.pi / 2])
def test_geodetic_inverts_closed_form(lat):
    r = geodetic_to_ecef(lat, 0.7, 450e3)
    la, lo, h = geodetic(*r)
    assert la == pytest.approx(lat, abs=1e-12) and h == pytest.approx(450e3, abs=1e-6)


@pytest.mark.parametrize("h", [0.0, 300e3, 500e3, 2000e3])
def test_geodetic_height_two_passes(h):
    """The drag's 2-pass height against the closed-form forward map (and geodetic's 6 passes):
    < 1e-8 m at every latitude (the height is stationary in the latitude; measured 2.8e-9 m,
    the round-off of 7e6 m coordinates)."""
    rng = np.random.default_rng(3)
    for lat, lon in zip(np.concatenate([[-math.pi / 2, 0.0, math.pi / 4, math.pi / 2], rng.uniform(-1.57, 1.57, 300)]),
                        rng.uniform(-3.1, 3.1, 304)):  # fmt: skip
        r = geodetic_to_ecef(lat, lon, h)
        assert abs(geodetic_height(*r) - h) < 1e-8 and abs(geodetic_height(*r) - geodetic(*r)[2]) < 1e-8


# ----------------------------------------------------------------------------- drag, third body, SRP
def test_drag_hand_computed():
    rho, bc, w = 3.0e-12, 2.2 * 2.0 / 500.0, 7.292115e-5
    a = accel_drag(7.0e6, 0.0, 0.0, 0.0, 7500.0, 100.0, rho, bc, 0.0, 0.0, w)
    vr = np.array([0.0, 7500.0 - w * 7.0e6, 100.0])  # co-rotating air: v - w x r
    expected = -0.5 * rho * bc * np.linalg.norm(vr) * vr
    assert np.allclose(a, expected, rtol=1e-14)
    assert abs(a[1]) == pytest.approx(0.5 * 3e-12 * 0.0088 * (6989.55178**2 + 100**2) ** 0.5 * 6989.55178, rel=1e-8)


def test_third_body_tidal_limit():
    r = np.array([7.0e6, 0.0, 0.0])
    s = np.array([AU, 0.0, 0.0])
    a = np.array(accel_third_body(*r, *s, GM_SUN))
    tidal = 2.0 * GM_SUN * 7.0e6 / AU**3  # leading term along the Sun line; next term 1.5 r/d smaller
    assert a[0] == pytest.approx(tidal, rel=1e-4) and a[1] == 0.0 and a[2] == 0.0
    r = np.array([0.0, 7.0e6, 0.0])  # perpendicular: -GM r / d^3 (compression)
    a = np.array(accel_third_body(*r, *s, GM_SUN))
    assert a[1] == pytest.approx(-GM_SUN * 7.0e6 / AU**3, rel=1e-4)


def test_srp_hand_computed():
    sc = Spacecraft(mass_kg=500.0, area_m2=2.0, cr=1.3)
    s = np.array([AU, 0.0, 0.0])
    a = np.array(accel_srp(0.0, 7.0e6, 0.0, *s, sc.srp_factor, 1.0, AU))
    d = np.array([-AU, 7.0e6, 0.0])
    expected = P_SUN * 1.3 * 2.0 / 500.0 * AU**2 / np.linalg.norm(d) ** 2 * d / np.linalg.norm(d)
    assert np.allclose(a, expected, rtol=1e-14)
    assert np.array(accel_srp(0.0, 7.0e6, 0.0, *s, sc.srp_factor, 0.0, AU)).tolist() == [0.0, 0.0, 0.0]
    assert np.linalg.norm(a) == pytest.approx(4.56e-6 * 0.0052, rel=1e-3)


def test_density_is_nrlmsise00_at_the_geodetic_point():
    import pymsis  # a core dependency
    ep = "2022-05-01T06:00:00Z"
    er = earth_rotation(ep)
    atm = Atmosphere(ep, er, SpaceWeather(120.0, 130.0, 7.0))
    lat, lon, h = 0.5, -1.1, 480e3
    r_ecef = geodetic_to_ecef(lat, lon, h)
    r_eci = er.matrix(0.0).T @ r_ecef
    expected = pymsis.calculate(np.datetime64("2022-05-01T06:00"), math.degrees(lon), math.degrees(lat), 480.0,
                                120.0, 130.0, [[7.0] * 7], version=0)[..., 0]  # fmt: skip
    assert atm.density(0.0, r_eci)[0] == pytest.approx(float(np.ravel(expected)[0]), rel=1e-6)
    assert 1e-13 < float(np.ravel(expected)[0]) < 1e-11  # kg/m^3 at 480 km, moderate activity


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"mass_kg": -1.0}, "mass_kg"),
        ({"mass_kg": 0.0}, "mass_kg"),
        ({"area_m2": -0.5}, "area_m2"),
        ({"cd": 0.0}, r"cd = 0.0: drag coefficient must be in \(0, 5\]"),
        ({"cd": 5.5}, "cd"),
        ({"cr": 2.5}, "cr"),
    ],
)
def test_spacecraft_bad_input(kwargs, match):
    with pytest.raises(ProxopsInputError, match=match):
        Spacecraft(name="truth.chaser", **kwargs)


def test_space_weather_bounds():
    with pytest.raises(ProxopsInputError, match="truth.f107"):
        SpaceWeather(f107=10.0)
    assert MU_EARTH > 0 and R_SUN > 0
