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
    # the plant's clock (a loop of its own) and the solver's are disjoint parts of a loop: never more than all of it
    assert 0.0 < probe["plant_share"] < 1.0 and probe["solver_share"] + probe["plant_share"] < 1.0


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
    # the breakdown's clocks are disjoint parts of its loop: the truth's kernels (DOP853, body state) inside the
    # plant's clock, the fused guidance + QP data kernel outside it; none of them inside the solver's
    b = probe
    assert 0.0 < b["plant_kernel_share"] <= b["plant_share"] < 1.0
    assert b["kernel_share"] > 0.0 and b["python_share"] > 0.0
    assert b["breakdown_solver_share"] + b["plant_share"] + b["kernel_share"] < 1.0
    assert b["breakdown_solver_share"] < b["compiled_bound"] < 1.0
    # the solver is called from the controller's step: its share of the step is above its share of the loop
    assert b["breakdown_solver_share"] < b["controller_share"] < 1.0
    assert b["breakdown_solver_share"] < b["solver_share_of_controller"] < 1.0


def _probe_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("ab_probe", ROOT / "benchmarks" / "_ab_probe.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_timer_counts_a_nested_call_once_into_the_clock_picked_at_the_call(monkeypatch):
    """_ab_probe._timer against a fake clock that advances 1 s per reading: the outer call reads it twice
    (2 readings apart: its own start, the nested call's nothing), a call with no clock is not timed."""
    probe = _probe_module()
    ticks = iter(range(100))
    monkeypatch.setattr(probe.time, "perf_counter", lambda: float(next(ticks)))
    clock = {"s": 0.0, "depth": 0}
    active = {"on": True}
    inner = probe._timer(lambda: "inner", lambda: clock if active["on"] else None)
    outer = probe._timer(lambda: inner(), lambda: clock if active["on"] else None)
    assert outer() == "inner"
    assert clock == {"s": 1.0, "depth": 0}  # one interval: the nested call read no clock
    active["on"] = False
    assert outer() == "inner" and clock["s"] == 1.0  # not timed at all


def test_breakdown_puts_every_kernel_back():
    """After the breakdown's loop every proxops module holds its numba kernels again (the timed loops and any
    later code see no wrapper)."""
    from numba.core.registry import CPUDispatcher

    from proxops import api

    probe = _probe_module()
    loaded = api.load_scenario("los-tumble", [])
    api.run(loaded)
    kernels = {(name, attr) for name, mod in list(sys.modules.items()) if name.startswith("proxops") and mod
               for attr, value in vars(mod).items() if isinstance(value, CPUDispatcher)}
    out = probe.breakdown(loaded)
    assert out is not None and out["kernel_share"] > 0.0 and 0.0 < out["plant_kernel_share"] <= out["plant_share"]
    after = {(name, attr) for name, mod in list(sys.modules.items()) if name.startswith("proxops") and mod
             for attr, value in vars(mod).items() if isinstance(value, CPUDispatcher)}
    assert kernels and kernels <= after


def _ab():
    import importlib.util

    spec = importlib.util.spec_from_file_location("ab_bench", ROOT / "benchmarks" / "ab.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_goal_verdict_needs_every_repetition_and_names_an_unresolved_one():
    """A goal is met only when every repetition meets it: the 10:26-10:40 UTC passes of 2026-11-28 put
    `proxops mc` at 4.12-4.60 s against its 4 s goal, a spread a median verdict hides."""
    ab = _ab()
    assert ab.verdict([3.6, 3.9, 3.95], 4.0, below=True) == "met"
    assert ab.verdict([4.0, 4.4, 4.6], 4.0, below=True) == "NOT met"  # at the goal is not below it
    assert ab.verdict([3.9, 4.1, 4.6], 4.0, below=True) == "met in 1 of 3 repetitions only"
    assert ab.verdict([0.50, 0.53, 0.52], 0.5, below=False) == "met"  # a share at the line meets ">= 50 %"
    assert ab.verdict([0.49, 0.53, 0.52], 0.5, below=False) == "met in 2 of 3 repetitions only"


def test_ratio_spread_pairs_the_repetitions_that_ran_side_by_side():
    ab = _ab()
    this = [{"wall_s": 1.0}, {"wall_s": 1.2}, {"error": "x"}, {"wall_s": 0.9}]
    prev = [{"wall_s": 2.0}, {"wall_s": 1.0}, {"wall_s": 1.0}, {"wall_s": 1.0}]
    assert ab._ratio_range(this, prev) == "reps x0.50-1.20"  # pairs 0, 1 and 3; the failed one is left out
    assert ab._ratio_range(this[:1], prev[:1]) == ""  # one pair has no spread
