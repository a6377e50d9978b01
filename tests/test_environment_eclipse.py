"""Earth's shadow (conical / cylindrical) and eclipse profiles.

Independent references: a brute-force count of solar-disc sample rays blocked by the
Earth sphere; the closed-form eclipse duration of a circular orbit under the
cylindrical model, T_ecl = (2/n) acos(sqrt(1 - (R_E/r)^2) / cos(beta)) (e.g. Wertz,
*Space Mission Analysis and Design*, 3rd ed., sec. 5.1); small-angle penumbra and umbra
durations of an in-plane Sun, 2 (b -/+ a)/n; the beta-angle test for a dawn-dusk
sun-synchronous orbit."""

import math

import numpy as np
import pytest

from proxops.core.constants import MU_EARTH, R_EARTH
from proxops.environment.eclipse import eclipse_profile, illumination, kepler_positions, shadow_boundaries
from proxops.environment.ephemeris import AU, R_SUN, sun_position_eci
from proxops.environment.epochs import parse_epoch
from proxops.environment.gravity import j2_raan_rate
from proxops.errors import ProxopsInputError
from proxops.frames.elements import OrbitalElements, elements_to_eci, orbital_period


def _visible_fraction_brute(r, s, n=1200):
    """Fraction of the solar disc's area whose rays to ``r`` miss the Earth sphere: a uniform
    grid over the disc, each point tested by ray-sphere intersection."""
    d = s - r
    dn = np.linalg.norm(d)
    w = d / dn
    u = np.cross(w, [0.0, 0.0, 1.0])
    u /= np.linalg.norm(u)
    v = np.cross(w, u)
    g = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    X, Y = np.meshgrid(g, g)
    inside = X**2 + Y**2 <= 1.0
    pts = s + R_SUN * (X[inside, None] * u + Y[inside, None] * v)  # points on the disc facing r
    ray = pts - r
    L = np.linalg.norm(ray, axis=1)
    ray /= L[:, None]
    tc = -(ray @ r)  # closest approach of the ray to the Earth's centre
    miss = (tc < 0) | (np.linalg.norm(r + tc[:, None] * ray, axis=1) >= R_EARTH)
    return miss.mean()


def test_conical_penumbra_matches_brute_force_disc_sampling():
    s = np.array([AU, 0.0, 0.0])
    rad = R_EARTH + 500e3
    b = math.asin(R_EARTH / rad)
    a = math.asin(R_SUN / AU)
    # positions across the penumbra: angle from the anti-Sun direction around b
    for off in (-0.9 * a, -0.5 * a, 0.0, 0.4 * a, 0.8 * a):
        th = b + off
        r = rad * np.array([-math.cos(th), math.sin(th), 0.0])
        assert illumination(r[None], s)[0] == pytest.approx(_visible_fraction_brute(r, s), abs=3e-3)
    # sunlit side, umbra, and the 0/1 limits
    assert illumination(np.array([[rad, 0, 0]]), s)[0] == 1.0
    assert illumination(np.array([[-rad, 0, 0]]), s)[0] == 0.0


def test_shadow_event_functions_change_sign_where_the_disc_starts_and_stops_being_covered():
    """The integrators restart where shadow_boundaries changes sign: just outside the
    penumbra (c = a + b) the brute-force disc sampling sees the whole Sun, 0.1 a inside it
    ~2 % covered; just inside the umbra (c = b - a) none of it, 0.1 a outside a sliver.
    Cylindrical: the event function's sign is the 0/1 factor."""
    s = np.array([AU, 0.0, 0.0])
    rad = R_EARTH + 500e3
    b = math.asin(R_EARTH / rad)
    a = math.asin(R_SUN / AU)
    for th, pen, umb in ((b + 1.1 * a, 1, 1), (b + 0.9 * a, -1, 1), (b - 0.9 * a, -1, 1), (b - 1.1 * a, -1, -1)):
        r = rad * np.array([-math.cos(th), math.sin(th), 0.0])
        g_pen, g_umb = shadow_boundaries(*r, *s, R_EARTH, R_SUN, True)
        assert np.sign(g_pen) == pen and np.sign(g_umb) == umb
        brute = _visible_fraction_brute(r, s)
        assert (brute == 1.0) == (pen > 0) and (brute == 0.0) == (umb < 0)
        assert illumination(r[None], s)[0] == pytest.approx(brute, abs=3e-3)
    edge = math.asin(R_EARTH / rad)  # cylinder wall: |r| sin(th) = R_E
    for th in (edge - 1e-6, edge + 1e-6):
        r = rad * np.array([-math.cos(th), math.sin(th), 0.0])
        g, g2 = shadow_boundaries(*r, *s, R_EARTH, R_SUN, False)
        assert g == g2 and (g < 0.0) == (illumination(r[None], s, "cylindrical")[0] == 0.0) == (th < edge)
        assert abs(g) == pytest.approx(rad * abs(math.sin(th) - R_EARTH / rad), rel=1e-3)


