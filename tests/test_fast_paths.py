"""Start-up and per-run fast paths (issue 18): each must give exactly what the slow path gives.

- the PIQP adapter's in-place matrix update (same pattern) vs building the matrix / a fresh set-up;
- the srf per-process caches (Algorithm 1 plan, target ephemeris, CW prediction blocks) vs cold;
- ``proxops mc`` on a local pool: the system check runs in the workers, its error is still one line;
- the CLI's exit without interpreter teardown: complete output, exit codes kept;
- numpy.f2py / numpy.testing deferred: scipy does not execute them, real use still works.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from proxops.solvers import _util
from proxops.solvers.piqp_qp import PiqpQP

SRC = str(Path(__file__).resolve().parents[1] / "src")


def _run(args: list[str], **kw) -> subprocess.CompletedProcess:
    env = {"PYTHONPATH": SRC, "PATH": "/usr/bin:/bin", "OPENBLAS_NUM_THREADS": "1"}
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, timeout=300, **kw)


# --------------------------------------------------------------------------- PIQP in-place update
def _random_csc(rng, shape, density=0.3) -> sp.csc_matrix:
    m = sp.random(*shape, density=density, format="csc", random_state=rng)
    m.sum_duplicates()
    m.sort_indices()
    return m


def test_refill_same_pattern_gives_the_converted_matrix_and_declines_anything_else():
    rng = np.random.default_rng(1)
    stored = _util.csc_matrix("G", _random_csc(rng, (8, 5)), (8, 5))
    value = stored.copy()
    value.data = rng.normal(size=value.nnz)
    out = _util.refill_same_pattern(stored, value)
    assert out is stored
    np.testing.assert_array_equal(out.toarray(), _util.csc_matrix("G", value, (8, 5)).toarray())
    other = _random_csc(np.random.default_rng(2), (8, 5))
    assert _util.refill_same_pattern(stored, other) is None  # another pattern: convert and rebuild
    assert _util.refill_same_pattern(stored, value.astype(np.float32)) is None
    assert _util.refill_same_pattern(stored, value.toarray()) is None
    assert _util.refill_same_pattern(stored, value.tocsr()) is None
    unsorted = value.copy()
    unsorted.indices = unsorted.indices.copy()
    col = next(j for j in range(5) if unsorted.indptr[j + 1] - unsorted.indptr[j] >= 2)
    a, b = unsorted.indptr[col], unsorted.indptr[col + 1]
    unsorted.indices[a:b] = unsorted.indices[a:b][::-1]
    unsorted.data[a:b] = unsorted.data[a:b][::-1]
    unsorted.has_sorted_indices = False
    assert _util.refill_same_pattern(stored, unsorted) is None  # same matrix, not canonical


def test_piqp_update_in_place_solves_like_a_fresh_setup_and_is_feasible():
    """Box-and-row-constrained QP; the G values change with the pattern kept. The updated solver's
    x equals a fresh solver's on the new data (1e-9) and satisfies the rows (1e-6)."""
    rng = np.random.default_rng(3)
    n, m = 6, 5
    P = sp.identity(n, format="csc")
    q = rng.normal(size=n)
    G0 = _random_csc(rng, (m, n), density=0.6)
    lo, hi = -np.ones(m), np.ones(m)
    lb, ub = -2 * np.ones(n), 2 * np.ones(n)
    from proxops.solvers.forms import QuadraticProgram

    solver = PiqpQP()
    solver.setup(QuadraticProgram(P, q, G0, lo, hi, lb, ub))
    solver.solve()
    G1 = G0.copy()
    G1.data = 3.0 * rng.normal(size=G1.nnz)
    solver.update(A=G1)
    got = solver.solve()
    assert not got.info["rebuilt"]
    fresh = PiqpQP()
    fresh.setup(QuadraticProgram(P, q, G1, lo, hi, lb, ub))
    ref = fresh.solve()
    assert got.ok and ref.ok
    np.testing.assert_allclose(got.x, ref.x, atol=1e-9)
    gx = G1 @ got.x
    assert np.all(gx >= lo - 1e-6) and np.all(gx <= hi + 1e-6)


