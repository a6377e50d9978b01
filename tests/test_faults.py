"""Faults leave nothing behind (issue 25, item 5): a ``kill -9`` of ``proxops mc`` takes its fork
server, its workers and its resource tracker with it, and the caller's pipes reach EOF; a Ctrl-C at
any moment of the start gives exactly one line and exit code 130.

Waits are on state (files the campaign writes, the process table, EOF of the pipes); the only
sleeps are the moments of the Ctrl-C, which are what the test is about.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import psutil
import pytest

SRC_DIR = Path(__file__).resolve().parents[1] / "src"


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC_DIR), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def _proxops(*args: str, **kwargs) -> subprocess.Popen:
    """``proxops ARGS`` as a real process (its own session, pipes on stdout and stderr); SIGINT is
    restored to Python's default handler, as a terminal's foreground process has it (a shell that
    starts jobs in the background leaves it ignored)."""
    code = ("import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
            "sys.argv = ['proxops', *sys.argv[1:]]; from proxops.exec.entry import main; main()")
    return subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, env=_env(), **kwargs)


class _Drain:
    """Read a pipe to EOF in a thread (a full pipe must never block the child); ``eof`` is set
    when every process holding its write end has closed it."""

    def __init__(self, pipe):
        self.data = b""
        self.eof = threading.Event()
        self._thread = threading.Thread(target=self._read, args=(pipe,), daemon=True)
        self._thread.start()

    def _read(self, pipe):
        while chunk := pipe.read1(65536) if hasattr(pipe, "read1") else pipe.read(65536):
            self.data += chunk
        self.eof.set()


def _wait_for(predicate, what: str, timeout: float = 240.0, proc: subprocess.Popen | None = None) -> None:
    t0 = time.monotonic()
    while not predicate():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"the process ended before {what} (exit {proc.returncode})")
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(0.02)  # polling interval of a state check


def _alive(procs: list[psutil.Process]) -> list[psutil.Process]:
    out = []
    for p in procs:
        try:
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
        except psutil.NoSuchProcess:
            pass
    return out


KILL_CASES = [  # the command (slow: numba's srf kernels load), and a campaign of cheap runs
    pytest.param(["srf-vbar-mc", "--runs", "200"], marks=pytest.mark.slow, id="srf-vbar-mc"),
    pytest.param(["station-keeping-mc", "--runs", "100000", "--set", "truth.model=cw", "--set", "sim.duration_s=600"],
                 id="station-keeping-mc"),
]


@pytest.mark.parametrize("campaign", KILL_CASES)
def test_kill_9_of_mc_leaves_no_process_and_the_pipes_reach_eof(tmp_path, campaign):
    out = tmp_path / "mc"
    proc = _proxops("mc", *campaign, "--workers", "2", "--out", str(out))
    stdout, stderr = _Drain(proc.stdout), _Drain(proc.stderr)
    family: list[psutil.Process] = []
    try:
        # mid-run: the first runs are saved (a part is written every 2 s) and both workers exist
        _wait_for(lambda: any((out / "runs").glob("part-*.parquet")), "the first saved runs", proc=proc)
        me = psutil.Process(proc.pid)
        family = me.children(recursive=True)
        names = [" ".join(p.cmdline()) for p in family]
        # the resource tracker and the fork server (children of proxops), the 2 workers (of the server)
        assert len(family) >= 4, names
        assert any("resource_tracker" in n for n in names) and any("forkserver" in n for n in names), names
        proc.send_signal(signal.SIGKILL)
        t_kill = time.monotonic()
        proc.wait(timeout=10)
        _wait_for(lambda: not _alive(family), "every process of the campaign to end", timeout=5.0)
        assert stdout.eof.wait(5.0 - (time.monotonic() - t_kill)) and stderr.eof.wait(0.1), "a pipe is still open"
    finally:
        if proc.poll() is None:
            family += psutil.Process(proc.pid).children(recursive=True)
            proc.kill()
        for p in _alive(family):  # a failed test must not leave them running either
            p.kill()


def _session_alive(sid: int) -> list[int]:
    out = []
    for p in psutil.process_iter(["pid", "status"]):
        try:
            if os.getsid(p.info["pid"]) == sid and p.info["status"] != psutil.STATUS_ZOMBIE:
                out.append(p.info["pid"])
        except OSError:
            pass
    return out


@pytest.mark.parametrize("after_s", [0.5, 2.0, 4.0])
def test_ctrl_c_during_the_start_of_mc_is_one_line_and_exit_130(tmp_path, after_s):
    """The issue's moments: 0.5 s (the CLI's imports, the fork server's start), 2 s (the fork server
    imports the warm-up, the command line is parsed), 4 s (the campaign's checks, workers starting).
    Before: 5 of 10 Ctrl-Cs at 3-5 s exited 130 in silence (typer's own handler), and the fork
    server printed a KeyboardInterrupt traceback."""
    proc = _proxops("mc", "srf-vbar-mc", "--runs", "200", "--workers", "2", "--out", str(tmp_path / "mc"),
                    "--no-progress")  # the bar's redraws are not messages
    time.sleep(after_s)  # the moment of the Ctrl-C is what is tested
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal sends: the whole foreground group
    t0 = time.monotonic()
    _, err = proc.communicate(timeout=120)  # both pipes at EOF and the process ended
    took = time.monotonic() - t0
    text = err.decode()
    # before, proxops waited for the fork server to finish its imports and fork the workers it had
    # been asked for (24-30 s measured at 0.5-1.5 s, under load); now 0.03-0.14 s
    assert took < 10.0, (took, text)
    lines = [ln for ln in text.splitlines() if ln.strip()]
    assert proc.returncode == 130, text
    assert len(lines) == 1 and lines[0].startswith("interrupted"), text
    _wait_for(lambda: not _session_alive(proc.pid), "every process of the session to end", timeout=10.0)


def test_ctrl_c_while_the_command_line_is_parsed_is_not_silent():
    """typer turns a KeyboardInterrupt raised outside a command's ``invoke`` (here: in an eager
    option's callback, while the command line is parsed) into exit code 130 with no message; the
    proxops group says ``interrupted``."""
    import typer
    from typer.testing import CliRunner

    from proxops.cli_common import ProxopsGroup

    def _interrupt(value: bool):
        if value:
            raise KeyboardInterrupt

    app = typer.Typer(cls=ProxopsGroup, add_completion=False)

    @app.callback()
    def main(now: bool = typer.Option(False, "--now", callback=_interrupt, is_eager=True)):
        pass

    @app.command()
    def work():
        pass

    res = CliRunner().invoke(app, ["--now", "work"])
    assert res.exit_code == 130
    assert [ln for ln in res.stderr.splitlines() if ln.strip()] == ["interrupted"]
