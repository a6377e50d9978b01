"""Monte Carlo campaigns: dispersions, seeds, backends (serial, local pool, Dask LocalCluster),
resumable results, failures, statistics, CLI and report.

Reference values come from the dispersion definitions (srf-hopping-mpc.md §5: 10 %, at
least 1 m / 0.1 m/s), numpy's SeedSequence spawn API, closed-form order statistics of
1..100, and re-running the same run alone (bit-for-bit equality).
"""

from __future__ import annotations

import copy
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

import test_campaign_toy as toy
from proxops.analysis.campaign import (
    read_rows,
    CampaignResult,
    RunError,
    is_timing_column,
    load_campaign,
    map_runs,
    rerun,
    run_campaign,
    run_seeds,
)
from proxops.report.campaign import write_report
from proxops.analysis.dispersions import parse_dispersions
from proxops.analysis.statistics import describe, outcome_counts
from proxops.cli import app
from proxops.errors import ProxopsInputError
from proxops.scenarios.loader import validate_scenario

TESTS_DIR = Path(__file__).parent
SRC_DIR = TESTS_DIR.parent / "src"


def toy_data(**toy_keys) -> dict:
    data = copy.deepcopy(toy.TOY_SCENARIO)
    data["toy"].update(toy_keys)
    return data


def same_rows(a: CampaignResult, b: CampaignResult) -> None:
    pd.testing.assert_frame_equal(a.deterministic_table(), b.deterministic_table(), check_exact=True)


# --------------------------------------------------------------------------- dispersions
def test_percent_dispersion_scale_is_ten_percent_with_minimum_offset():
    """srf-hopping-mpc.md §5: +-10 % of each component, at least 1 m / 0.1 m/s where nominal is small."""
    data = toy_data()
    data["initial"] = {"position_m": [2000.0, 0.0, -50.0], "velocity_mps": [0.0, 0.5, 0.0]}
    data["dispersions"] = {"initial": {"position_m": {"percent": 10, "min_abs": 1.0},
                                       "velocity_mps": {"percent": 10, "min_abs": 0.1}}}
    sc = validate_scenario(data).scenario
    plan = parse_dispersions(sc)
    rng = np.random.default_rng(0)
    draws = [plan.sample(rng) for _ in range(4000)]
    pos = np.array([[d[f"initial.position_m[{i}]"] for i in range(3)] for d in draws])
    vel = np.array([[d[f"initial.velocity_mps[{i}]"] for i in range(3)] for d in draws])
    half_pos = np.array([200.0, 1.0, 5.0])  # max(10 % |nominal|, 1 m)
    half_vel = np.array([0.1, 0.1, 0.1])  # max(10 % |nominal|, 0.1 m/s): 0.05 < 0.1
    dpos = pos - np.array([2000.0, 0.0, -50.0])
    dvel = vel - np.array([0.0, 0.5, 0.0])
    assert np.all(np.abs(dpos) <= half_pos) and np.all(np.abs(dvel) <= half_vel + 1e-15)
    # uniform on [-h, h]: extremes approach h, std = h / sqrt(3)
    np.testing.assert_allclose(np.abs(dpos).max(axis=0), half_pos, rtol=0.01)
    np.testing.assert_allclose(dpos.std(axis=0), half_pos / np.sqrt(3), rtol=0.05)
    np.testing.assert_allclose(dvel.std(axis=0), half_vel / np.sqrt(3), rtol=0.05)


def test_normal_and_clipped_dispersions():
    data = toy_data()
    data["dispersions"] = {
        "initial.position_m[0]": {"percent": 10, "distribution": "normal"},  # sigma = 2 m
        "actuator.missed_probability": {"sigma": 0.2, "clip": [0.0, 1.0]},
    }
    plan = parse_dispersions(validate_scenario(data).scenario)
    rng = np.random.default_rng(1)
    draws = [plan.sample(rng) for _ in range(4000)]
    x = np.array([d["initial.position_m[0]"] for d in draws])
    p = np.array([d["actuator.missed_probability"] for d in draws])
    assert abs(x.mean() - 20.0) < 0.15 and abs(x.std() - 2.0) < 0.1
    assert p.min() >= 0.0 and p.max() <= 1.0 and (p == 0.0).any()  # clipped at 0 (nominal 0.05, sigma 0.2)


