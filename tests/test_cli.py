"""The proxops command line: JSON contracts, exit codes and one-line errors."""

import json

import pytest
from typer.testing import CliRunner

from proxops import __version__
from proxops.cli import app

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, list(args))


def test_version():
    res = invoke("--version")
    assert res.exit_code == 0 and __version__ in res.stdout


def test_scenarios_json_lists_names_and_descriptions():
    res = invoke("scenarios", "--json")
    assert res.exit_code == 0
    items = json.loads(res.stdout)
    names = {i["name"] for i in items}
    assert "station-keeping" in names
    assert all(i["description"] for i in items)


def test_validate_ok_and_bad(tmp_path):
    assert invoke("validate", "station-keeping").exit_code == 0
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nsystem = "station-keeping"\n[sim]\nduration_s = -5.0\n'
                   '[orbit]\naltitude_km = 500.0\n[initial]\nposition_m = [0.0, -100.0, 0.0]\n')
    res = invoke("validate", str(bad))
    assert res.exit_code == 2
    assert "sim.duration_s = -5.0 s" in res.stderr and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_unknown_name_and_bad_set_exit_2():
    res = invoke("run", "nope")
    assert res.exit_code == 2 and "no built-in scenario" in res.stderr
    res = invoke("run", "station-keeping", "--set", "orbit.bogus_km=3")
    assert res.exit_code == 2 and "no key 'bogus_km'" in res.stderr


def test_run_json_contract(tmp_path):
    res = invoke("run", "station-keeping", "--set", "sim.duration_s=600", "--json", "--out", str(tmp_path / "o"))
    assert res.exit_code == 0, res.stderr
    s = json.loads(res.stdout)
    for key in ("status", "final_range_m", "final_speed_mps", "total_dv_mps", "min_range_m", "sim_time_s",
                "wall_time_s", "solve_time_ms", "events"):
        assert key in s
    assert set(s["solve_time_ms"]) >= {"median", "p95"}
    assert s["sim_time_s"] == pytest.approx(600.0)
    assert (tmp_path / "o" / "run" / "steps.parquet").is_file()
    assert (tmp_path / "o" / "summary.json").is_file()


def test_readme_scenario_example_validates(tmp_path):
    """The scenario shown in the README must stay valid."""
    from pathlib import Path

    text = (Path(__file__).parents[1] / "README.md").read_text()
    start = text.index("```toml\n") + len("```toml\n")
    example = tmp_path / "example.toml"
    example.write_text(text[start : text.index("```", start)])
    res = invoke("validate", str(example))
    assert res.exit_code == 0, res.stderr


def test_demo_runs_its_scenarios_side_by_side_and_reports_them_in_order(tmp_path, monkeypatch, capsys):
    # runner.run_demo on 2 worker processes (longest first by DEMO_SECONDS): one stage line per scenario as it
    # ends, the report's sections in DEMO_SCENARIOS order, each section what that scenario's worker wrote
    # (its summary.json, its figures): nothing mixed between the workers
    from proxops import runner

    names = ("srf-rbar", "station-keeping")
    monkeypatch.setattr(runner, "DEMO_SCENARIOS", names)
    monkeypatch.setattr(runner, "DEMO_SECONDS", {"station-keeping": 1.0})  # goes first, srf-rbar second
    report = runner.run_demo(tmp_path, workers=2)
    err = capsys.readouterr().err
    assert "[demo] 2 scenarios on 2 worker processes" in err
    text = report.read_text()
    assert text.index("## srf-rbar") < text.index("## station-keeping")
    for k, name in enumerate(names, start=1):
        summary = json.loads((tmp_path / name / "summary.json").read_text())
        assert summary["scenario"] == name
        assert f"[demo {k}/2] {name}: {summary['status']} in " in err
        section = text.split(f"## {name}")[1].split("\n## ")[0]
        assert f"| status | {summary['status']} |" in section
        figures = [line[line.index("(") + 1 : -1] for line in section.splitlines() if line.startswith("![")]
        assert figures and all((tmp_path / f).is_file() and f.startswith(f"{name}/") for f in figures)
