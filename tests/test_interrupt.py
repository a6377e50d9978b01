"""Ctrl-C at any moment of ``proxops mc``: one message, exit 130, no finished run lost, no
process left behind, and ``--resume`` completes the campaign to the uninterrupted table.

Every wait here is on state (files the runs create, the signal-pending mask of /proc, the
process table), never on a sleep: the toy system's gate (``PROXOPS_TOY_GATE``) holds runs
after the first K so the campaign is stopped in a known state.
"""

from __future__ import annotations

import copy
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import test_campaign_toy as toy
from proxops.analysis.campaign import load_campaign, run_campaign

TESTS_DIR = Path(__file__).resolve().parent
SRC_DIR = TESTS_DIR.parent / "src"
N_RUNS = 30

_CHILD = """
import signal, sys
# a shell that starts jobs in the background (CI does) leaves SIGINT ignored in its children;
# a user's Ctrl-C reaches a foreground process with Python's default handler, so restore it
signal.signal(signal.SIGINT, signal.default_int_handler)
sys.path[:0] = [{tests!r}, {src!r}]
import test_campaign_toy  # registers the toy system (its workers import it by name)
if __name__ == "__main__":  # spawned workers import this file as __mp_main__
    from proxops.exec.entry import main
    sys.argv = ["proxops", "mc", {scenario!r}, "--runs", "{n}", "--workers", "{workers}", "--seed", "8",
                "--out", {out!r}, "--no-progress"]
    main()
"""


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    return repr(v)