def test_choice_and_low_high_dispersions():
    data = toy_data()
    data["dispersions"] = {"initial.frame": {"choice": ["hill", "lvlh-srf"]},
                           "toy.gain_scale": {"low": 0.5, "high": 2.0}}
    plan = parse_dispersions(validate_scenario(data).scenario)
    rng = np.random.default_rng(2)
    draws = [plan.sample(rng) for _ in range(2000)]
    frames = [d["initial.frame"] for d in draws]
    gains = np.array([d["toy.gain_scale"] for d in draws])
    assert set(frames) == {"hill", "lvlh-srf"} and abs(frames.count("hill") / 2000 - 0.5) < 0.05
    assert gains.min() >= 0.5 and gains.max() <= 2.0 and abs(gains.mean() - 1.25) < 0.03  # U(0.5, 2): mean 1.25


def test_grid_is_a_cartesian_product_with_groups_zipped():
    data = toy_data()
    data["dispersions"] = {
        "toy.gain_scale": {"grid": [0.5, 1.0, 2.0]},
        "initial.position_m": {"grid": [[10.0, -100.0, 0.0], [20.0, -150.0, 0.0]]},
        "actuator.magnitude_sigma": {"grid": [0.1, 0.2], "group": "level"},
        "actuator.missed_probability": {"grid": [0.05, 0.10], "group": "level"},
    }
    plan = parse_dispersions(validate_scenario(data).scenario)
    assert plan.n_grid == 3 * 2 * 2
    points = [plan.grid_point(i) for i in range(plan.n_grid)]
    combos = {(p["toy.gain_scale"], p["initial.position_m[1]"], p["actuator.magnitude_sigma"]) for p in points}
    assert len(combos) == 12  # every combination once
    for p in points:  # grouped keys vary together
        assert (p["actuator.magnitude_sigma"], p["actuator.missed_probability"]) in {(0.1, 0.05), (0.2, 0.10)}
    assert points[0]["actuator.magnitude_sigma"] == 0.1 and points[1]["actuator.magnitude_sigma"] == 0.2  # last axis fastest


@pytest.mark.parametrize("table, message", [
    ({"initial.positon_m": {"percent": 10}}, "no 'positon_m' in initial"),
    ({"controller.kp": {"sigma": 1.0}}, "no 'controller' in the scenario's top level"),
    ({"initial.position_m[5]": {"sigma": 1.0}}, "index [5] is out of range"),
    ({"initial.position_m": {"sigma": [1.0, 2.0]}}, "2 components given but initial.position_m has 3"),
    ({"initial.position_m": {"percent": 10, "sigma": 1.0}}, "give exactly one of"),
    ({"initial.position_m": {"grid": [1.0, 2.0]}}, "each value must be a list of 3 numbers"),
    ({"initial.frame": {"sigma": 1.0}}, "needs a numeric value"),
    ({"sim.seed": {"sigma": 1.0}}, "whole number"),
    ({"initial": {"position_m": 3}}, "expected a table"),
    ({"a": {"grid": [1], "group": "g"}, "b": {"grid": [1, 2], "group": "g"}}, "does not exist"),
])
def test_bad_dispersions_are_clear_errors(table, message):
    data = toy_data()
    data["dispersions"] = table
    with pytest.raises(ProxopsInputError, match="dispersions") as err:
        run_campaign(data, n_runs=2, workers=1, progress=False)
    assert message in str(err.value)


def test_run_seeds_follow_the_seedsequence_spawn_tree():
    children = np.random.SeedSequence(42).spawn(5)
    for i, child in enumerate(children):
        sim_child, disp_child = child.spawn(2)
        seed, rng = run_seeds(42, i)
        assert seed == int(sim_child.generate_state(1, np.uint64)[0] >> np.uint64(1))
        assert rng.random() == np.random.default_rng(disp_child).random()
    assert len({run_seeds(42, i)[0] for i in range(200)}) == 200


