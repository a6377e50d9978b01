"""Every script in examples/ runs (shortened with --quick) and prints what it says it prints."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCRIPTS = sorted(p for p in EXAMPLES.glob("*.py") if not p.name.startswith("_"))


def test_every_example_is_listed_in_its_readme():
    listed = (EXAMPLES / "README.md").read_text()
    assert SCRIPTS and all(f"`{p.name}`" in listed for p in SCRIPTS)


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_example_runs(script, monkeypatch, capsys):
    monkeypatch.chdir(EXAMPLES)
    monkeypatch.syspath_prepend(str(EXAMPLES))
    monkeypatch.setattr(sys, "argv", [str(script), "--quick"])
    runpy.run_path(str(script), run_name="__main__")
    out = capsys.readouterr().out
    assert out.strip(), f"{script.name} printed nothing"
    assert "Traceback" not in out


def test_custom_controller_holds_the_point(monkeypatch, capsys):
    """The PD law of the example converges on the hold point (stable gains: kp > 3n^2 radially)."""
    import re

    monkeypatch.chdir(EXAMPLES)
    monkeypatch.syspath_prepend(str(EXAMPLES))
    monkeypatch.setattr(sys, "argv", ["custom_controller.py", "--quick"])
    runpy.run_path(str(EXAMPLES / "custom_controller.py"), run_name="__main__")
    error = float(re.search(r"final position error ([\d.]+) m", capsys.readouterr().out).group(1))
    assert error < 1.0
