"""The scenario key reference (`proxops keys`, docs/scenario-keys.md) and `--set` on dispersions."""

from __future__ import annotations

import json
import tomllib
import typing
from pathlib import Path

import pytest
from typer.testing import CliRunner

from proxops.analysis.dispersions import parse_dispersions
from proxops.cli import app
from proxops.errors import ProxopsInputError
from proxops.scenarios import reference as ref
from proxops.scenarios.catalog import BUILTIN_DIR
from proxops.scenarios.loader import load_scenario
from proxops.scenarios.registry import SYSTEM_MODULES

ROOT = Path(__file__).resolve().parents[1]


def _keys(system: str) -> dict:
    return {k.key: k for sec in ref.reference(system) for k in sec.keys}


def _leaf_keys(data: dict, prefix: str = "") -> list[str]:
    """Dotted keys of a TOML document (array-of-tables as name[]), [dispersions] content skipped."""
    out = []
    for key, val in data.items():
        full = f"{prefix}.{key}" if prefix else key
        if isinstance(val, dict) and key != "dispersions":
            out += _leaf_keys(val, full)
        elif isinstance(val, list) and val and all(isinstance(v, dict) for v in val):
            for item in val:
                out += _leaf_keys(item, f"{full}[]")
        else:
            out.append(full)
    return out


@pytest.mark.parametrize("system", sorted(SYSTEM_MODULES))
def test_every_key_and_section_has_a_meaning(system):
    sections = ref.reference(system)
    assert sections and all(sec.meaning.strip() for sec in sections), [s.section for s in sections if not s.meaning]
    empty = [k.key for sec in sections for k in sec.keys if not k.meaning.strip()]
    assert not empty, f"{system}: keys without a meaning line: {empty}"
    assert all(k.meaning.strip() for k in ref.dispersion_reference().keys)


@pytest.mark.parametrize("path", sorted(BUILTIN_DIR.glob("*.toml")), ids=lambda p: p.stem)
def test_every_key_of_every_builtin_scenario_is_documented(path):
    data = tomllib.loads(path.read_text())
    documented = _keys(data["system"])
    missing = [k for k in _leaf_keys(data) if k not in documented]
    assert not missing, f"{path.name}: keys missing from `proxops keys {data['system']}`: {missing}"


def test_every_model_field_is_documented_once():
    """Walk the pydantic models independently: every leaf field appears exactly once."""
    from pydantic import BaseModel

    def leaves(model, prefix=""):
        for name, info in model.model_fields.items():
            full = f"{prefix}.{name}" if prefix else name
            ann = info.annotation
            many = typing.get_origin(ann) is list
            args = typing.get_args(ann) or (ann,)
            sub = [a for a in args if isinstance(a, type) and issubclass(a, BaseModel)]
            if sub:
                yield from leaves(sub[0], f"{full}[]" if many else full)
            else:
                yield full

    for system in SYSTEM_MODULES:
        from proxops.scenarios.registry import get_system

        expected = sorted(leaves(get_system(system).Scenario))
        listed = [k.key for sec in ref.reference(system) for k in sec.keys]
        assert sorted(listed) == expected, system


def test_units_ranges_and_defaults_come_from_the_schema():
    srf = _keys("srf")
    # unit from the suffix, with _per_ as the inverse unit (the same function names units in errors)
    assert srf["keep_out.alpha_per_s"].unit == "1/s" and srf["keep_out.alpha_per_s"].default == 0.01
    assert srf["mpc.q_terminal_per_m2"].unit == "1/m^2"
    assert srf["sim.duration_s"].unit == "s" and srf["sim.duration_s"].required
    assert srf["approach.hops"].allowed == ">= 1, <= 50" and srf["approach.hops"].type == "integer"
    assert srf["approach.gamma"].allowed == "> 0, < 1"
    assert srf["orbit.inc_deg"].allowed == ">= 0, <= 180" and srf["orbit.inc_deg"].unit == "deg"
    assert srf["truth.model"].allowed == "one of: j2, two-body, cw, full" and srf["truth.model"].default == "j2"
    assert srf["initial.position_m"].type == "list of 3 numbers" and srf["initial.position_m"].unit == "m"
    assert srf["mpc.steps_per_hop"].default is None and srf["mpc.steps_per_hop"].allowed == ">= 1, <= 100"
    ua = _keys("underactuated")
    assert ua["controller.q"].type == "list of 6 numbers" and ua["controller.q"].allowed == "each >= 0"
    assert ua["controller.r"].allowed == "each > 0"
    assert ua["deputy.wheel_inertia_kgm2"].unit == "kg m^2" and ua["limits.wheel_acc_deg_s2"].unit == "deg/s^2"
    assert "runs[].label" in ua and ua["runs[].label"].required
    disp = {k.key: k for k in ref.dispersion_reference().keys}
    assert set(disp) == {"percent", "min_abs", "distribution", "sigma", "half_width", "low", "high", "choice", "grid",
                         "linspace", "clip", "group"}
    assert disp["percent"].allowed == ">= 0" and disp["linspace"].type == "list of 3 numbers"


def test_checked_in_key_listing_is_the_live_schema():
    """`proxops keys` reads src/proxops/scenarios/keys.json (no pydantic): it must be what the schema
    generates now, byte for byte."""
    from proxops.scenarios import key_listing

    assert key_listing.LISTING.read_text(encoding="utf-8") == ref.listing_json(), \
        "regenerate: python -m proxops.scenarios.reference > src/proxops/scenarios/keys.json"
    assert key_listing.system_names() == sorted(ref.SYSTEM_MODULES)
    # the listing read back gives the schema's own key records (types, defaults, ranges) for every system
    for system in key_listing.system_names():
        live = {k.key: k for sec in ref.reference(system) for k in sec.keys}
        listed = {k["key"]: k for sec in key_listing.sections(system) for k in sec["keys"]}
        assert listed.keys() == live.keys()
        assert all(listed[key]["default"] == k.default and listed[key]["allowed"] == k.allowed
                   and listed[key]["required"] == k.required for key, k in live.items())


