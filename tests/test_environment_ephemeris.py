"""Epochs (UTC/TT) and the Sun/Moon positions (erfa, and the kernels' corrected series).

Independent references: calendar arithmetic of Python's datetime, the IERS TAI-UTC
value, USNO's published equinox/solstice instants and the 2022-05-16 total lunar
eclipse, and (when installed: ``pip install jplephem de421``) JPL DE421."""

import math
from datetime import datetime, timezone

import numpy as np
import pytest

from proxops.environment.ephemeris import moon_position_eci, sun_position_eci
from proxops.environment.epochs import JD_J2000, parse_epoch
from proxops.errors import ProxopsInputError


def _jd_from_datetime(dt: datetime) -> float:
    """UTC Julian date by datetime arithmetic from J2000's UTC instant (2000-01-01 11:58:55.816)."""
    ref = datetime(2000, 1, 1, 12, 0, 0, tzinfo=timezone.utc)
    return 2451545.0 + (dt - ref).total_seconds() / 86400.0


# ----------------------------------------------------------------------------- epochs
@pytest.mark.parametrize(
    "text, dt",
    [
        ("2022-05-01T00:00:00Z", datetime(2022, 5, 1, tzinfo=timezone.utc)),
        ("2000-01-01T12:00:00Z", datetime(2000, 1, 1, 12, tzinfo=timezone.utc)),
        ("1999-12-31 23:59:59.5", datetime(1999, 12, 31, 23, 59, 59, 500000, tzinfo=timezone.utc)),
        ("2024-02-29T06:30Z", datetime(2024, 2, 29, 6, 30, tzinfo=timezone.utc)),
    ],
)
def test_epoch_julian_date_matches_calendar_arithmetic(text, dt):
    ep = parse_epoch(text)
    assert ep.jd_utc == pytest.approx(_jd_from_datetime(dt), abs=1e-9)


def test_tt_minus_utc_matches_iers_value():
    # IERS Bulletin C: TAI - UTC = 37 s since 2017-01-01, 36 s from 2015-07-01; TT = TAI + 32.184 s
    assert parse_epoch("2022-05-01T00:00:00Z").tt_minus_utc_s == pytest.approx(69.184)
    assert parse_epoch("2016-12-31T23:59:59Z").tt_minus_utc_s == pytest.approx(68.184)
    ep = parse_epoch("2022-05-01T00:00:00Z")
    assert (ep.jd_tt - ep.jd_utc) * 86400.0 == pytest.approx(69.184, abs=1e-4)
    assert parse_epoch("2000-01-01T11:58:55.816Z").jd_tt == pytest.approx(JD_J2000, abs=1e-9)


def test_leap_second_is_accepted():
    ep = parse_epoch("2016-12-31T23:59:60Z")
    assert ep.jd_utc_frac * 86400.0 == pytest.approx(86400.0)


@pytest.mark.parametrize(
    "bad",
    ["2022-13-01T00:00:00Z", "2022-02-30T00:00:00Z", "yesterday", "2022:05:01 00:00:00", "2022-05-01", "", 2022,
     "2022-05-01T25:00:00Z", "2022-05-01T00:00:00+02:00"],
)  # fmt: skip
def test_malformed_epoch_is_one_clear_error(bad):
    with pytest.raises(ProxopsInputError, match=r"^target.epoch = .*ISO 8601 UTC, e.g. 2022-05-01T00:00:00Z$"):
        parse_epoch(bad, "target.epoch")


@pytest.mark.parametrize("bad", ["1950-01-01T00:00:00Z", "2100-01-01T00:00:00Z"])
def test_epoch_outside_supported_range_is_rejected(bad):
    with pytest.raises(ProxopsInputError, match="outside the supported range 1972-01-01 .. 2099-12-31"):
        parse_epoch(bad)


def test_ephemeris_time_past_range_is_rejected():
    ep = parse_epoch("2099-12-31T00:00:00Z")
    with pytest.raises(ProxopsInputError, match="t_s .*supported range"):
        sun_position_eci(ep, np.array([0.0, 2 * 86400.0]))


# ----------------------------------------------------------------------------- Sun, Moon
def _ecliptic_lon_lat_deg(r):
    eps = math.radians(23.43929111)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    ye = math.cos(eps) * y + math.sin(eps) * z
    ze = -math.sin(eps) * y + math.cos(eps) * z
    return np.degrees(np.arctan2(ye, x)) % 360.0, np.degrees(np.arctan2(ze, np.hypot(x, ye)))


@pytest.mark.parametrize(
    "instant, lon_of_date",
    [  # USNO "Earth's Seasons" 2022 (Astronomical Applications Dept.), to the minute
        ("2022-03-20T15:33:00Z", 0.0),
        ("2022-06-21T09:14:00Z", 90.0),
        ("2022-09-23T01:04:00Z", 180.0),
        ("2022-12-21T21:48:00Z", 270.0),
    ],
)
def test_sun_at_2022_equinoxes_and_solstices(instant, lon_of_date):
    ep = parse_epoch(instant)
    r = sun_position_eci(ep, [0.0])[0]
    lon, lat = _ecliptic_lon_lat_deg(r)
    # the equinox regresses: longitudes of date exceed J2000 longitudes by the general
    # precession, 1.3970 deg per Julian century (Montenbruck & Gill sec. 3.3.2)
    T = (ep.jd_tt - JD_J2000) / 36525.0
    expected = (lon_of_date - 1.3970 * T) % 360.0
    # USNO's instants are apparent (nutation in longitude <= 0.005 deg, aberration 0.0057 deg),
    # the position geometric
    assert abs((lon - expected + 180.0) % 360.0 - 180.0) < 0.015
    # latitude on the J2000 ecliptic: the ecliptic of date tilts from it by 47"/century (10.4" in 2022)
    assert abs(lat) < 12.0 / 3600
    assert 0.9832 * 1.495978707e11 < np.linalg.norm(r) < 1.0168 * 1.495978707e11  # perihelion/aphelion