# --------------------------------------------------------------------------- srf caches
def test_srf_prediction_blocks_are_shared_read_only_and_equal_the_cw_stm():
    from proxops.core.cw import cw_stm
    from proxops.scenarios.loader import load_scenario
    from proxops.systems.srf import build_controller, plan_of

    sc = load_scenario("srf-rbar").scenario
    c1, plan1, sched = build_controller(sc)
    c2, plan2, _ = build_controller(sc)
    assert c1._phi is c2._phi and c1._S is c2._S and c1._phi_tau is c2._phi_tau
    assert not (c1._phi.flags.writeable or c1._S.flags.writeable or c1._phi_tau.flags.writeable)
    T = sched.times
    for i, j in ((0, 0), (0, len(T) - 1), (3, 7)):
        np.testing.assert_array_equal(c1._phi[j, i], cw_stm(c1.n_orb, T[j] - T[i]))
    np.testing.assert_array_equal(c1._S[5][:, 3 * 2:3 * 2 + 3], cw_stm(c1.n_orb, T[5] - T[2])[:, 3:6])
    np.testing.assert_array_equal(c1._phi_tau[4], cw_stm(c1.n_orb, c1.tau[4]))
    # the plan is a copy: changing one leaves the next untouched
    plan1.hops[0].duration_s = -1.0
    assert plan_of(sc).hops[0].duration_s == plan2.hops[0].duration_s > 0


def test_srf_campaign_rows_with_warm_caches_equal_cold_ones():
    """V-bar (J2 ephemeris, drift rows) and a glideslope (Algorithm 1 root finding): 2 runs each
    after clearing every per-process cache, then again with them filled."""
    import proxops.control.srf_mpc as srf_mpc
    import proxops.systems.srf as srf
    from proxops.analysis.campaign import run_campaign

    for name in ("srf-vbar-mc", "srf-glideslope-40-mc"):
        for cache in (srf._PLAN_CACHE, srf._EPHEMERIS_CACHE, srf_mpc._BLOCK_CACHE):
            cache.clear()
        cold = run_campaign(name, n_runs=2, workers=1, seed=5, progress=False).deterministic_table()
        assert srf._PLAN_CACHE and srf_mpc._BLOCK_CACHE
        warm = run_campaign(name, n_runs=2, workers=1, seed=5, progress=False).deterministic_table()
        assert cold.equals(warm), name


# --------------------------------------------------------------------------- CLI
def test_mc_check_failing_in_the_pool_workers_is_one_line_and_writes_nothing(tmp_path):
    out = tmp_path / "mc"
    proc = _run(["-m", "proxops.exec.entry", "mc", "srf-rbar-mc", "--runs", "4", "--workers", "2", "--out", str(out),
                 "--no-progress", "--set", "keep_out.radius_m=5000"])
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: initial position") and "keep-out" in lines[0], lines
    assert not out.exists()


def test_cli_exit_without_teardown_keeps_output_and_exit_code(tmp_path):
    ok = _run(["-m", "proxops.exec.entry", "run", "station-keeping", "--json", "--set", "truth.model=cw",
               "--set", "sim.duration_s=300"])
    assert ok.returncode == 0, ok.stderr
    summary = json.loads(ok.stdout)  # exactly one JSON object, complete
    assert summary["scenario"] == "station-keeping" and summary["steps"] == 30
    bad = _run(["-m", "proxops.exec.entry", "run", "station-keeping", "--set", "sim.duration_s=-5"])
    assert bad.returncode == 2 and bad.stderr.count("error:") == 1


def test_deferred_numpy_submodules_are_not_executed_by_scipy_and_still_work():
    code = (
        "import sys\n"
        "from proxops.exec.startup import defer_unused_numpy_submodules\n"
        "defer_unused_numpy_submodules()\n"
        "import scipy.linalg, numpy\n"
        "assert 'numpy.f2py.f2py2e' not in sys.modules and 'numpy.testing._private.utils' not in sys.modules\n"
        "numpy.testing.assert_allclose(scipy.linalg.inv([[2.0]]), [[0.5]])\n"
        "from numpy.testing import assert_array_equal\n"
        "import numpy.f2py\n"
        "assert callable(numpy.f2py.run_main) and 'numpy.f2py.f2py2e' in sys.modules\n"
        "print('ok')\n"
    )
    proc = _run(["-c", code])
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr


