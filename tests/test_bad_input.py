"""Bad input a user can give, across every command: exit code 2, exactly one ``error:`` line
on stderr, no traceback (issue: reliability). Each case names what is wrong; the expected
fragment is checked in the message so the line is the right one, not merely one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

import test_campaign_toy  # noqa: F401  (registers the toy system for the campaign cases)
from proxops.cli import app

SK = ["--set", "truth.model=cw", "--set", "sim.duration_s=300"]  # a station-keeping run of a few ms


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("bad")
    f = {"dir": d, "afile": d / "afile", "bad_toml": d / "bad.toml", "bad_system": d / "badsys.toml",
         "empty": d / "empty.toml", "unknown_key": d / "unknown.toml", "wrong_type": d / "type.toml"}
    f["afile"].write_text("x")
    f["bad_toml"].write_text('name = "x"\nsystem = "srf"\n[sim\n')
    f["bad_system"].write_text('name = "x"\nsystem = "nope"\n')
    f["empty"].write_text("")
    f["not_utf8"] = d / "latin1.toml"
    f["not_utf8"].write_bytes('name = "caf\u00e9"\nsystem = "srf"\n'.encode("latin-1"))
    base = Path(__file__).resolve().parents[1] / "src/proxops/scenarios/builtin/station-keeping.toml"
    f["unknown_key"].write_text(base.read_text().replace("[sim]", "[sim]\nbogus_key_s = 3.0", 1))
    f["wrong_type"].write_text(base.read_text().replace("[sim]", '[sim]\ncheck_substeps = "many"', 1))
    # campaign folders: a good one (toy, 2 runs), then damaged copies
    good = d / "good"
    res = CliRunner().invoke(app, ["mc", _toy_file(d), "--runs", "2", "--workers", "1", "--out", str(good),
                                   "--no-progress", "--json"])
    assert res.exit_code == 0, res.output
    f["good"] = good
    for name, damage in (("trunc_manifest", "manifest"), ("bad_part", "part"), ("other_version", "version")):
        import shutil

        copy = d / name
        shutil.copytree(good, copy)
        if damage == "manifest":
            text = (copy / "campaign.json").read_text()
            (copy / "campaign.json").write_text(text[: len(text) // 2])
        elif damage == "part":
            part = next((copy / "runs").glob("part-*.parquet"))
            part.write_bytes(part.read_bytes()[:40])
        else:
            m = json.loads((copy / "campaign.json").read_text())
            m["proxops_version"] = "0.0.1"
            (copy / "campaign.json").write_text(json.dumps(m))
        f[name] = copy
    mixed = d / "mixed"
    (mixed / "runs").mkdir(parents=True)
    (mixed / "runs" / "part-00000000-00000009-old.parquet").write_bytes(b"old rows")
    f["mixed"] = mixed
    f["toy"] = Path(_toy_file(d))
    return f


def _toy_file(d: Path) -> str:
    from test_interrupt import write_toy_toml

    return str(write_toy_toml(d / "toy.toml"))


# (case id, args with {placeholders} for files, fragment expected in the error line)
CASES = [
    # scenario files and TOML
    ("no-such-scenario", ["run", "nosuch"], "no such file"),
    ("invalid-toml", ["run", "{bad_toml}"], "not valid TOML"),
    ("unknown-system", ["run", "{bad_system}"], "system"),
    ("scenario-is-folder", ["validate", "{dir}"], ""),
    ("empty-toml", ["validate", "{empty}"], ""),
    ("unknown-key", ["validate", "{unknown_key}"], "bogus_key_s"),
    ("wrong-type", ["validate", "{wrong_type}"], "check_substeps"),
    ("set-without-equals", ["validate", "station-keeping", "--set", "sim.duration_s"], "sim.duration_s"),
    ("set-unknown-key", ["validate", "station-keeping", "--set", "sim.nope_s=3"], "nope_s"),
    ("set-unknown-section", ["validate", "station-keeping", "--set", "nosection.x_m=3"], "nosection"),
    # values: range, NaN, inf, types
    ("duration-nan", ["run", "station-keeping", "--set", "sim.duration_s=nan"], "finite"),
    ("duration-inf", ["run", "station-keeping", "--set", "sim.duration_s=inf"], "finite"),
    ("duration-negative", ["validate", "station-keeping", "--set", "sim.duration_s=-5"], "duration_s"),
    ("duration-text", ["validate", "station-keeping", "--set", "sim.duration_s=abc"], "duration_s"),
    ("dt-longer-than-run", ["run", "station-keeping", "--set", "sim.dt_s=1000", "--set", "sim.duration_s=100"],
     "dt_s"),
    ("controller-dt-longer-than-run", ["validate", "station-keeping", "--set", "controller.dt_s=600.001", "--set",
                                       "sim.duration_s=600"], "no step"),
    ("duration-too-many-steps", ["validate", "station-keeping", "--set", "sim.duration_s=1e12"],
     "at most 2,000,000 steps"),
    ("string-for-number", ["validate", "cortex-nominal", "--set", 'geometry.r_kos_m="15"'], "geometry.r_kos_m = '15'"),
    ("string-for-bool", ["validate", "hybrid-capture", "--set", 'latch.snap="yes"'], "latch.snap = 'yes'"),
    ("float-for-int", ["validate", "srf-vbar", "--set", "approach.hops=3.5"], "approach.hops"),
    ("check-substeps-zero", ["validate", "station-keeping", "--set", "sim.check_substeps=0"], "check_substeps"),
    ("altitude-underground", ["validate", "station-keeping", "--set", "orbit.altitude_km=-100"], "Earth"),
    ("ecc-above-one", ["validate", "station-keeping", "--set", "orbit.ecc=1.5"], "ecc"),
    ("srf-angle-400", ["validate", "srf-vbar", "--set", "approach.angle_deg=400"], "angle_deg"),
    ("srf-hops-zero", ["validate", "srf-vbar", "--set", "approach.hops=0"], "hops"),
    ("srf-gamma-above-one", ["validate", "srf-vbar", "--set", "approach.gamma=1.5"], "gamma"),
    ("srf-start-text", ["validate", "srf-vbar", "--set", "approach.start_m=abc"], "start_m"),
    ("srf-epsilon-infeasible", ["validate", "srf-vbar", "--set", "mpc.epsilon_m=2000"], "epsilon_m"),
    ("srf-koz-larger-than-start", ["validate", "srf-vbar", "--set", "keep_out.radius_m=5000"], "keep-out"),
    ("srf-unknown-solver", ["validate", "srf-vbar", "--set", "mpc.solver=foo"], "solver"),
    ("srf-trim-after-hop-end", ["validate", "srf-vbar", "--set", "mpc.drift_trim_delay_nodes=6"],
     "drift_trim_delay_nodes"),
    ("srf-trim-window-zero", ["validate", "srf-vbar", "--set", "mpc.drift_estimator_window_s=0"],
     "drift_estimator_window_s"),
    ("los-rate-nan", ["validate", "los-tumble", "--set", "target.tumble_rate_deg_s=nan"], "tumble_rate_deg_s"),
    # seeds
    ("run-seed-negative", ["run", "station-keeping", "--seed", "-1", *SK], "--seed"),
    ("set-seed-negative", ["run", "station-keeping", "--set", "sim.seed=-1"], "seed"),
    ("mc-seed-negative", ["mc", "station-keeping-mc", "--runs", "2", "--seed", "-1", "--out", "{dir}/s1"], "seed"),
    ("run-seed-text", ["run", "station-keeping", "--seed", "one"], "--seed"),
    # options of the wrong type or unknown
    ("workers-text", ["mc", "station-keeping-mc", "--workers", "two"], "--workers"),
    ("runs-text", ["mc", "station-keeping-mc", "--runs", "many"], "--runs"),
    ("unknown-option", ["run", "station-keeping", "--bogus"], "--bogus"),
    ("missing-argument", ["run"], "scenario"),
    ("unknown-command", ["fly"], "fly"),
    # hop-times
    ("hop-sma-zero", ["hop-times", "--approach-deg", "0", "--sma-km", "0"], "semi-major axis"),
    ("hop-angle-400", ["hop-times", "--approach-deg", "400"], "--approach-deg"),
    ("hop-angle-nan", ["hop-times", "--approach-deg", "nan"], "--approach-deg"),
    ("hop-hops-zero", ["hop-times", "--approach-deg", "0", "--hops", "0"], "hops"),
    ("hop-gamma-two", ["hop-times", "--approach-deg", "0", "--gamma", "2"], "gamma"),
    ("hop-both-sizes", ["hop-times", "--approach-deg", "0", "--altitude-km", "500", "--sma-km", "8000"], "at most one"),
    ("hop-period-fraction", ["hop-times", "--approach-deg", "0", "--vbar-period-fraction", "1.5"], "fraction"),
    # campaigns: sizes, scheduler, timeouts
    ("mc-runs-zero", ["mc", "station-keeping-mc", "--runs", "0"], "--runs"),
    ("mc-runs-negative", ["mc", "station-keeping-mc", "--runs", "-2"], "--runs"),
    ("mc-runs-too-many", ["mc", "station-keeping-mc", "--runs", "100000000", "--out", "{dir}/big"], "10,000,000"),
    ("mc-workers-zero", ["mc", "station-keeping-mc", "--runs", "2", "--workers", "0"], "--workers"),
    ("mc-timeout-nan", ["mc", "station-keeping-mc", "--runs", "2", "--connect-timeout-s", "nan"], "connect-timeout"),
    ("mc-timeout-negative", ["mc", "station-keeping-mc", "--runs", "2", "--connect-timeout-s", "-1"], "connect-timeout"),
    ("mc-scheduler-no-port", ["mc", "station-keeping-mc", "--runs", "2", "--scheduler", "tcp://", "--out",
                              "{dir}/sch1"], "--scheduler"),
    ("mc-scheduler-malformed", ["mc", "station-keeping-mc", "--runs", "2", "--scheduler", "foo:bar:baz", "--out",
                                "{dir}/sch2"], "--scheduler"),
    ("mc-scheduler-no-file", ["mc", "station-keeping-mc", "--runs", "2", "--scheduler", "{dir}/none.json", "--out",
                              "{dir}/sch3"], "scheduler file"),
    ("mc-dispersion-negative", ["mc", "station-keeping-mc", "--runs", "2", "--out", "{dir}/d1", "--set",
                                "dispersions.initial.velocity_mps.percent=-1"], "percent"),
    ("mc-infeasible-nominal", ["mc", "srf-vbar-mc", "--runs", "2", "--out", "{dir}/koz", "--set",
                               "keep_out.radius_m=5000"], "keep-out"),
    # campaign folders: mixed, damaged, resumed wrongly
    ("mc-out-is-file", ["mc", "station-keeping-mc", "--runs", "2", "--out", "{afile}"], "is a file"),
    ("mc-out-mixed", ["mc", "station-keeping-mc", "--runs", "2", "--out", "{mixed}"], "no campaign.json"),
    ("mc-resume-nothing", ["mc", "station-keeping-mc", "--runs", "2", "--out", "{dir}/empty-resume", "--resume"],
     "nothing to resume"),
    ("mc-resume-other-scenario", ["mc", "station-keeping-mc", "--runs", "2", "--out", "{good}", "--resume"],
     "holds a campaign"),
    ("mc-resume-other-seed", ["mc", "{toy}", "--out", "{good}", "--resume", "--seed", "99"], "seed"),
    ("mc-resume-other-version", ["mc", "{toy}", "--out", "{other_version}", "--resume"], "0.0.1"),
    ("mc-resume-damaged-manifest", ["mc", "{toy}", "--out", "{trunc_manifest}", "--resume"], "damaged"),
    ("mc-new-on-existing", ["mc", "{toy}", "--runs", "2", "--out", "{good}"], "--resume"),
    ("report-not-campaign", ["report", "{dir}"], "not a campaign folder"),
    ("report-file", ["report", "{afile}"], "not a folder"),
    ("report-damaged-manifest", ["report", "{trunc_manifest}"], "damaged"),
    ("report-damaged-part", ["report", "{bad_part}"], "unreadable"),
    ("report-dir-is-file", ["report", "{good}", "--report-dir", "{afile}"], "--report-dir"),
    ("report-max-overlay", ["report", "{good}", "--max-overlay", "-1"], "--max-overlay"),
    # output paths: a file, cannot be created, read-only file system
    ("run-out-is-file", ["run", "station-keeping", "--out", "{afile}", *SK], "is a file"),
    ("run-out-under-file", ["run", "station-keeping", "--out", "{afile}/sub", *SK], "cannot create"),
    ("run-out-read-only", ["run", "station-keeping", "--out", "/proc/proxops-test", *SK], "--out"),
    ("demo-out-is-file", ["demo", "--out", "{afile}"], "is a file"),
    ("demo-out-read-only", ["demo", "--out", "/sys/proxops-test"], "--out"),
    ("demo-workers-zero", ["demo", "--workers", "0", "--out", "{dir}/demo"], "--workers = 0: must be a whole number from 1"),
    ("reach-map-out-is-file", ["reach", "map", "--omega-deg", "2", "--amax", "0.1", "--out", "{afile}"], "is a file"),
    ("reach-map-out-read-only", ["reach", "map", "--omega-deg", "2", "--amax", "0.1", "--out", "/proc/x"], "--out"),
    ("report-dir-read-only", ["report", "{good}", "--report-dir", "/sys/proxops-test"], "--report-dir"),
    # every command that writes checks its output folder first, and refuses a campaign's folder
    ("run-out-campaign", ["run", "station-keeping", "--out", "{good}", *SK], "is a campaign folder"),
    ("demo-out-campaign", ["demo", "--out", "{good}"], "is a campaign folder"),
    ("cortex-reference-out-campaign", ["cortex", "reference", "--out", "{good}"], "is a campaign folder"),
    ("cortex-reference-out-is-file", ["cortex", "reference", "--out", "{afile}"], "--out"),
    ("cortex-references-out-is-file", ["cortex", "references", "--n", "2", "--out", "{afile}"], "--out"),
    ("cortex-references-out-read-only", ["cortex", "references", "--n", "2", "--out", "/proc/x"], "--out"),
    ("reach-table-out-is-file", ["reach", "table", "--out", "{afile}"], "--out"),
    ("reach-table-out-campaign", ["reach", "table", "--out", "{good}"], "is a campaign folder"),
    ("reach-mc-out-is-file", ["reach", "mc", "--out", "{afile}"], "--out"),
    ("reproduce-out-is-file", ["reproduce", "los", "--quick", "--out", "{afile}"], "--out"),
    ("reproduce-out-read-only", ["reproduce", "los", "--quick", "--out", "/proc/x"], "--out"),
    ("mc-out-read-only", ["mc", "station-keeping-mc", "--runs", "2", "--out", "/proc/x"], "--out"),
    ("mc-out-under-file", ["mc", "station-keeping-mc", "--runs", "2", "--out", "{afile}/sub"], "--out"),
    # reach sizes and values
    ("reach-map-grid-huge", ["reach", "map", "--omega-deg", "2", "--amax", "0.1", "--grid", "100000", "--out",
                             "{dir}/rm"], "3000"),
    ("reach-map-grid-two", ["reach", "map", "--omega-deg", "2", "--amax", "0.1", "--grid", "2", "--out",
                            "{dir}/rm"], "--grid"),
    ("reach-map-omega-negative", ["reach", "map", "--omega-deg", "-1", "--amax", "0.1", "--out", "{dir}/rm"],
     "--omega-deg"),
    ("reach-map-amax-nan", ["reach", "map", "--omega-deg", "2", "--amax", "nan", "--out", "{dir}/rm"], "--a-max-mps2"),  # the canonical name (--amax is its alias)
    ("reach-table-grid-huge", ["reach", "table", "--grid", "1000000"], "3000"),
    ("reach-mc-nx-huge", ["reach", "mc", "--out", "{dir}/rmc", "--n-x", "100000"], "--n-x"),
    ("reach-mc-ny-zero", ["reach", "mc", "--out", "{dir}/rmc", "--n-y", "0"], "--n-y"),
    ("reach-mc-duration-nan", ["reach", "mc", "--out", "{dir}/rmc", "--duration-s", "nan"], "--duration-s"),
    ("keys-unknown-system", ["keys", "nosystem"], "nosystem"),
    # internal errors that were input errors (issue 25): a scenario of another system, bytes, sizes
    ("propagate-srf-no-initial", ["propagate", "--scenario", "srf-vbar", "--duration-s", "100"], "[initial]"),
    ("cortex-reference-srf", ["cortex", "reference", "--scenario", "srf-vbar"], "give a cortex one"),
    ("cortex-references-srf", ["cortex", "references", "--scenario", "srf-vbar", "--n", "3"], "give a cortex one"),
    ("scenario-not-utf8", ["validate", "{not_utf8}"], "not UTF-8"),
    ("orbit-in-the-atmosphere", ["propagate", "--scenario", "station-keeping", "--duration-s", "100", "--set",
                                 "orbit.altitude_km=99.9"], ">= 100 km"),
    ("orbit-sma-in-the-atmosphere", ["validate", "srf-vbar", "--set", "orbit.sma_km=6478.0"], ">= 100 km"),
    ("cortex-references-n-huge", ["cortex", "references", "--n", "1000000000"], "1,000,000"),
    ("cortex-eclipse-samples-huge", ["cortex", "reference", "--set", "eclipse.samples_per_orbit=1000000000"],
     "samples_per_orbit"),
    ("cortex-eclipse-orbits-huge", ["validate", "cortex-reference", "--set", "eclipse.orbits=1e9"], "orbits"),
    ("cortex-fibonacci-n-huge", ["validate", "cortex-reference", "--set", "axis.fibonacci_n=1000001"], "fibonacci_n"),
    ("cortex-kos-iter-huge", ["validate", "cortex-reference", "--set", "planner.kos_max_iter=1001"], "kos_max_iter"),
    ("underactuated-horizon-huge", ["validate", "underactuated-case1", "--set", "controller.horizon=1001"],
     "horizon"),
    ("mc-workers-huge", ["mc", "station-keeping-mc", "--runs", "3", "--workers", "257"], "--workers"),
    ("cortex-references-workers-huge", ["cortex", "references", "--n", "3", "--workers", "257"], "--workers"),
    ("reach-mc-workers-huge", ["reach", "mc", "--out", "{dir}/rmw", "--workers", "257"], "--workers"),
    ("hop-hops-huge", ["hop-times", "--approach-deg", "0", "--hops", "51"], "--hops"),
    ("propagate-multistep-j2", ["propagate", "--scenario", "station-keeping", "--duration-s", "100", "--set",
                                'truth.integrator="multistep"'], "integrator = 'multistep' needs model = 'full'"),
    ("propagate-multistep-srp", ["propagate", "--scenario", "station-keeping", "--duration-s", "100", "--model",
                                 "full", "--set", "truth.srp=true", "--set", 'truth.integrator="multistep"'],
     "without srp"),
    ("propagate-integrator-unknown", ["propagate", "--scenario", "station-keeping", "--duration-s", "100", "--set",
                                      'truth.integrator="rk4"'], "truth.integrator"),
]


@pytest.mark.parametrize("case, args, fragment", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_and_exit_2(files, case, args, fragment):
    argv = [a.format(**{k: str(v) for k, v in files.items()}) for a in args]
    res = CliRunner().invoke(app, argv)
    err = res.stderr
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert res.exit_code == 2, (argv, res.exit_code, err, res.exception)
    assert "Traceback" not in err and "Traceback" not in res.stdout, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert fragment in lines[0], (fragment, lines[0])


def test_at_least_sixty_distinct_cases():
    assert len({c[0] for c in CASES}) == len(CASES) >= 60


def test_a_mixed_folder_is_refused_before_anything_is_written(files):
    before = sorted(p.name for p in files["mixed"].rglob("*"))
    res = CliRunner().invoke(app, ["mc", str(files["toy"]), "--runs", "2", "--workers", "1", "--out",
                                   str(files["mixed"]), "--no-progress"])
    assert res.exit_code == 2
    assert sorted(p.name for p in files["mixed"].rglob("*")) == before


# --------------------------------------------------------------------------- no silent nonsense
def test_srf_run_away_from_the_reference_point_is_not_arrived_and_fails():
    # the nominal V-bar run ends ~1-3 m from the reference point (srf §5.1); a 1 mm tolerance is
    # the boundary case where the engine's "handover" stop must not read as success
    # the summary is printed all the same; the exit code says "finished but failed" (4), one line on stderr
    res = CliRunner().invoke(app, ["run", "srf-vbar", "--json", "--set", "safety.reference_tolerance_m=0.001"])
    assert res.exit_code == 4, res.output
    s = json.loads(res.stdout)
    assert s["arrived"] is False and s["reached_reference"] is False
    assert s["status"].startswith("failed: ended") and s["arrival_error_m"] > 0.001
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("error:")]  # besides stage lines (logging)
    assert len(errors) == 1 and "finished but failed" in errors[0] and "exit code 4" in errors[0], res.stderr


def test_the_exit_codes_are_documented_in_help_and_readme():
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    assert "4 a run that finished but failed" in " ".join(readme.split())
    res = CliRunner().invoke(app, ["--help"])
    assert "4 a run that finished but failed" in " ".join(res.stdout.replace("│", " ").split())


def test_mc_with_every_run_failed_exits_3(files, tmp_path):
    # toy success needs the hold error below success_tolerance_m; 1e-9 m is below any closed loop's error
    res = CliRunner().invoke(app, ["mc", str(files["toy"]), "--runs", "3", "--workers", "1", "--out",
                                   str(tmp_path / "f"), "--no-progress", "--json",
                                   "--set", "toy.success_tolerance_m=1e-9"])
    assert res.exit_code == 3, res.output
    assert json.loads(res.stdout)["succeeded"] == 0
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "all 3 runs failed" in lines[0]


# --------------------------------------------------------------------------- no data mixed or lost
def test_resume_never_deletes_a_results_file_it_did_not_write(files, tmp_path):
    from proxops.analysis.campaign import load_campaign, run_campaign

    out = tmp_path / "c"
    run_campaign(str(files["toy"]), n_runs=4, workers=1, seed=5, out=out, progress=False)
    first = sorted((out / "runs").glob("part-*.parquet"))
    assert first
    run_campaign(str(files["toy"]), n_runs=7, workers=1, seed=5, out=out, resume=True, progress=False)
    assert all(p.is_file() for p in first)  # the first session's files survive the second's compaction
    assert sorted(load_campaign(out).table["run_id"]) == list(range(7))


def test_same_seed_campaigns_compare_equal_and_different_seeds_do_not(files):
    from proxops.analysis.campaign import is_timing_column, run_campaign

    a = run_campaign(str(files["toy"]), n_runs=5, workers=1, seed=11, progress=False).deterministic_table()
    b = run_campaign(str(files["toy"]), n_runs=5, workers=1, seed=11, progress=False).deterministic_table()
    c = run_campaign(str(files["toy"]), n_runs=5, workers=1, seed=12, progress=False).deterministic_table()
    assert a.equals(b) and not a.equals(c)
    assert not any(is_timing_column(col) for col in a.columns)
    for col in ("metric.mpc_solve_ms.median", "metric.solve_time_ms.p95", "metric.wall_time_s", "run_cpu_s"):
        assert is_timing_column(col), col


def test_malformed_scheduler_prints_one_line_in_a_real_process(tmp_path):
    # a half-built distributed.Client used to print a traceback from __del__ when collected at exit
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "proxops.exec.entry", "mc", "station-keeping-mc", "--runs", "2",
                           "--scheduler", "tcp://", "--out", str(tmp_path / "x")],
                          capture_output=True, text=True, timeout=120)
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: --scheduler"), proc.stderr


# --------------------------------------------------------------------------- outputs checked first
@pytest.mark.parametrize("argv, work", [
    (["reproduce", "los", "--quick", "--out", "{afile}"], "proxops.report.reproduction.reproduce"),
    (["cortex", "reference", "--out", "{good}"], "proxops.systems.cortex.plan_scenario"),
    (["run", "station-keeping", "--out", "{good}"], "proxops.runner.run_scenario"),
    (["reach", "table", "--out", "{afile}"], "proxops.analysis.reach.reach_table"),
    (["mc", "station-keeping-mc", "--runs", "2", "--out", "{afile}/sub"], "proxops.analysis.campaign.run_campaign"),
], ids=["reproduce", "cortex-reference", "run", "reach-table", "mc"])
def test_output_folders_are_checked_before_any_work(files, monkeypatch, argv, work):
    """`reproduce los --quick --out FILE` computed for 99 s before it failed (issue 25): the work
    function must not even be called; a campaign folder is left exactly as it was."""
    import importlib

    module, name = work.rsplit(".", 1)
    monkeypatch.setattr(importlib.import_module(module), name,
                        lambda *a, **k: pytest.fail(f"{work} ran before the output check"))
    before = {p: p.read_bytes() for p in files["good"].rglob("*") if p.is_file()}
    res = CliRunner().invoke(app, [a.format(**{k: str(v) for k, v in files.items()}) for a in argv])
    assert res.exit_code == 2 and res.stderr.startswith("error: --out"), res.stderr
    assert {p: p.read_bytes() for p in files["good"].rglob("*") if p.is_file()} == before


def test_a_campaign_check_of_a_new_folder_leaves_nothing_behind(tmp_path):
    from proxops.cli_common import check_out_dir

    target = tmp_path / "a" / "b" / "c"
    assert check_out_dir(target, campaign=True) == target
    assert list(tmp_path.iterdir()) == []
    assert check_out_dir(target).is_dir()  # one result: the folder is made


# --------------------------------------------------------------------------- cross-field and types
def test_a_control_period_equal_to_the_run_is_one_step_and_valid():
    # the boundary of "controller-dt-longer-than-run": dt = duration is one step, allowed
    res = CliRunner().invoke(app, ["run", "station-keeping", "--set", "controller.dt_s=600", "--set",
                                   "sim.duration_s=600", "--set", "truth.model=cw", "--json"])
    assert res.exit_code == 0, res.stderr
    assert json.loads(res.stdout)["sim_time_s"] == 600.0


def test_toml_integers_are_numbers_for_float_keys_but_strings_and_floats_are_not_coerced(tmp_path):
    from proxops.scenarios.loader import load_scenario

    base = Path(__file__).resolve().parents[1] / "src/proxops/scenarios/builtin/station-keeping.toml"
    text = base.read_text()
    ok = tmp_path / "int.toml"
    ok.write_text(_with_key(text, "sim", "duration_s", "600"))
    sc = load_scenario(str(ok)).scenario
    assert sc.sim.duration_s == 600.0 and isinstance(sc.sim.duration_s, float)
    assert load_scenario("station-keeping", ["sim.duration_s=600"]).scenario.sim.duration_s == 600.0
    for value, fragment in (('"600"', "valid number"), ("true", "valid number")):
        bad = tmp_path / "bad.toml"
        bad.write_text(_with_key(text, "sim", "duration_s", value))
        res = CliRunner().invoke(app, ["validate", str(bad)])
        assert res.exit_code == 2 and "sim.duration_s" in res.stderr and fragment in res.stderr, res.stderr


def _with_key(text: str, section: str, key: str, value: str) -> str:
    """``text`` (TOML) with ``key`` of ``[section]`` set to ``value`` (replaced or added)."""
    import re

    head, sep, rest = text.partition(f"[{section}]\n")
    body, nxt, tail = rest.partition("\n[")
    body = re.sub(rf"^{key}\s*=.*$\n?", "", body, flags=re.M)
    return head + sep + f"{key} = {value}\n" + body + nxt + tail


def test_the_lowest_allowed_orbit_is_valid():
    # the boundary of "orbit-in-the-atmosphere": a perigee altitude of exactly 100 km is allowed
    from proxops.scenarios.loader import load_scenario

    assert load_scenario("station-keeping", ["orbit.altitude_km=100.0"]).scenario.orbit.sma_m == 6478137.0
