"""Scenario files: every built-in validates; bad input gives one clear line."""

import math

import pytest

from proxops.errors import ProxopsInputError
from proxops.scenarios.catalog import builtin_names, read_toml, resolve
from proxops.scenarios.loader import load_scenario, validate_scenario


def base():
    return read_toml(resolve("station-keeping"))


@pytest.mark.parametrize("name", builtin_names())
def test_every_builtin_validates(name):
    loaded = load_scenario(name)
    assert loaded.scenario.name == name


def expect_error(data, *fragments, overrides=()):
    with pytest.raises(ProxopsInputError) as exc:
        validate_scenario(data, overrides)
    text = str(exc.value)
    assert "\n" not in text
    for frag in fragments:
        assert frag in text, text
    return text


def test_unknown_key():
    d = base()
    d["sim"]["durashun_s"] = 5.0
    expect_error(d, "unknown key", "sim.durashun_s")


def test_wrong_type():
    d = base()
    d["sim"]["duration_s"] = "long"
    expect_error(d, "sim.duration_s", "'long'", " s:")


def test_negative_time_step():
    d = base()
    d["controller"]["dt_s"] = -1.0
    expect_error(d, "controller.dt_s = -1.0 s", "greater than 0")


def test_nan_initial_state():
    d = base()
    d["initial"]["position_m"] = [math.nan, 0.0, 0.0]
    expect_error(d, "initial.position_m", "m:")


def test_perigee_inside_earth():
    d = base()
    d["orbit"] = {"sma_km": 7000.0, "ecc": 0.2}
    expect_error(d, "perigee", "inside the Earth")


def test_both_orbit_sizes():
    d = base()
    d["orbit"]["sma_km"] = 7000.0
    expect_error(d, "exactly one of orbit.sma_km or orbit.altitude_km")


def test_unknown_scenario_name():
    with pytest.raises(ProxopsInputError, match="no built-in scenario"):
        load_scenario("no-such-scenario")


def test_unknown_system():
    d = base()
    d["system"] = "warp-drive"
    expect_error(d, "system = 'warp-drive'", "allowed:")


def test_set_overrides_value_and_rejects_unknown_key():
    loaded = load_scenario("station-keeping", ["sim.duration_s=600", "controller.type=\"pd\""])
    assert loaded.scenario.sim.duration_s == 600.0 and loaded.scenario.controller.type == "pd"
    with pytest.raises(ProxopsInputError, match="no key 'bogus'"):
        load_scenario("station-keeping", ["controller.bogus=1"])
    with pytest.raises(ProxopsInputError, match="key=value"):
        load_scenario("station-keeping", ["sim.duration_s"])