@pytest.mark.parametrize("workers", [2])
def test_prestarted_pool_is_the_one_the_campaign_uses(workers):
    import test_campaign_toy as toy
    from proxops.analysis.campaign import run_campaign
    from proxops.exec import backends

    backends.shutdown_pools()
    backends.prestart_pool(workers, ("proxops.analysis.campaign_worker",))
    pool = backends._POOLS[workers]
    a = run_campaign(dict(toy.TOY_SCENARIO), n_runs=4, workers=workers, seed=2, progress=False)
    assert backends._POOLS[workers] is pool
    b = run_campaign(dict(toy.TOY_SCENARIO), n_runs=4, workers=1, seed=2, progress=False)
    da, db = a.deterministic_table(), b.deterministic_table()
    assert da.drop(columns=[c for c in da if c.startswith("metric.wall")]).equals(
        db.drop(columns=[c for c in db if c.startswith("metric.wall")]))
    backends.shutdown_pools()


def test_fork_server_warm_up_builds_the_scenario_once_and_ignores_bad_input():
    """Importing proxops.exec.worker_warmup with PROXOPS_WARM_SCENARIO set (what the fork server
    of ``proxops mc`` does) builds that scenario: the srf per-process caches hold one plan and one
    ephemeris afterwards, and the variable is gone (forked workers do not repeat it); a scenario that
    does not load or build is skipped without an exception (the workers' check reports it)."""
    code = (
        "import json, os\n"
        "os.environ['PROXOPS_WARM_SCENARIO'] = json.dumps({'scenario': 'srf-vbar-mc', 'overrides': ['sim.seed=3']})\n"
        "import proxops.exec.worker_warmup as w\n"
        "import proxops.systems.srf as srf\n"
        "assert 'PROXOPS_WARM_SCENARIO' not in os.environ\n"
        "assert len(srf._PLAN_CACHE) == 1 and len(srf._EPHEMERIS_CACHE) == 1\n"
        "assert w.warm_up('no-such-scenario') is False\n"
        "assert w.warm_up('srf-vbar', ['approach.end_m=5000']) is False\n"  # end beyond start: an input error
        "print('ok')\n"
    )
    proc = _run(["-c", code])
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr


# --------------------------------------------------------------------------- mc start-up and exit
def test_fork_server_registers_its_quick_exit_and_workers_inherit_only_the_pid():
    """The pool's fork server imports proxops.exec.forkserver_exit first: there it records its pid and
    registers the os._exit handler; a worker forked from it sees the server's pid (its parent's), not
    its own, so the handler's pid check keeps it inert in workers. Imported elsewhere it registers
    nothing."""
    from proxops.exec.backends import START_METHOD

    if START_METHOD != "forkserver":
        pytest.skip("no fork server on this platform")
    code = (
        "import os\n"
        "from proxops.exec import backends, forkserver_exit\n"
        "assert forkserver_exit.SERVER_PID is None\n"
        "pool = backends._new_pool(2)\n"
        "probe = \"__import__('proxops.exec.forkserver_exit', fromlist=['x']).SERVER_PID\"\n"
        "print(pool.submit(eval, probe).result(), pool.submit(os.getppid).result(), pool.submit(os.getpid).result())\n"
        "pool.shutdown()\n"
    )
    proc = _run(["-c", code])
    assert proc.returncode == 0, proc.stderr
    recorded, worker_parent, worker = (int(x) for x in proc.stdout.split())
    assert recorded == worker_parent != worker


@pytest.mark.parametrize("argv, expected", [
    (["mc", "srf-vbar-mc", "--runs", "50", "--workers", "2", "--out", "o"], ("srf-vbar-mc", 50, 2, [])),
    (["--debug", "mc", "-n", "3", "x.toml", "--set=sim.seed=4", "--set", "a.b=1", "--json"],
     ("x.toml", 3, None, ["sim.seed=4", "a.b=1"])),
    (["mc", "s", "--runs=1", "-w", "1", "--no-progress", "--resume"], ("s", 1, 1, [])),
    (["mc", "s", "--runs", "0"], None),           # invalid: mc reports it, nothing starts early
    (["mc", "s", "--workers", "two"], None),
    (["mc", "s", "--runs"], None),                # missing value
    (["mc", "s", "--seed", "-1"], None),
    (["mc", "s", "--seed", str(2**63)], None),
    (["mc", "s", "--connect-timeout-s", "nan"], None),
    (["mc", "s", "--connect-timeout-s", "0"], None),
    (["mc", "s", "--seed", "0", "--connect-timeout-s", "0.5"], ("s", None, None, [])),
    (["mc", "s", "--help"], None),
    (["mc", "s", "--scheduler", "tcp://h:1"], None),  # Dask: no local pool
    (["mc", "s", "--frobnicate"], None),          # unknown option
    (["mc", "s", "-n=5"], None),                  # click reads the value "=5": left to mc
    (["mc", "s", "t"], None),                     # two scenarios
    (["mc"], None),
    (["run", "mc"], None),                        # another command
    (["-q", "--debug", "mc", "s"], ("s", None, None, [])),  # proxops.cli.main's flags before the command
    (["--verbose", "mc", "s", "-n", "2"], ("s", 2, None, [])),
])
def test_early_prestart_reads_only_unambiguous_mc_command_lines(argv, expected):
    from proxops.exec.prestart import _read_mc_argv

    assert _read_mc_argv(argv) == expected


