"""The A/B benchmark's probe (benchmarks/_ab_probe.py) counts what it says it counts.

Independent reference: the srf summary's own count of MPC solves (``solves``), which the srf
controller keeps itself; the probe wraps the solver adapters' ``solve`` from outside.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_probe_counts_every_solver_call_once_and_share_is_a_fraction():
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "_ab_probe.py"), "loop", "srf-rbar", "1"],
                         env=env, capture_output=True, text=True, check=True)
    probe = json.loads(out.stdout.strip().splitlines()[-1])
    from proxops import api

    summary, _ = api.run(api.load_scenario("srf-rbar", []))
    assert probe["solver_calls"] == summary["solves"] > 0
    assert 0.0 < probe["solver_share"] < 1.0 and 0.0 < probe["run_solver_share"] < 1.0
    assert probe["solver_s"] < probe["wall_s"]  # the solver clock runs inside the loop's clock of the same call


def test_probe_counts_the_lean_daqp_solves_of_the_los_loop():
    """The los MPC solves through DaqpQP.solve_fast (issue 32 item 2): one QP per controller step (no
    refinements), so the probe's count equals the engine's step count of the run."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "_ab_probe.py"), "loop", "los-tumble", "1"],
                         env=env, capture_output=True, text=True, check=True)
    probe = json.loads(out.stdout.strip().splitlines()[-1])
    from proxops import api

    summary, _ = api.run(api.load_scenario("los-tumble", []))
    assert probe["solver_calls"] == summary["steps"] > 0
    assert 0.0 < probe["solver_share"] < 1.0