# --------------------------------------------------------------------------- statistics
def test_describe_matches_closed_form_order_statistics():
    st = describe(np.arange(1, 101))
    assert st["n"] == 100 and st["mean"] == 50.5
    assert st["std"] == pytest.approx(np.sqrt(100 * 101 / 12))  # sample std of 1..n = sqrt(n(n+1)/12)
    # linear interpolation at position q (n - 1): Q1 = 1 + 24.75, P99 = 1 + 98.01
    assert (st["q1"], st["median"], st["q3"], st["p99"]) == pytest.approx((25.75, 50.5, 75.25, 99.01))
    assert describe([])["n"] == 0


# --------------------------------------------------------------------------- campaigns
@pytest.fixture(scope="module")
def serial_campaign():
    return run_campaign(toy_data(), n_runs=12, workers=1, seed=11, progress=False)


def test_rows_hold_seed_dispersed_values_outcome_and_metrics(serial_campaign):
    t = serial_campaign.table
    assert list(t["run_id"]) == list(range(12))
    assert {"seed", "grid_index", "outcome", "success", "status", "error"} <= set(t.columns)
    assert {f"disp.initial.position_m[{i}]" for i in range(3)} <= set(t.columns)
    assert {"metric.total_dv_mps", "metric.final_range_m", "metric.hold_error_m"} <= set(t.columns)
    assert t["seed"].nunique() == 12
    assert (t["outcome"] == "success").all()
    # the stored dispersed start is the simulated start: min range <= initial range
    r0 = np.linalg.norm(t[[f"disp.initial.position_m[{i}]" for i in range(3)]].to_numpy(), axis=1)
    assert np.all(t["metric.min_range_m"].to_numpy() <= r0 + 1e-9)


def test_single_run_reruns_bit_for_bit_from_its_row(serial_campaign):
    row = serial_campaign.table.iloc[7].to_dict()
    again, series = rerun(row, serial_campaign)
    for key, val in row.items():
        if is_timing_column(key):
            continue
        assert again[key] == val, key
    assert series is not None and series.meta["seed"] == row["seed"]


def test_local_pool_and_dask_give_identical_rows(serial_campaign, tmp_path):
    from distributed import Client, LocalCluster

    pool = run_campaign(toy_data(), n_runs=12, workers=2, seed=11, progress=False, chunk_size=2)
    same_rows(serial_campaign, pool)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as cluster:
        dask = run_campaign(toy_data(), n_runs=12, scheduler=cluster.scheduler_address, seed=11, progress=False)
        with Client(cluster, set_as_default=False) as client:  # an existing Client works too
            squares = map_runs(toy.square, range(7), scheduler=client)
        scheduler_file = tmp_path / "scheduler.json"  # what `dask scheduler --scheduler-file` writes
        scheduler_file.write_text(json.dumps({"type": "Scheduler", "address": cluster.scheduler_address}))
        cubes = map_runs(toy.cube, range(5), scheduler=str(scheduler_file))
    same_rows(serial_campaign, dask)
    assert squares == [i * i for i in range(7)] and cubes == [i ** 3 for i in range(5)]


def test_a_raising_run_is_recorded_and_the_campaign_goes_on(tmp_path):
    res = run_campaign(toy_data(raise_if_x_above_m=20.0), n_runs=10, workers=1, seed=2, out=tmp_path / "c",
                       progress=False)
    t = res.table
    raised = t["disp.initial.position_m[0]"] > 20.0
    assert 0 < raised.sum() < 10 and len(t) == 10
    assert (t.loc[raised, "outcome"] == "error").all()
    assert t.loc[raised, "error"].str.contains("toy failure").all()
    assert (t.loc[~raised, "outcome"] == "success").all()
    counts = res.counts()
    assert counts["errors"] == raised.sum() and counts["failed"] == raised.sum()
    assert res.statistics().loc["total_dv_mps", "n"] == (~raised).sum()


def test_success_hook_and_violation_counts():
    # hold 100 m away from the target: a 100.5 m keep-out sphere is violated, a 1 cm tolerance fails most runs
    res = run_campaign(toy_data(keep_out_m=100.5, success_tolerance_m=0.01), n_runs=6, workers=1, progress=False)
    counts = outcome_counts(res.table)
    assert counts["with_violations"] == 6 and counts["violations_by_constraint"] == {"keep_out": 6}
    ok = res.table["metric.hold_error_m"] < 0.01
    assert counts["succeeded"] == ok.sum()