def test_early_prestart_finds_the_system_module_of_a_builtin_and_of_a_file(tmp_path):
    """The fork server imports the scenario's system module up front: read from the TOML without the
    loader (a built-in by name, a file by path; () when it cannot be told)."""
    from proxops.exec.prestart import system_module

    assert system_module("srf-vbar-mc") == ("proxops.systems.srf",)
    path = tmp_path / "s.toml"
    path.write_text('system = "station-keeping"\n')
    assert system_module(str(path)) == ("proxops.systems.station_keeping",)
    assert system_module("no-such-scenario") == ()


def _reach(duration_s=400.0):
    return ["sim.duration_s=" + repr(float(duration_s)), "mpc.config=monte-carlo", "mpc.constraint_mode=hard"]


@pytest.mark.parametrize("argv, expected", [
    # runs = omegas x a_max x n_x x n_y: the paper's 5 x 4 axes and 13 x 15 ICs by default (§9: 3900 runs)
    (["reach", "mc", "--out", "o"], ("los-tumble", 5 * 4 * 13 * 15, None, _reach())),
    (["-q", "reach", "mc", "--out=o", "--workers", "2", "--n-x", "3", "--n-y=2", "--omega-deg-s", "2",
      "--omega-deg", "3", "--amax", "0.1", "--duration-s", "50", "--no-progress", "--json"],
     ("los-tumble", 2 * 1 * 3 * 2, 2, _reach(50))),
    (["reach", "mc", "--out", "o", "--grid", "2"], None),        # below 3 points: reach mc's error, no pool
    (["reach", "mc", "--out", "o", "--n-x", "201"], None),       # above MAX_IC_AXIS
    (["reach", "mc", "--out", "o", "--duration-s", "inf"], None),
    (["reach", "mc", "--out", "o", "--amax", "-0.1"], None),
    (["reach", "mc", "--out", "o", "--workers", "0"], None),
    (["reach", "mc", "--out", "o", "--resume"], None),           # resuming starts no pool
    (["reach", "mc", "--out", "o", "--scheduler", "tcp://h:1"], None),
    (["reach", "mc", "--out", "o", "--help"], None),
    (["reach", "mc", "--out"], None),                             # missing value
    (["reach", "mc", "extra"], None),
    (["reach", "table"], None),
])
def test_early_prestart_reads_only_unambiguous_reach_mc_command_lines(argv, expected):
    """`proxops reach mc` starts its pool before the CLI and cli_reach's imports (numba, scipy,
    matplotlib) too, sized like the command sizes it; anything in doubt is left to the command."""
    from proxops.exec.prestart import _read_reach_mc_argv, _without_global_options

    assert _read_reach_mc_argv(_without_global_options(argv)) == expected


def test_mc_bad_scenario_after_early_prestart_is_one_error_line_exit_2(tmp_path):
    """proxops.exec.entry starts the pool (and the fork server's warm-up of the scenario) before parsing;
    a scenario that does not exist still ends with one ``error:`` line naming it, exit code 2, and
    no folder written."""
    proc = _run(["-m", "proxops.exec.entry", "mc", "no-such-scenario", "--runs", "4", "--workers", "2",
                 "--out", str(tmp_path / "o"), "--no-progress"])
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith("error:") and "no-such-scenario" in lines[0], proc.stderr
    assert not (tmp_path / "o").exists()