def test_annular_case_far_from_earth():
    # far beyond the umbra's apex (1.38e9 m) the Earth covers (b/a)^2 of the Sun's disc
    s = np.array([AU, 0.0, 0.0])
    r = np.array([-3.0e9, 0.0, 0.0])
    a = math.asin(R_SUN / (AU + 3.0e9))
    b = math.asin(R_EARTH / 3.0e9)
    assert illumination(r[None], s)[0] == pytest.approx(1.0 - b * b / (a * a), rel=1e-9)


def test_cylindrical_is_binary_and_bounded_by_the_earth_radius():
    s = np.array([AU, 0.0, 0.0])
    pts = np.array([[-7e6, R_EARTH * 0.999, 0.0], [-7e6, R_EARTH * 1.001, 0.0], [7e6, 0.0, 0.0]])
    assert illumination(pts, s, "cylindrical").tolist() == [0.0, 1.0, 1.0]


def _plane_with_sun(epoch, alt, beta):
    """Circular orbit whose plane makes angle ``beta`` (rad) with the Sun direction at ``epoch``."""
    s = sun_position_eci(epoch, [0.0])[0]
    ra, dec = math.atan2(s[1], s[0]), math.asin(s[2] / np.linalg.norm(s))
    # normal h = (-sin i cos RA', -sin i sin RA', cos i) with RA' = raan + 90 deg; h . s_hat = sin(dec - i)
    inc = dec - (-beta)  # sin(dec - i) = sin(-beta) -> beta measured so that h . s = -sin(beta)
    raan = ra - math.pi / 2
    return OrbitalElements(R_EARTH + alt, 0.0, inc, raan, 0.0, 0.0), s


def _synodic_rate(el, ep):
    """Angular rate (rad/s) of the spacecraft relative to the Sun direction about the orbit
    normal: n minus the Sun's apparent motion (~2e-7 rad/s, 0.4 s over a 36-min eclipse)."""
    h = np.cross(*np.split(elements_to_eci(el), 2))
    h /= np.linalg.norm(h)
    s0, s1 = sun_position_eci(ep, [0.0, 3600.0])
    w_sun = np.cross(s0, s1) @ h / (np.linalg.norm(s0) * np.linalg.norm(s1) * 3600.0)
    return math.sqrt(MU_EARTH / el.sma**3) - w_sun


def _intervals(t, illum, level):
    """Durations of complete intervals with illum < level, edges by linear interpolation."""
    below = illum < level
    edges = np.flatnonzero(np.diff(below.astype(int)))
    out = []
    for i0, i1 in zip(edges[:-1], edges[1:]):
        if below[i0 + 1]:
            f0 = (level - illum[i0]) / (illum[i0 + 1] - illum[i0]) if illum[i0 + 1] != illum[i0] else 0.5
            f1 = (level - illum[i1]) / (illum[i1 + 1] - illum[i1]) if illum[i1 + 1] != illum[i1] else 0.5
            out.append((t[i1] + f1 * (t[i1 + 1] - t[i1])) - (t[i0] + f0 * (t[i0 + 1] - t[i0])))
    return out