def test_grid_defaults_n_runs_to_grid_size_and_report_draws_figures(tmp_path):
    data = toy_data()
    data["dispersions"] = {"toy.gain_scale": {"grid": [0.5, 2.0]},
                           "initial.position_m[0]": {"linspace": [5.0, 35.0, 3]},
                           "initial.velocity_mps": {"half_width": 0.01}}
    res = run_campaign(data, workers=1, out=tmp_path / "g", keep_series=True, progress=False)
    assert len(res.table) == 6 and res.manifest["n_grid"] == 6
    assert sorted(res.table["grid_index"]) == list(range(6))
    rep = write_report(tmp_path / "g")
    names = {Path(f).name for f in rep["files"]}
    assert {"statistics.csv", "report.md", "dv_distribution.png", "outcome_map.png", "trajectories.png"} <= names
    assert "Grid point 5" in (tmp_path / "g" / "report" / "report.md").read_text()
    series = res.series(3)
    assert series.x_true[0, 0] == res.table.loc[3, "disp.initial.position_m[0]"]


def test_resume_runs_only_what_is_missing_and_extends(tmp_path):
    out = tmp_path / "r"
    first = run_campaign(toy_data(), n_runs=4, workers=1, seed=5, out=out, progress=False)
    assert first.new_runs == 4
    again = run_campaign(toy_data(), n_runs=4, workers=1, seed=5, out=out, resume=True, progress=False)
    assert again.new_runs == 0
    more = run_campaign(toy_data(), n_runs=7, workers=1, seed=5, out=out, resume=True, progress=False)
    assert more.new_runs == 3 and len(more.table) == 7
    whole = run_campaign(toy_data(), n_runs=7, workers=1, seed=5, progress=False)
    same_rows(load_campaign(out), whole)


def test_bad_campaign_inputs_are_clear_errors(tmp_path):
    out = tmp_path / "c"
    run_campaign(toy_data(), n_runs=2, workers=1, seed=1, out=out, progress=False)
    other = toy_data()
    other["sim"]["duration_s"] = 300.0
    with pytest.raises(ProxopsInputError, match="holds a campaign of scenario 'toy'.*not of 'toy' with these overrides"):
        run_campaign(other, n_runs=2, workers=1, seed=1, out=out, resume=True, progress=False)
    with pytest.raises(ProxopsInputError, match="--set"):
        run_campaign(toy_data(), n_runs=2, workers=1, seed=1, out=out, resume=True, overrides=["sim.duration_s=300"],
                     progress=False)
    with pytest.raises(ProxopsInputError, match="seed 9 differs"):
        run_campaign(toy_data(), n_runs=2, workers=1, seed=9, out=out, resume=True, progress=False)
    with pytest.raises(ProxopsInputError, match="pass --resume"):
        run_campaign(toy_data(), n_runs=2, workers=1, seed=1, out=out, progress=False)
    with pytest.raises(ProxopsInputError, match="nothing to resume"):
        run_campaign(toy_data(), n_runs=2, workers=1, out=tmp_path / "empty", resume=True, progress=False)
    for n in (0, -3, 2.5):
        with pytest.raises(ProxopsInputError, match="runs"):
            run_campaign(toy_data(), n_runs=n, workers=1, progress=False)
    with pytest.raises(ProxopsInputError, match="give the number of runs"):
        run_campaign(toy_data(), workers=1, progress=False)
    with pytest.raises(ProxopsInputError, match="workers"):
        run_campaign(toy_data(), n_runs=2, workers=0, progress=False)


def test_unreachable_scheduler_fails_fast_with_a_clear_error(tmp_path):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ProxopsInputError, match="could not connect within 1 s"):
        run_campaign(toy_data(), n_runs=2, scheduler=f"tcp://127.0.0.1:{port}", connect_timeout_s=1.0, progress=False,
                     out=tmp_path / "never")
    assert not (tmp_path / "never").exists()  # nothing written before the scheduler answered
    with pytest.raises(ProxopsInputError, match="no such scheduler file"):
        map_runs(toy.square, [1], scheduler=str(tmp_path / "nope.json"))
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as empty:
        with pytest.raises(ProxopsInputError, match="no workers after 1 s"):
            map_runs(toy.square, [1], scheduler=empty.scheduler_address, connect_timeout_s=1.0)