def test_moon_opposite_sun_at_2022_05_16_total_lunar_eclipse():
    # greatest eclipse 2022-05-16 04:11 UTC (NASA eclipse catalogue): the Moon sits in the Earth's
    # umbra, whose radius seen from Earth is ~0.7 deg, so the Moon is within ~0.7 deg of the anti-Sun.
    ep = parse_epoch("2022-05-16T04:11:00Z")
    s = sun_position_eci(ep, [0.0])[0]
    m = moon_position_eci(ep, [0.0])[0]
    angle = math.degrees(math.acos(-(s @ m) / np.linalg.norm(s) / np.linalg.norm(m)))
    assert angle < 0.7
    assert 356_000e3 < np.linalg.norm(m) < 407_000e3


def test_sun_and_moon_against_jpl_de421():
    import de421  # the [test] extra
    from jplephem.ephem import Ephemeris

    eph = Ephemeris(de421)
    ep = parse_epoch("2000-01-01T12:00:00Z")
    rng = np.random.default_rng(7)
    t = np.sort(rng.uniform(-20 * 365.25, 50 * 365.25, 500)) * 86400.0  # 1980-2050
    jd_tt = ep.jd_tt + t / 86400.0  # TDB ~ TT (< 1.7 ms)
    moon_geo = eph.position("moon", jd_tt).T * 1e3
    earth = eph.position("earthmoon", jd_tt).T * 1e3 - moon_geo * eph.earth_share
    sun_geo = eph.position("sun", jd_tt).T * 1e3 - earth
    for ours, ref, max_deg, max_rel in (
        (sun_position_eci(ep, t), sun_geo, 0.05 / 3600, 1e-7),  # measured 0.014", 3.3e-8
        (moon_position_eci(ep, t), moon_geo, 12.0 / 3600, 5e-5),  # measured 9.5", 2.6e-5
    ):
        cosang = np.sum(ours * ref, axis=1) / np.linalg.norm(ours, axis=1) / np.linalg.norm(ref, axis=1)
        assert np.degrees(np.arccos(np.clip(cosang, -1, 1))).max() < max_deg
        assert np.max(np.abs(np.linalg.norm(ours, axis=1) / np.linalg.norm(ref, axis=1) - 1)) < max_rel


@pytest.mark.parametrize("iso", ["1985-03-03T05:00:00Z", "2022-05-01T00:00:00Z", "2049-12-01T00:00:00Z"])
def test_kernel_positions_follow_erfa_over_the_fit_span(iso):
    """The kernels' Sun and Moon (analytic series + per-run cubic correction) stay within 0.02"
    (Sun) and 0.3" (Moon) of erfa over the 2-day fit span (sun_position_eci gives the same numbers
    there), where the bare series is worse
    (up to 39" / 317" over 1980-2050) at every point. Measured
    2026-11-27: Sun 0.004-0.006", Moon 0.05-0.19" (the series alone: Sun 4-25", Moon 48-107")."""
    from proxops.environment.ephemeris import FIT_DAYS, fitted_position, third_body_fit

    import erfa

    ep = parse_epoch(iso)
    c = third_body_fit(ep)
    d0 = ep.days_tt_since_j2000()
    t = np.linspace(0.0, FIT_DAYS * 86400.0, 97)
    jd = ep.jd_tt + t / 86400.0  # erfa called here directly (TDB ~ TT)
    sun = -erfa.epv00(np.floor(jd), jd - np.floor(jd))[0]["p"] * 1.495978707e11
    moon = erfa.moon98(np.floor(jd), jd - np.floor(jd))["p"] * 1.495978707e11
    assert np.allclose(sun_position_eci(ep, t), [fitted_position(0, d0 + x / 86400.0, x / 86400.0, c, 0) for x in t])
    for which, exact, tol in ((0, sun, 0.02), (1, moon, 0.3)):
        fit = np.array([fitted_position(which, d0 + x / 86400.0, x / 86400.0, c, 0) for x in t])
        bare = np.array([fitted_position(which, d0 + x / 86400.0, x / 86400.0, np.zeros_like(c), 0) for x in t])
        for ours, limit in ((fit, tol / 3600), (bare, 1.0)):
            cosang = np.sum(ours * exact, 1) / np.linalg.norm(ours, axis=1) / np.linalg.norm(exact, axis=1)
            worst = np.degrees(np.arccos(np.clip(cosang, -1, 1))).max()
            assert worst < limit, (which, worst * 3600)
        assert np.linalg.norm(fit - exact, axis=1).max() < np.linalg.norm(bare - exact, axis=1).min()