def write_toy_toml(path: Path) -> Path:
    """The toy scenario as TOML (flat tables; dispersion keys quoted)."""
    data = copy.deepcopy(toy.TOY_SCENARIO)
    lines = [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for table, body in data.items():
        if isinstance(body, dict):
            lines.append(f"[{table}]")
            lines += [f'"{k}" = {_toml_value(v)}' if "." in k else f"{k} = {_toml_value(v)}" for k, v in body.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def _start(tmp_path: Path, workers: int, gate_open: int) -> tuple[subprocess.Popen, Path, Path]:
    out, gate = tmp_path / "mc", tmp_path / "gate"
    scenario = write_toy_toml(tmp_path / "toy.toml")
    script = tmp_path / "child.py"
    script.write_text(_CHILD.format(tests=str(TESTS_DIR), src=str(SRC_DIR), scenario=str(scenario), n=N_RUNS,
                                    workers=workers, out=str(out)))
    env = dict(os.environ, PROXOPS_TOY_GATE=str(gate), PROXOPS_TOY_GATE_OPEN=str(gate_open))
    proc = subprocess.Popen([sys.executable, str(script)], start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    return proc, out, gate


def _wait_for(predicate, proc: subprocess.Popen, what: str, timeout: float = 300.0) -> None:
    t0 = time.monotonic()
    while not predicate():
        if proc.poll() is not None:
            raise AssertionError(f"child ended before {what}: {proc.communicate()}")
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.005)  # polling interval of a state check, not a wait for time to pass


def _builds(gate: Path) -> int:
    return sum(p.name.startswith("build-") for p in gate.iterdir()) if gate.is_dir() else 0


def _sigint_delivered(pid: int) -> bool:
    """SIGINT no longer pending for the process (its handler has run)."""
    status = Path(f"/proc/{pid}/status").read_text()
    mask = 0
    for key in ("SigPnd", "ShdPnd"):
        mask |= int(re.search(rf"{key}:\s*([0-9a-f]+)", status).group(1), 16)
    return not mask & (1 << (signal.SIGINT - 1))


def _session_processes(sid: int) -> list[int]:
    pids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[3]) == sid and fields[0] != "Z":
                pids.append(int(d.name))
    return pids


def _children(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


def _finish(proc: subprocess.Popen) -> str:
    _, err = proc.communicate(timeout=90)
    _wait_for_no_processes(proc.pid)
    return err


def _wait_for_no_processes(sid: int, timeout: float = 30.0) -> None:
    t0 = time.monotonic()
    while _session_processes(sid):
        assert time.monotonic() - t0 < timeout, f"processes left behind: {_session_processes(sid)}"
        time.sleep(0.01)


def _assert_one_interrupted_line(err: str) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert "Traceback" not in err and "Error" not in err, err
    assert len(lines) == 1 and lines[0].startswith("interrupted"), err


@pytest.mark.parametrize("workers", [1, 2])
def test_ctrl_c_mid_campaign_saves_every_finished_run_and_resume_completes_it(tmp_path, workers):
    k = 10  # runs that pass the gate; the rest wait for the release file
    proc, out, gate = _start(tmp_path, workers, gate_open=k)
    _wait_for(lambda: _builds(gate) >= k + workers, proc, "every worker held at the gate")
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal sends on Ctrl-C: the whole foreground group
    _wait_for(lambda: _sigint_delivered(proc.pid), proc, "SIGINT delivered")
    (gate / "release").touch()  # the runs in flight may now finish; they must be saved
    err = _finish(proc)
    assert proc.returncode == 130, err
    _assert_one_interrupted_line(err)
    saved = load_campaign(out)
    n_saved = int(re.search(r"interrupted: (\d+) new runs saved", err).group(1))
    assert len(saved.table) == n_saved and k <= n_saved < N_RUNS
    assert (saved.table["outcome"] == "success").all()  # workers ignored the Ctrl-C: nothing broke
    resumed = run_campaign(str(tmp_path / "toy.toml"), n_runs=N_RUNS, workers=1, seed=8, out=out, resume=True,
                           progress=False)
    assert resumed.new_runs == N_RUNS - n_saved
    whole = run_campaign(str(tmp_path / "toy.toml"), n_runs=N_RUNS, workers=1, seed=8, progress=False)
    a = load_campaign(out).deterministic_table().reset_index(drop=True)
    b = whole.deterministic_table().reset_index(drop=True)
    assert a.drop(columns=[c for c in a if c.startswith("metric.wall")]).equals(
        b.drop(columns=[c for c in b if c.startswith("metric.wall")])
    )


_CHILD_BUILTIN = """
import sys
sys.path[:0] = [{src!r}]
if __name__ == "__main__":
    from proxops.exec.entry import main
    sys.argv = ["proxops", "mc", "station-keeping-mc", "--runs", "40", "--workers", "2", "--out", {out!r},
                "--no-progress", "--set", "truth.model=cw", "--set", "sim.duration_s=600"]
    main()
"""


def _start_builtin(tmp_path: Path) -> subprocess.Popen:
    script = tmp_path / "child_builtin.py"
    script.write_text("import signal\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
                      + _CHILD_BUILTIN.format(src=str(SRC_DIR), out=str(tmp_path / "mc")))
    return subprocess.Popen([sys.executable, str(script)], start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _maps(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return ""


@pytest.mark.parametrize("moment", ["importing", "pool-starting"])
def test_ctrl_c_while_starting_gives_one_line_and_leaves_no_process(tmp_path, moment):
    proc = _start_builtin(tmp_path)
    if moment == "importing":  # proxops' imports are under way (numpy's C core is mapped)
        _wait_for(lambda: "_multiarray_umath" in _maps(proc.pid), proc, "numpy loaded")
    else:  # the parent has spawned pool workers; they are still importing
        _wait_for(lambda: len(_children(proc.pid)) >= 1, proc, "pool workers spawned")
    os.killpg(proc.pid, signal.SIGINT)
    err = _finish(proc)
    assert proc.returncode == 130, err
    _assert_one_interrupted_line(err)
    out = tmp_path / "mc"
    if (out / "campaign.json").is_file():  # runs that were in flight finished and were saved whole
        saved = load_campaign(out)
        assert saved.table["outcome"].isin(["success", "failure"]).all()


_CHILD_DEMO = """
import sys
sys.path[:0] = [{src!r}]
if __name__ == "__main__":
    from proxops.exec.entry import main
    sys.argv = ["proxops", "demo", "--workers", "2", "--out", {out!r}]
    main()
"""


def test_ctrl_c_stops_the_demo_at_once_with_one_line_and_no_process(tmp_path):
    # proxops demo runs its scenarios on 2 workers (runner.run_demo, map_runs with finish_in_flight=False): a
    # Ctrl-C while they run stops them at once (nothing of a demo is worth waiting for: hybrid-capture alone is
    # 5-9 s), so the scenario in flight leaves no summary and no report is written
    script = tmp_path / "child_demo.py"
    out = tmp_path / "demo"
    script.write_text("import signal\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
                      + _CHILD_DEMO.format(src=str(SRC_DIR), out=str(out)))
    proc = subprocess.Popen([sys.executable, str(script)], start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    _wait_for(lambda: sum(len(_children(c)) for c in _children(proc.pid)) >= 2, proc, "both demo workers forked")
    os.killpg(proc.pid, signal.SIGINT)
    err = _finish(proc)
    assert proc.returncode == 130, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert "Traceback" not in err and "Error" not in err, err
    assert lines[0].startswith("[demo] 6 scenarios on 2 worker processes") and lines[-1] == "interrupted", err
    assert not (out / "report.md").exists() and not (out / "hybrid-capture" / "summary.json").exists(), err