def test_map_runs_keeps_order_passes_context_and_returns_errors():
    assert map_runs(toy.square, range(9), workers=2, chunk_size=2) == [i * i for i in range(9)]
    assert map_runs(toy.scaled, [1, 2, 3], workers=1, context=10.0) == [10.0, 20.0, 30.0]
    out = map_runs(toy.fail_on_three, range(5), workers=1, errors="return")
    assert isinstance(out[3], RunError) and "three" in out[3].message and out[4] == 4
    with pytest.raises(ValueError, match="three"):
        map_runs(toy.fail_on_three, range(5), workers=1)


def test_a_killed_worker_is_replaced_and_its_run_recorded(tmp_path):
    # runs whose dispersed x0 exceeds 21.5 m kill their worker process (os._exit): with seed 4, one of 6
    res = run_campaign(toy_data(exit_if_x_above_m=21.5), n_runs=6, workers=2, seed=4, out=tmp_path / "k",
                       progress=False)
    t = res.table
    killer = t["disp.initial.position_m[0]"] > 21.5
    assert len(t) == 6 and killer.sum() == 1
    assert t.loc[killer, "error"].str.startswith("WorkerLost").all()
    assert (t.loc[~killer, "outcome"] == "success").all()


# --------------------------------------------------------------------------- killed and resumed
# (Ctrl-C at every moment is tested in test_interrupt.py)
def test_killed_campaign_resumes_to_the_uninterrupted_table(tmp_path):
    from test_interrupt import N_RUNS, _builds, _start, _wait_for

    k = 10
    proc, out, gate = _start(tmp_path, workers=2, gate_open=k)  # runs after the 10th wait at the gate
    _wait_for(lambda: _builds(gate) >= k + 2 and len(read_rows(out)) > 0, proc, "rows on disk, workers held")
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)
    saved = load_campaign(out)
    assert 0 < len(saved.table) <= k and (saved.table["outcome"] == "success").all()
    scenario = str(tmp_path / "toy.toml")
    resumed = run_campaign(scenario, n_runs=N_RUNS, workers=1, seed=8, out=out, resume=True, progress=False)
    assert resumed.new_runs == N_RUNS - len(saved.table)
    whole = run_campaign(scenario, n_runs=N_RUNS, workers=1, seed=8, progress=False)  # uninterrupted, in memory
    same_rows(load_campaign(out), whole)


# --------------------------------------------------------------------------- CLI
def test_cli_mc_json_and_report(tmp_path):
    runner = CliRunner()
    out = tmp_path / "sk"
    args = ["mc", "station-keeping-mc", "--runs", "4", "--workers", "1", "--out", str(out), "--no-progress",
            "--set", "truth.model=cw", "--set", "sim.duration_s=300", "--json"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    obj = json.loads(res.stdout)
    assert {"runs", "succeeded", "failed", "wall_time_s", "statistics"} <= set(obj)
    assert obj["runs"] == 4 and obj["succeeded"] + obj["failed"] == 4
    assert set(obj["statistics"]["total_dv_mps"]) >= {"mean", "std", "q1", "median", "q3", "p99"}
    rep = runner.invoke(app, ["report", str(out), "--json"])
    assert rep.exit_code == 0, rep.output
    assert (out / "report" / "report.md").is_file() and (out / "report" / "outcome_map.png").is_file()


@pytest.mark.parametrize("args, message", [
    (["--runs", "0"], "--runs 0"),
    (["--runs", "-2"], "--runs -2"),
    (["--runs", "2", "--workers", "0"], "--workers 0"),
    (["--runs", "2", "--set", "dispersions.initial.velocity_mps.percent=-1"], "percent"),
])
def test_cli_mc_bad_input_is_one_line_exit_2(tmp_path, args, message):
    res = CliRunner().invoke(app, ["mc", "station-keeping-mc", "--out", str(tmp_path / "x"), "--no-progress", *args])
    assert res.exit_code == 2, res.output
    assert message in res.stderr and "Traceback" not in res.stderr


def test_cli_report_on_a_non_campaign_folder(tmp_path):
    res = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert res.exit_code == 2 and "not a campaign folder" in res.stderr