def test_committed_docs_equal_the_generated_reference():
    from proxops.scenarios import key_listing

    committed = (ROOT / "docs" / "scenario-keys.md").read_text()
    assert committed == key_listing.all_markdown(), "regenerate: proxops keys --all --markdown > docs/scenario-keys.md"
    res = CliRunner().invoke(app, ["keys", "--all", "--markdown"])
    assert res.exit_code == 0 and res.stdout == committed
    assert "docs/scenario-keys.md" in (ROOT / "README.md").read_text()


def test_cli_keys():
    runner = CliRunner()
    res = runner.invoke(app, ["keys"])
    assert res.exit_code == 0 and all(name in res.stdout for name in SYSTEM_MODULES)
    res = runner.invoke(app, ["keys", "--json"])
    assert [s["name"] for s in json.loads(res.stdout)["systems"]] == sorted(SYSTEM_MODULES)
    res = runner.invoke(app, ["keys", "los"])
    assert res.exit_code == 0 and "tumble_rate_deg_s" in res.stdout and "deg/s" in res.stdout
    res = runner.invoke(app, ["keys", "srf", "--json"])
    obj = json.loads(res.stdout)  # exactly one object
    assert obj["system"] == "srf" and {s["section"] for s in obj["sections"]} >= {"", "sim", "approach", "mpc"}
    assert {k["name"] for k in obj["dispersions"]["keys"]} >= {"percent", "grid"}
    for args, message in ((["srv"], "allowed: cortex, hybrid, los, srf"), (["srf", "--all"], "not both"),
                          (["srf", "--json", "--markdown"], "not both")):
        res = runner.invoke(app, ["keys", *args])
        assert res.exit_code == 2 and res.stderr.count("error:") == 1 and message in res.stderr
        assert "Traceback" not in res.stderr and res.stdout == ""


# --------------------------------------------------------------------------- --set on [dispersions]
def _entries(overrides):
    sc = load_scenario("srf-vbar-mc", overrides).scenario
    plan = parse_dispersions(sc)
    return {d.key: d.spec for d in plan.random + [d for axis in plan.grid for d in axis]}


def test_set_changes_one_field_of_a_dispersion_entry():
    assert _entries([])["initial.position_m"].percent == 10  # the file
    specs = _entries(["dispersions.initial.position_m.percent=5"])
    assert specs["initial.position_m"].percent == 5 and specs["initial.position_m"].min_abs == 1.0
    assert specs["initial.velocity_mps"].percent == 10  # untouched
    assert _entries(['dispersions."initial.position_m".min_abs=2.5'])["initial.position_m"].min_abs == 2.5


def test_set_replaces_adds_and_removes_whole_entries():
    specs = _entries(['dispersions."initial.position_m"={sigma = 2.0}'])
    assert specs["initial.position_m"].kind == "sigma" and specs["initial.position_m"].percent is None
    specs = _entries(["dispersions.initial.velocity_mps={half_width = 0.01}"])  # unquoted path, whole entry
    assert specs["initial.velocity_mps"].half_width == 0.01
    specs = _entries(['dispersions."navigation.position_sigma_m"={grid = [0.1, 0.2]}'])
    assert specs["navigation.position_sigma_m"].grid == [0.1, 0.2] and len(specs) == 3
    specs = _entries(['dispersions."initial.position_m"={}', 'dispersions."initial.position_m[1]"={half_width = 3.0}'])
    assert set(specs) == {"initial.velocity_mps", "initial.position_m[1]"}
    assert _entries(["dispersions={}"]) == {}


@pytest.mark.parametrize("override, message", [
    ("dispersions.initial.position_m.percent=-1", "greater than or equal to 0"),
    ("dispersions.initial.position_m.percnt=5", "one of its keys"),
    ("dispersions.sim.seed.percent=5", "no dispersion entry 'sim.seed'"),
    ('dispersions."nosuch.key"={percent = 5}', "does not exist"),
    ('dispersions."initial.position_m=5', "unclosed quote"),
    ('dispersions."orbit.sma_km"={}', "no dispersion entry"),
])
def test_bad_dispersion_overrides_are_one_line_errors(override, message):
    with pytest.raises(ProxopsInputError, match=message):
        load_scenario("srf-vbar-mc", [override])
    res = CliRunner().invoke(app, ["validate", "srf-vbar-mc", "--set", override])
    assert res.exit_code == 2 and res.stderr.count("\n") == 1 and "Traceback" not in res.stderr


def test_set_on_a_nested_table_dispersion():
    """[dispersions.initial] position_m = {...} (nested tables) takes the same --set forms."""
    from proxops.scenarios.catalog import read_toml, resolve
    from proxops.scenarios.loader import validate_scenario

    data = read_toml(resolve("station-keeping-mc"))
    data["dispersions"] = {"initial": {"position_m": {"percent": 10, "min_abs": 1.0}}}
    sc = validate_scenario(data, ["dispersions.initial.position_m.min_abs=3.0"]).scenario
    (d,) = parse_dispersions(sc).random
    assert d.key == "initial.position_m" and d.spec.percent == 10 and d.spec.min_abs == 3.0
