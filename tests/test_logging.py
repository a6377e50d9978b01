"""Stage lines on stderr: one per stage when stderr is not a terminal (a log file sees progress),
none with --quiet; --json keeps stdout one JSON object either way."""

import json

from typer.testing import CliRunner

from proxops.cli import app

ARGS = ["run", "station-keeping", "--set", "sim.duration_s=120", "--json"]


def test_stage_lines_when_stderr_is_a_log():
    done = CliRunner().invoke(app, ARGS)
    assert done.exit_code == 0, done.output
    lines = [ln for ln in done.stderr.splitlines() if ln.startswith("proxops: ")]
    assert any("station-keeping scenario loaded" in ln for ln in lines)
    assert any("ran in" in ln and "status completed" in ln for ln in lines)
    assert json.loads(done.stdout)["scenario"] == "station-keeping"


def test_quiet_leaves_stderr_empty_and_verbose_keeps_the_stages():
    quiet = CliRunner().invoke(app, ["--quiet", *ARGS])
    assert quiet.exit_code == 0 and quiet.stderr == ""
    verbose = CliRunner().invoke(app, ["--verbose", *ARGS])
    assert verbose.exit_code == 0 and "ran in" in verbose.stderr