@pytest.mark.parametrize("beta_deg", [0.0, 30.0, 55.0])
def test_cylindrical_eclipse_duration_closed_form(beta_deg):
    ep = parse_epoch("2022-05-01T00:00:00Z")
    alt = 500e3
    el, s = _plane_with_sun(ep, alt, math.radians(beta_deg))
    n_per_orbit = 20000
    t, ill = eclipse_profile(el, ep, n_per_orbit=n_per_orbit, n_orbits=2.0, model="cylindrical")
    dt = t[1] - t[0]
    r = el.sma
    n = _synodic_rate(el, ep)
    # beta over the run (the Sun drifts ~0.07 deg per orbit): use the value at mid-eclipse
    durations = _intervals(t, ill, 0.5)
    assert durations, "no complete eclipse found"
    h = np.cross(*np.split(elements_to_eci(el), 2))
    h /= np.linalg.norm(h)
    i_mid = np.flatnonzero(ill < 0.5)
    s_mid = sun_position_eci(ep, [t[i_mid[len(i_mid) // 4]]])[0]
    beta = math.asin(abs(h @ s_mid) / np.linalg.norm(s_mid))
    expected = 2.0 / n * math.acos(math.sqrt(1.0 - (R_EARTH / r) ** 2) / math.cos(beta))
    assert abs(beta - math.radians(beta_deg)) < math.radians(0.1)
    assert durations[0] == pytest.approx(expected, abs=dt + 0.5)


def test_conical_umbra_and_penumbra_durations_in_plane():
    ep = parse_epoch("2022-05-01T00:00:00Z")
    el, s = _plane_with_sun(ep, 500e3, 0.0)
    t, ill = eclipse_profile(el, ep, n_per_orbit=100000, n_orbits=2.0, model="conical")
    n = _synodic_rate(el, ep)
    b = math.asin(R_EARTH / el.sma)
    a = math.asin(R_SUN / np.linalg.norm(s))
    umbra = _intervals(t, ill, 1e-12)[0]
    shadow = _intervals(t, ill, 1.0 - 1e-12)[0]
    # small-angle geometry: the Sun's disc centre is c = theta from the Earth's centre seen
    # from the spacecraft (parallax r/AU ~ 5e-5 rad ~ 0.04 s); umbra 2(b - a)/n, any shadow 2(b + a)/n
    assert umbra == pytest.approx(2 * (b - a) / n, abs=0.2)
    assert shadow == pytest.approx(2 * (b + a) / n, abs=0.2)
    # each penumbra crossing lasts 2a/n ~ 8.5 s at 500 km
    assert (shadow - umbra) / 2 == pytest.approx(2 * a / n, abs=0.15)


def test_dawn_dusk_sun_synchronous_orbit_eclipse_season():
    alt = 700e3
    sma = R_EARTH + alt
    # sun-synchronous inclination: J2 nodal rate = 360 deg per tropical year
    rate = 2 * math.pi / (365.2422 * 86400.0)
    cos_i = rate / j2_raan_rate(sma, 0.0, 0.0)  # j2_raan_rate(i=0) = -3/2 n J2 (Re/p)^2
    inc = math.acos(cos_i)
    b = math.asin(R_EARTH / sma)
    for instant, eclipsed in (("2022-12-21T21:48:00Z", False), ("2022-06-21T09:14:00Z", True)):
        ep = parse_epoch(instant)
        s = sun_position_eci(ep, [0.0])[0]
        ra = math.atan2(s[1], s[0])
        el = OrbitalElements(sma, 0.0, inc, (ra + math.pi / 2) % (2 * math.pi), 0.0, 0.0)  # LTAN 18:00
        h = np.cross(*np.split(elements_to_eci(el), 2))
        beta = math.asin(h @ s / np.linalg.norm(h) / np.linalg.norm(s))
        assert (abs(beta) < b) is eclipsed  # the beta-angle test, independent of the shadow code
        t, ill = eclipse_profile(el, ep, n_per_orbit=2000, n_orbits=14.0, model="conical", j2_mean=True)
        assert bool(ill.min() < 1.0) is eclipsed


def test_eclipse_profile_grid_and_bad_input():
    el = OrbitalElements(R_EARTH + 500e3, 0.001, 0.9, 0.1, 0.2, 0.3)
    t, ill = eclipse_profile(el, "2022-05-01T00:00:00Z")
    assert t.size == 1001 and t[-1] == pytest.approx(orbital_period(el.sma))
    assert np.all((ill >= 0) & (ill <= 1))
    # Keplerian positions agree with the elements -> ECI conversion
    assert np.allclose(kepler_positions(el, np.array([0.0]))[0], elements_to_eci(el)[:3], atol=1e-6)
    with pytest.raises(ProxopsInputError, match="eclipse model"):
        illumination(np.zeros((1, 3)) + 7e6, np.array([AU, 0, 0]), model="flat")
    with pytest.raises(ProxopsInputError, match="epoch"):
        eclipse_profile(el, "2022-05-01 noon")
    with pytest.raises(ProxopsInputError, match="n_per_orbit"):
        eclipse_profile(el, "2022-05-01T00:00:00Z", n_per_orbit=1)
