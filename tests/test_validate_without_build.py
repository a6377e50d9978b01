"""``proxops validate`` checks srf, station-keeping, los and underactuated scenarios without building them (issue 32 item 5):
the schema's build-free check (:func:`proxops.scenarios.registry.check_without_build`) must raise the
very line the build raises (the system's ``check``: plant, controller, navigation and the engine's step
count) for every bad input, and pass every input the build passes. The reference here is the build
itself, run in the same process on the same scenario: each case is judged by both paths. The cases sit
on the boundaries of each check (one engine step, the MAX_STEPS limit, the V-bar hop ladder at its
limit, the reference point on the keep-out sphere and on radius + margin, the trim node at the hop's
end) on both sides."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from proxops.errors import ProxopsInputError
from proxops.scenarios.catalog import builtin_names
from proxops.scenarios.loader import load_scenario
from proxops.scenarios.registry import check_without_build

SRC = Path(__file__).resolve().parents[1] / "src"
CW = ["truth.model='cw'"]  # the build's onboard J2 ephemeris is skipped: the slow part of an srf build

# (scenario, overrides, what the build says: None = valid, else a fragment of its one line)
CASES = [
    # station-keeping: the engine's step count on controller.dt_s = 10 s
    ("station-keeping", ["sim.duration_s=10.0"], None),  # exactly one step
    ("station-keeping", ["sim.duration_s=9.99"], "shorter than the step of the closed loop"),
    ("station-keeping", ["controller.dt_s=600.001", "sim.duration_s=600.0"], "shorter than the step"),
    ("station-keeping", ["sim.duration_s=2e7"], None),  # 2,000,000 steps: MAX_STEPS exactly
    ("station-keeping", ["sim.duration_s=20000010.0"], "at most 2,000,000"),
    ("station-keeping", ["sim.duration_s=1e12"], "at most 2,000,000"),
    ("station-keeping", ["truth.model='cw'", "controller.type='pd'"], None),
    ("station-keeping", ["truth.model='two-body'", "actuator.missed_probability=1.0"], None),
    ("station-keeping-mc", [], None),
    # srf: Algorithm 1, the node schedule, the approach against the run
    ("srf-vbar", [], None),
    ("srf-vbar", ["sim.duration_s=10882.5"], "shorter than the 3-hop approach"),  # the approach ends at 10882.53 s
    ("srf-vbar", ["sim.duration_s=10882.6"], None),
    ("srf-vbar", ["mpc.horizon_steps=2"], "more hops than the MPC horizon"),
    ("srf-vbar", ["mpc.horizon_steps=3", "mpc.drift_trim=false"], None),  # one node per hop
    ("srf-vbar", ["mpc.horizon_steps=3"], "the trim must come 1 to 0 MPC nodes"),  # no node left for the trim
    ("srf-vbar", ["mpc.horizon_steps=10", "mpc.steps_per_hop=4"], "exceeds mpc.horizon_steps"),
    ("srf-vbar", ["sim.dt_s=1000.0"], "too short for 6 MPC steps"),  # a half-orbit hop of 3.6 engine steps
    ("srf-vbar", [*CW, "sim.dt_s=0.005"], "at most 2,000,000"),  # 2.2e6 engine steps
    ("srf-vbar", [*CW, "sim.dt_s=0.0055"], None),  # 1.98e6
    # the V-bar hop ladder (29n-o): 3 hops over 1900 m shrink by at most 633.3 m
    ("srf-vbar", ["mpc.epsilon_m=633.3"], None),
    ("srf-vbar", ["mpc.epsilon_m=633.4"], "cannot each shrink by 633.4 m"),
    ("srf-vbar", ["mpc.epsilon_m=2000"], "epsilon_m"),
    ("srf-vbar", ["mpc.h_max_m=683.4"], None),  # 3 h_max - 150 >= 1900
    ("srf-vbar", ["mpc.h_max_m=683.3"], "cannot cover 1900 m"),
    ("srf-vbar", ["mpc.h_min_m=600.0"], "h_min_m = 600 m"),
    # the keep-out zone: radius 50 m + margin 10 m, reference point 100 m out
    ("srf-vbar", ["keep_out.radius_m=100.0"], "the reference point lies inside the keep-out zone"),  # on the sphere
    ("srf-vbar", ["keep_out.radius_m=90.0"], "must lie outside the KOZ radius + margin"),  # on radius + margin
    ("srf-vbar", ["keep_out.radius_m=89.99"], None),
    ("srf-vbar", ["keep_out.radius_m=99.0", "keep_out.margin_m=0.0"], None),
    ("srf-vbar", ["keep_out.radius_m=5000"], "keep-out"),
    ("srf-vbar", ["keep_out.center_m=[2000.0, 0.0, 0.0]"], "starts inside the keep-out zone"),
    ("srf-rbar", ["initial.position_m=[0.0, 0.0, 120.0]", "keep_out.radius_m=50.0"], None),
    ("srf-rbar", ["keep_out.center_m=[0.0, 0.0, 1000.0]", "keep_out.radius_m=200.0"], None),
    # the drift trim: 1 to steps_per_hop - 1 nodes after the hop start
    ("srf-vbar", ["mpc.drift_trim_delay_nodes=5"], None),
    ("srf-vbar", ["mpc.drift_trim_delay_nodes=6"], "the trim must come 1 to 5 MPC nodes"),
    ("srf-vbar", ["mpc.drift_trim_delay_nodes=6", "mpc.drift_trim=false"], None),
    ("srf-rbar", ["mpc.drift_trim_delay_nodes=6"], None),  # V-bar only
    # glideslopes: Algorithm 1's roots and hop lengths against the engine step
    ("srf-glideslope-40", [], None),
    ("srf-glideslope-40", ["approach.angle_deg=60", "approach.gamma=0.1", "approach.hops=5"], "hop 5 lasts"),
    ("srf-glideslope-40", ["approach.angle_deg=20", "approach.hops=5"], "shorter than the 5-hop approach"),
    ("srf-glideslope-250", [], None),
    ("srf-cbf-demo", [], None),
    # los: an ECI truth, the PD frequency 2 pi / pd_period_s, the step count on sim.dt_s (default 1 s)
    ("los-tumble", [], None),
    ("los-tumble", ["truth.model='cw'"], "needs an ECI truth"),
    ("los-tumble", ["truth.model='two-body'"], None),
    ("los-tumble", ["guidance.pd_period_s=1e-150"], None),  # kp = (2 pi / 1e-150)^2 = 3.9e301
    ("los-tumble", ["guidance.pd_period_s=1e-154"], "kp = (2 pi / pd_period_s)^2 overflows"),  # an OverflowError before
    ("los-tumble", ["guidance.pd_period_s=1e-310"], "kp = (2 pi / pd_period_s)^2 overflows"),
    ("los-tumble", ["sim.duration_s=1.0"], None),  # one step of sim.dt_s = 1 s
    ("los-tumble", ["sim.dt_s=0.001", "sim.duration_s=2000.0"], None),  # 2,000,000 steps
    ("los-tumble", ["sim.dt_s=0.001", "sim.duration_s=2000.01"], "at most 2,000,000"),
    # underactuated: the planar model objects and plant, the step count on controller.dt_s
    ("underactuated-case1", [], None),
    ("underactuated-case1", ["sim.duration_s=1.999"], "shorter than the step of the closed loop (2 s"),
    ("underactuated-case1", ["controller.dt_s=0.0001", "sim.duration_s=200.01"], "at most 2,000,000"),
    ("underactuated-compare", ["deputy.mean_motion_rad_s=0.0", "deputy.damping_Nms=0.0"], None),
]


def _build_says(loaded) -> str | None:
    try:
        loaded.system.check(loaded.scenario)
    except ProxopsInputError as exc:
        return str(exc)
    return None


def _build_free_says(loaded) -> tuple[bool | None, str | None]:
    try:
        return check_without_build(loaded.scenario), None
    except ProxopsInputError as exc:
        return None, str(exc)


@pytest.mark.parametrize("name, overrides, fragment", CASES,
                         ids=[f"{n}:{','.join(o) or 'nominal'}" for n, o, _ in CASES])
def test_build_free_check_says_what_the_build_says(name, overrides, fragment):
    loaded = load_scenario(name, overrides)
    built = _build_says(loaded)
    covered, said = _build_free_says(loaded)
    if fragment is None:
        assert built is None, built
    else:
        assert built is not None and fragment in built, built
    assert said == built  # the same line, or both valid
    if said is None:
        assert covered is True  # every check of the build ran without it


def test_builtins_the_check_covers_and_those_it_leaves_to_the_build():
    """Every built-in srf, station-keeping, los and underactuated scenario is valid either way; the ekf
    and the full truth are left to the build (their filter, force models and data check themselves)."""
    names = [n for n in builtin_names() if n.startswith(("srf", "station-keeping", "los", "underactuated"))]
    assert len(names) >= 19
    for name in names:
        loaded = load_scenario(name)
        sc = loaded.scenario
        covered = check_without_build(sc)
        full = getattr(getattr(sc, "truth", None), "model", None) == "full"
        assert covered is not (sc.navigation.model == "ekf" or full), name
        assert _build_says(loaded) is None, name


def test_validate_imports_no_numba_scipy_system_or_engine():
    """`proxops validate srf-vbar` and `validate station-keeping` load the schema and the light
    pieces of the build (numpy at most): no system module, no engine, no numba, scipy or solver."""
    code = ("import atexit, json, sys\n"
            "atexit.register(lambda: sys.stderr.write('MODULES ' + json.dumps(sorted(sys.modules)) + '\\n'))\n"
            "sys.argv = ['proxops', 'validate', sys.argv[1]]\n"
            "from proxops.exec.entry import main\nmain()\n")
    for name in ("srf-vbar", "station-keeping"):
        proc = subprocess.run([sys.executable, "-c", code, name], capture_output=True, text=True, timeout=120,
                              env={**os.environ, "PYTHONPATH": str(SRC)})
        assert proc.returncode == 0 and "valid" in proc.stdout, proc.stderr
        line = next(ln for ln in proc.stderr.splitlines() if ln.startswith("MODULES "))
        modules = set(json.loads(line[len("MODULES "):]))
        top = {m.split(".")[0] for m in modules}
        assert not top & {"numba", "scipy", "llvmlite", "casadi", "daqp", "piqp", "clarabel", "highspy",
                          "pandas", "matplotlib"}, (name, sorted(top))
        assert not {m for m in modules if m.startswith(("proxops.sim.engine", "proxops.control", "proxops.propagation",
                                                        "proxops.solvers."))} - {"proxops.solvers.stats"}, name
        assert not {"proxops.systems.srf", "proxops.systems.station_keeping", "proxops.systems.common"} & modules


@pytest.mark.parametrize("given, expected", [(None, "__all__"), ("", ""), ("logfire", "logfire")])
def test_the_console_script_skips_the_pydantic_plugin_scan_unless_told(given, expected):
    """The console script sets PYDANTIC_DISABLE_PLUGINS=__all__ (pydantic then never reads every
    installed distribution's entry points) and keeps any value the user gave, an empty one included."""
    code = ("import atexit, os, sys\n"
            "atexit.register(lambda: sys.stderr.write('PLUGINS ' + repr(os.environ.get('PYDANTIC_DISABLE_PLUGINS')) + '\\n'))\n"
            "sys.argv = ['proxops', 'validate', 'station-keeping']\n"
            "from proxops.exec.entry import main\nmain()\n")
    env = {k: v for k, v in os.environ.items() if k != "PYDANTIC_DISABLE_PLUGINS"}
    if given is not None:
        env["PYDANTIC_DISABLE_PLUGINS"] = given
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**env, "PYTHONPATH": str(SRC)})
    assert proc.returncode == 0, proc.stderr
    assert f"PLUGINS {expected!r}" in proc.stderr
