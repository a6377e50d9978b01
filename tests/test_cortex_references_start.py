"""`proxops cortex references` starts its worker pool before the CLI and the cortex system module are
imported (proxops.exec.entry -> proxops.exec.prestart.prestart_from_argv), with the arguments the command
itself starts it with; anything in doubt is left to the command, which reports bad input as usual."""

from __future__ import annotations

import inspect
import subprocess
import sys
from pathlib import Path

import pytest

from proxops.exec.prestart import MAX_FIBONACCI_N, _read_cortex_references_argv, _without_global_options

SRC = str(Path(__file__).resolve().parents[1] / "src")


def test_defaults_and_bound_are_the_commands():
    """The reader's defaults are the command's own (its signature) and its --n bound the schema's."""
    from proxops.cli_cortex import references
    from proxops.systems.schema.cortex import MAX_FIBONACCI_N as SCHEMA_MAX

    params = inspect.signature(references.__wrapped__ if hasattr(references, "__wrapped__") else references).parameters
    assert _read_cortex_references_argv(["cortex", "references"]) == (params["scenario"].default, params["n"].default,
                                                                      None, [])
    assert MAX_FIBONACCI_N == SCHEMA_MAX


@pytest.mark.parametrize("argv, expected", [
    (["cortex", "references", "--n", "100", "--workers", "2", "--out", "o"], ("cortex-reference", 100, 2, [])),
    (["-q", "cortex", "references", "--n=7", "--workers=3", "--out=o", "--scenario", "s.toml", "--set", "a=1",
      "--set=b=2", "--resume", "--no-figures", "--json"], ("s.toml", 7, 3, ["a=1", "b=2"])),
    (["cortex", "references", "--n", str(MAX_FIBONACCI_N)], ("cortex-reference", MAX_FIBONACCI_N, None, [])),
    (["cortex", "references", "--n", str(MAX_FIBONACCI_N + 1)], None),  # the command's error, no pool first
    (["cortex", "references", "--n", "0"], None),
    (["cortex", "references", "--n", "2.5"], None),
    (["cortex", "references", "--workers", "0"], None),
    (["cortex", "references", "--workers", "257"], None),  # above MAX_WORKERS
    (["cortex", "references", "--help"], None),
    (["cortex", "references", "--n"], None),  # value missing
    (["cortex", "references", "extra"], None),  # a positional
    (["cortex", "reference", "--n", "3"], None),  # the one-plan command: no pool
    (["mc", "references"], None),
])
def test_early_prestart_reads_only_unambiguous_references_command_lines(argv, expected):
    assert _read_cortex_references_argv(_without_global_options(argv)) == expected


def test_bad_scenario_after_early_prestart_is_one_error_line_exit_2(tmp_path):
    """The pool starts before parsing; a scenario that does not exist still ends with one ``error:`` line
    naming it, exit code 2, and no folder written."""
    env = {"PYTHONPATH": SRC, "PATH": "/usr/bin:/bin", "OPENBLAS_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-m", "proxops.exec.entry", "cortex", "references", "--scenario",
                           "no-such-scenario", "--n", "4", "--workers", "2", "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, env=env, timeout=300)  # fmt: skip
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith("error:") and "no-such-scenario" in lines[0], proc.stderr
    assert not (tmp_path / "o").exists()
