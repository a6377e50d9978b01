"""Closed loops at the solver's speed (issue 18): per system, the wall time of one run, the solver's
share of it and the glue per step, the 50-run srf campaigns, the analytic certification
(``reach table``) and the CLI start-up -- for this tree AND the previous release (commit
``BASELINE_COMMIT``), measured back to back in the same invocation.

    python benchmarks/bench_closed_loop.py                 # this tree vs the baseline tree
    python benchmarks/bench_closed_loop.py --no-baseline   # this tree, vs the stored baseline.json
    python benchmarks/bench_closed_loop.py --reach-mc      # also the 3 900-run ``reach mc`` (minutes)
    python benchmarks/bench_closed_loop.py --store         # measure the baseline tree, write baseline.json
    python benchmarks/bench_closed_loop.py --parts=campaigns --no-baseline   # one part, vs the stored numbers

The baseline tree is ``git archive BASELINE_COMMIT`` unpacked once into a cache folder (needs the
git history); without it the numbers stored in benchmarks/baseline.json (same commit, measured
on this 2-core machine, with their load average) are the reference, and the output says so.

What is measured (each in a fresh interpreter per tree, one BLAS thread, after a warm-up run so
imports and numba caches are loaded; best of ``--repeats``):

* ``run s``: ``execute(load_scenario(name))`` -- build, simulate, summarise (what ``proxops run``
  does, without printing);
* ``sim s``: the engine's wall time (``meta["wall_time_s"]``), ``solve s`` the sum of the
  controller's ``solve_time_s`` (QP data update + solve, as each controller reports it);
  ``solver share`` = solve / sim; ``glue us/step`` = (sim - solve) / steps: everything in the loop
  that is not the solver (engine, navigation, actuator, constraints, truth, controller glue);
* campaigns: ``run_campaign(name, n_runs=50, workers=2)``; the first in a process includes the
  pool's cold start (spawn, imports), the second reuses the pool;
* ``reach table``: the 20-combination analytic certification without the backward LP
  (``reach_table(backward=False)``, the ``total`` of its Table 4 timings, 300 x 300 grid), and as
  ``proxops reproduce`` runs it (``reach_table(n_points=300)``, backward LP kernel included: the
  wall time of the "All analytical sets for the 20 combinations" row, goal < 0.5 s);
  Its support LPs (``ConvexSection.polygon``, 1 234 per certification) run on DAQP's LP mode; the
  row also prints one support LP's cost per solver. Measured for issue 18 (2-core machine, best of
  3, the 20-combination masks and percentages identical to cold HiGHS in every variant):
  hand-written warm simplex (removed) 0.29-0.55 s, DAQP LP mode 0.23-0.51 s (7 pairs of fresh
  processes alternated, load 3.9-4.6; DAQP faster in 6 of 7; time in ``polygon`` 0.13-0.19 s
  against 0.06-0.13 s); HiGHS alone, hot-started, presolve off: dual simplex 0.55-0.59 s, primal simplex
  (``simplex_strategy`` 4) 0.52-0.55 s, primal with 24 instead of 48 first directions 0.47-0.49 s
  (load 2.6-3.0; 16 directions: 1.04-1.27 s, the coarser polygon leaves more grid points to
  per-point LPs); a fresh HiGHS model per LP 2.6-2.9 s. One support LP: DAQP 0.02 ms, HiGHS hot
  0.15-0.32 ms (its fixed cost per ``run()``: 0.16 ms with nothing changed; no option tried
  lowered it). Large sections stay on HiGHS (``ConvexSection.SUPPORT_DAQP_MAX_VARIABLES``): for
  ``viable_points`` (400 steps, 802 variables x 802 rows, 30 random starts) DAQP took up to 4.6 s
  per direction; HiGHS alone 1.4 s / 4.5 s (1 deg/s, 0.1 m/s^2 / 3 deg/s, 0.05 m/s^2) against the
  warm simplex's 4.8 s / 10.9 s (load 4.0-4.4).
* ``reach mc`` (``--reach-mc``): the 3 900-run §9 campaign on 2 workers, its wall time and the sum
  of the runs' CPU times (halved: what two free cores would need for the runs), and the CPU used
  meanwhile by this process, by the pool workers and by every other process of the machine
  (/proc/stat): on the shared 2-core machine the wall time is mostly decided by the last; and the
  whole command ``proxops reach mc --workers 2 --json`` from a fresh process (the issue's < 30 s
  goal is about this): wall time to exit, its campaign's share and the rest (start-up, maps,
  certification check, figures);
* CLI: ``python -m proxops.exec.entry --version``, ``... run station-keeping --json`` and ``... run srf-vbar
  --json`` wall time (process start to exit), best of ``--repeats`` after one cached use; with the
  campaigns, ``proxops mc NAME --runs 50 --workers 2`` of each srf campaign from a fresh process
  (what the < 5 s goal is about), one repeat each.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
BASELINE_COMMIT = "99b4039"
BASELINE_JSON = HERE / "baseline.json"
RUNS = ("srf-vbar", "srf-rbar", "srf-glideslope-40", "los-tumble", "station-keeping", "underactuated-case1",
        "cortex-nominal")
CAMPAIGNS = ("srf-vbar-mc", "srf-rbar-mc", "srf-glideslope-40-mc")
ENV = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")


# --------------------------------------------------------------------------- inside one tree
def _measure_runs(repeats: int) -> dict:
    import numpy as np

    from proxops.analysis.runs import execute
    from proxops.scenarios.loader import load_scenario

    out = {}
    for name in RUNS:
        loaded = load_scenario(name)
        execute(loaded)  # warm-up: imports, numba caches, solver libraries
        best = None
        for _ in range(repeats):
            loaded = load_scenario(name)
            t0, c0 = time.perf_counter(), time.process_time()
            _, results = execute(loaded)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            sim = sum(float(r.meta.get("wall_time_s", 0.0)) for r in results.values())
            # solver = QP data update + solve: srf and cortex time both in solve_time_s; los reports
            # its update (condensing offset + DAQP update) as info mpc_build_ms
            solve = sum(float(np.sum(r.solve_time_s)) + float(np.nansum(r.info.get("mpc_build_ms", 0.0))) * 1e-3
                        for r in results.values())
            steps = sum(len(r.t) - 1 for r in results.values())
            decisions = sum(int(np.count_nonzero(r.solve_time_s > 0)) for r in results.values())
            row = {"run_s": wall, "run_cpu_s": cpu, "sim_s": sim, "solve_s": solve, "steps": steps,
                   "decisions": decisions}
            if best is None or wall < best["run_s"]:
                best = row
        out[name] = best
    return out


def _measure_campaigns() -> dict:
    from proxops.analysis.campaign import run_campaign, shutdown_pools

    out = {}
    for i, name in enumerate(CAMPAIGNS):
        t0 = time.perf_counter()
        res = run_campaign(name, n_runs=50, workers=2, progress=False, seed=1)
        wall = time.perf_counter() - t0
        out[name] = {"wall_s": wall, "cold_pool": i == 0, "successes": int(res.table["success"].sum())
                     if "success" in res.table else None}
    shutdown_pools()
    return out


def _measure_qp(repeats: int) -> dict:
    """The real QPs inside closed loops, per decision: QP data update + solve (the headline) and
    the solve alone. los: the eq.-(11) QP of los-tumble (N = 40, DAQP); srf: problem (29) of
    srf-vbar (PIQP, update and solve both timed in solve_time_s)."""
    import numpy as np

    from proxops.analysis.runs import execute
    from proxops.scenarios.loader import load_scenario

    out = {}
    execute(load_scenario("los-tumble"))
    best = None
    for _ in range(repeats):
        res = next(iter(execute(load_scenario("los-tumble"))[1].values()))
        solve = res.solve_time_s[1:][res.solve_time_s[1:] > 0] * 1e3  # the first solve is the cold start
        upd = res.info["mpc_build_ms"][1:][res.solve_time_s[1:] > 0]
        row = {"update_plus_solve_ms": float(np.median(solve + upd)), "solve_ms": float(np.median(solve)),
               "update_ms": float(np.median(upd))}
        if best is None or row["update_plus_solve_ms"] < best["update_plus_solve_ms"]:
            best = row
    out["los"] = best
    res = next(iter(execute(load_scenario("srf-vbar"))[1].values()))
    st = res.solve_time_s[res.solve_time_s > 0] * 1e3
    out["srf"] = {"update_plus_solve_ms": float(np.median(st))}
    return out


def _measure_reach_table(repeats: int) -> dict:
    """The 20-combination certification: without the backward LP (``total_s``, the sum of Table 4's
    timings) and as ``proxops reproduce`` runs it, backward LP kernel included (``reproduce_s``:
    wall time of ``reach_table(n_points=300)``, the "All analytical sets" row)."""
    from proxops.analysis import reach as R

    R.reach_table(n_points=60)  # warm-up (numba kernels, HiGHS)
    best = min(R.reach_table(backward=False)[1]["total"] for _ in range(repeats))
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        R.reach_table(n_points=300)
        walls.append(time.perf_counter() - t0)
    return {"total_s": best, "reproduce_s": min(walls), "support_lp": _measure_support_lps(repeats)}


def _measure_support_lps(repeats: int) -> dict:
    """One support LP of the backward section (1 deg/s, 0.1 m/s^2, 300-point grid box; 63 rows, 42
    variables), re-solved for 48 directions with only the cost changed: ms per LP for DAQP's LP mode
    (what ConvexSection uses) and for HiGHS hot-started with presolve off (dual simplex, HiGHS's
    default, and primal simplex, ``simplex_strategy`` 4), and the largest support-value difference
    DAQP - HiGHS (m)."""
    import math

    import numpy as np

    from proxops.analysis import reach as R
    from proxops.geometry.polytope import ConvexSection
    from proxops.solvers import DaqpQP, HighsLP

    corridor = R.LosCorridor()
    grid = R.body_grid(corridor, 300, R.DEFAULT_GRID_Y_MAX_M)
    sec = R.backward_section(corridor, np.radians(1.0), 0.1, ((grid.x_m[0], grid.y_m[0]), (grid.x_m[-1], grid.y_m[-1])))
    A, b, lb, ub = sec.A, sec.b, sec.lb, sec.ub
    m, n = A.shape
    costs = []
    for ang in np.linspace(0.0, 2 * np.pi, 48, endpoint=False):
        c = np.zeros(n)
        c[:2] = -math.cos(ang), -math.sin(ang)
        costs.append(c)
    hot = {"presolve": "off", "solver": "simplex"}
    solvers = {"daqp": lambda: DaqpQP(settings={"eps_prox": getattr(ConvexSection, "SUPPORT_EPS_PROX", 1e-2)}),
               "highs_dual": lambda: HighsLP(settings=hot),
               "highs_primal": lambda: HighsLP(settings={**hot, "simplex_strategy": 4})}
    out, support = {}, {}
    for name, make in solvers.items():
        s = make()
        if name == "daqp":
            s.setup_native(np.zeros((n, n)), np.zeros(n), A, np.full(m, -np.inf), b, lb, ub)
        else:
            s.setup_native(np.zeros(n), A, None, b, lb, ub)
        best = math.inf
        for _ in range(max(repeats, 3)):
            vals = []
            t0 = time.perf_counter()
            for c in costs:
                s.update(f=c) if name == "daqp" else s.update(c=c)
                vals.append(-s.solve().objective)
            best = min(best, time.perf_counter() - t0)
        out[f"{name}_ms"] = best / len(costs) * 1e3
        support[name] = np.array(vals)
    out["max_support_diff_m"] = float(max(np.abs(support["daqp"] - support[k]).max() for k in ("highs_dual", "highs_primal")))
    return out


def _machine_cpu_s() -> float | None:
    """CPU-seconds the whole machine (every tenant, not only this process tree) has been busy
    since boot, from /proc/stat (None where it does not exist)."""
    try:
        fields = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    except (OSError, ValueError):
        return None
    return (sum(fields) - fields[3] - fields[4]) / os.sysconf("SC_CLK_TCK")  # all but idle and iowait


def _measure_reach_mc() -> dict:
    """The 3 900-run §9 campaign on 2 workers (what ``proxops reach mc --workers 2`` runs): wall time,
    and the sum of the runs' CPU times (``cpu_s``; cpu_s / 2 is the wall time two free cores would
    need for the runs alone, a figure less sensitive to the machine's load). Where the wall time
    goes: this process's CPU (``parent_cpu_s``: dispatch, result collection, Parquet, progress),
    the pool workers' CPU (``workers_cpu_s``, start-up included; the pool is shut down to read it)
    and what every other process of the machine used meanwhile (``others_cpu_s``: the machine's
    busy CPU-seconds from /proc/stat minus this tree's)."""
    import resource
    import tempfile

    from proxops.analysis import feasibility_maps as F
    from proxops.analysis.campaign import run_campaign, shutdown_pools

    shutdown_pools()  # a pool of an earlier part would hide its CPU from RUSAGE_CHILDREN
    usage = lambda who: (lambda r: r.ru_utime + r.ru_stime)(resource.getrusage(who))  # noqa: E731
    with tempfile.TemporaryDirectory() as d:
        self0, child0, machine0 = usage(resource.RUSAGE_SELF), usage(resource.RUSAGE_CHILDREN), _machine_cpu_s()
        t0 = time.perf_counter()
        res = run_campaign(F.mc_scenario(), workers=2, out=Path(d) / "mc", progress=False)
        wall = time.perf_counter() - t0
        machine1 = _machine_cpu_s()
        self1 = usage(resource.RUSAGE_SELF)
        shutdown_pools()
        workers = usage(resource.RUSAGE_CHILDREN) - child0
        cpu = float(res.table["run_cpu_s"].sum()) if "run_cpu_s" in res.table else float("nan")
        out = {"wall_s": wall, "runs": int(len(res.table)), "cpu_s": cpu,
               "feasible": int(F.outcome_table(res.table)["feasible"].sum()),
               "parent_cpu_s": self1 - self0, "workers_cpu_s": workers}
        if machine0 is not None and machine1 is not None:
            out["others_cpu_s"] = max(0.0, machine1 - machine0 - (self1 - self0) - workers)
        return out


def worker(args: list[str]) -> None:
    repeats = int(args[0])
    parts = set(args[1:])
    out = {"load_before": os.getloadavg()[0]}
    if "runs" in parts:
        out["runs"] = _measure_runs(repeats)
    if "reach_table" in parts:
        out["reach_table"] = _measure_reach_table(repeats)
    if "qp" in parts:
        out["qp"] = _measure_qp(repeats)
    if "campaigns" in parts:
        out["campaigns"] = _measure_campaigns()
    if "reach_mc" in parts:
        out["reach_mc"] = _measure_reach_mc()
    out["load_after"] = os.getloadavg()[0]
    print("RESULT " + json.dumps(out))


# --------------------------------------------------------------------------- driver
def baseline_tree() -> Path | None:
    """The baseline commit's tree unpacked in a cache folder (None without the git history)."""
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "proxops-bench" / BASELINE_COMMIT
    if (cache / "src" / "proxops").is_dir():
        return cache
    try:
        blob = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", BASELINE_COMMIT],
                              capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    cache.mkdir(parents=True, exist_ok=True)
    import io

    with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
        tar.extractall(cache, filter="data")
    return cache


def measure_tree(src: Path, repeats: int, parts: list[str]) -> dict:
    env = dict(ENV, PYTHONPATH=str(src))
    proc = subprocess.run([sys.executable, __file__, "--worker", str(repeats), *parts], env=env,
                          capture_output=True, text=True)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")), None)
    if line is None:
        raise RuntimeError(f"measuring {src} failed:\n{proc.stderr[-3000:]}")
    return json.loads(line[len("RESULT "):])


CLI_RUNS = (("version", ["--version"]), ("run_station_keeping", ["run", "station-keeping", "--json"]),
            ("run_srf_vbar", ["run", "srf-vbar", "--json"]))
CLI_GOALS = {"version": 0.3, "run_station_keeping": 1.0}


def cli_times(src: Path, repeats: int) -> dict:
    env = dict(ENV, PYTHONPATH=str(src))
    out = {}
    for label, args in CLI_RUNS:
        cmd = [sys.executable, "-m", "proxops.exec.entry", *args]
        subprocess.run(cmd, env=env, capture_output=True, check=True)  # the first (cached) use
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            subprocess.run(cmd, env=env, capture_output=True, check=True)
            best = min(best, time.perf_counter() - t0)
        out[label] = best
    return out


def cli_campaign_times(src: Path) -> dict:
    """``proxops mc NAME --runs 50 --workers 2`` as a user runs it (a fresh process: imports, pool
    start, checks, runs, Parquet rows, statistics, exit), wall time of each 50-run srf campaign,
    after one 2-run campaign has filled the numba cache. One repeat each (5-10 s)."""
    import shutil
    import tempfile

    env = dict(ENV, PYTHONPATH=str(src))
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, name in enumerate(CAMPAIGNS):
            runs = ["2"] if i == 0 else []
            for n in runs + ["50"]:
                folder = Path(tmp) / f"{name}-{n}"
                cmd = [sys.executable, "-m", "proxops.exec.entry", "mc", name, "--runs", n, "--workers", "2",
                       "--seed", "1", "--out", str(folder), "--progress", "--json"]
                phases, stdout = mc_phases(cmd, env)
                shutil.rmtree(folder, ignore_errors=True)
            out[name] = {**phases, "succeeded": json.loads(stdout).get("succeeded")}
    out["load_after"] = os.getloadavg()[0]
    return out


def mc_phases(cmd: list[str], env: dict) -> tuple[dict, str]:
    """Run a ``proxops mc ... --progress`` command and time its phases from its stderr (the progress
    bar): ``start_s`` launch to the bar's first output (imports, pool start, checks, manifest; the
    bar appears just before the first run is sent), ``runs_s`` to its last output (the bar closed
    after the last run), ``tail_s`` from there until the process has exited AND its stderr is closed
    by every process holding it (Parquet compaction, statistics, printing, pool and fork server
    exit: what ``proxops mc ... 2>&1 | tee`` waits for). ``wall_s`` is the sum."""
    import threading

    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    chunks: list[bytes] = []
    reader = threading.Thread(target=lambda: chunks.append(proc.stdout.read()), daemon=True)
    reader.start()
    first = last = None
    errors = b""
    while True:
        chunk = proc.stderr.read1(4096)
        if not chunk:
            break
        last = time.perf_counter() - t0
        first = last if first is None else first
        errors += chunk
    proc.wait()
    reader.join()
    end = time.perf_counter() - t0
    if proc.returncode != 0 or first is None:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{errors.decode(errors='replace')[-2000:]}")
    return {"wall_s": end, "start_s": first, "runs_s": last - first, "tail_s": end - last}, chunks[0].decode()


def cli_reach_mc_time(src: Path) -> dict | None:
    """The whole ``proxops reach mc --workers 2 --out DIR --json`` from a fresh process (imports, pool
    start, the 3 900-run campaign, 20 maps, certification check, Figs. 2-3, JSON), wall time from
    process start until it has exited and its output pipes are closed (what a reader of its output
    waits for), after one 4-run use has filled the numba cache; ``campaign_s`` is the campaign's own
    wall time from the JSON and ``outside_campaign_s`` the rest. One repeat (~30 s). None when the
    tree's command fails (an old tree without it)."""
    import tempfile

    env = dict(ENV, PYTHONPATH=str(src))
    base = [sys.executable, "-m", "proxops.exec.entry", "reach", "mc", "--workers", "2", "--no-progress", "--json"]
    with tempfile.TemporaryDirectory() as tmp:
        warm = base + ["--out", str(Path(tmp) / "warm"), "--n-x", "2", "--n-y", "2", "--omega-deg", "1", "--amax", "0.2"]
        if subprocess.run(warm, env=env, capture_output=True).returncode != 0:
            return None
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        proc = subprocess.run(base + ["--out", str(Path(tmp) / "mc")], env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return None
    summary = json.loads(proc.stdout)
    return {"wall_s": wall, "campaign_s": summary["wall_time_s"], "outside_campaign_s": wall - summary["wall_time_s"],
            "runs": summary["runs"], "feasible": summary["feasible"], "load_before": load,
            "load_after": os.getloadavg()[0]}


def cold_compile(src: Path) -> dict:
    """First ``station-keeping`` and ``srf-vbar`` runs in a fresh interpreter with an EMPTY numba
    cache (every kernel compiled) against a fresh interpreter with the cache filled: the one-off
    compile time, printed apart from every other figure."""
    import tempfile

    code = ("import time; t0 = time.perf_counter(); from proxops.analysis.runs import execute; "
            "from proxops.scenarios.loader import load_scenario; t1 = time.perf_counter(); "
            "[execute(load_scenario(n)) for n in ('station-keeping', 'srf-vbar')]; "
            "print('RESULT', t1 - t0, time.perf_counter() - t1)")
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(ENV, PYTHONPATH=str(src), NUMBA_CACHE_DIR=cache)
        for label in ("cold", "cached"):
            proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
            line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT")), None)
            if line is None:
                raise RuntimeError(proc.stderr[-2000:])
            imports, runs = map(float, line.split()[1:])
            out[label] = {"imports_s": imports, "first_runs_s": runs}
    return out


def _ratio(old, new) -> str:
    return f"{old / new:5.2f}x" if old and new else "   - "


def report(new: dict, old: dict, old_label: str) -> None:
    print(f"baseline: {old_label}")
    print(f"\nclosed loop per system (best of repeats; solver share = solve / sim; glue = (sim - solve) / steps)")
    print(f"{'scenario':<20} {'steps':>6} {'decide':>6} {'run s':>7} {'(base)':>7} {'speed-up':>8} {'cpu x':>6} "
          f"{'sim s':>7} {'solver %':>8} {'(base)':>6} {'glue us/step':>12} {'(base)':>7}")
    for name, n in new.get("runs", {}).items():
        o = old.get("runs", {}).get(name, {})
        share = 100 * n["solve_s"] / n["sim_s"] if n["sim_s"] else 0.0
        glue = (n["sim_s"] - n["solve_s"]) / max(n["steps"], 1) * 1e6
        o_share = 100 * o["solve_s"] / o["sim_s"] if o.get("sim_s") else float("nan")
        o_glue = (o["sim_s"] - o["solve_s"]) / max(o["steps"], 1) * 1e6 if o else float("nan")
        print(f"{name:<20} {n['steps']:>6d} {n.get('decisions', 0):>6d} {n['run_s']:7.3f} "
              f"{o.get('run_s', float('nan')):7.3f} {_ratio(o.get('run_s'), n['run_s']):>8} "
              f"{_ratio(o.get('run_cpu_s'), n.get('run_cpu_s')):>6} {n['sim_s']:7.3f} {share:8.1f} {o_share:6.1f} "
              f"{glue:12.1f} {o_glue:7.1f}")
    print("(decide: steps where the controller solved; cpu x: ratio of the run's CPU time, less sensitive "
          "to the machine's load than the wall time)")
    if "qp" in new:
        q, oq = new["qp"], old.get("qp", {})
        lo, olo = q["los"], oq.get("los", {})
        print(f"\nheadline, the real QPs in closed loops (median per decision): los eq. (11), N = 40, DAQP: "
              f"update + solve {lo['update_plus_solve_ms']:.3f} ms (update {lo['update_ms']:.3f}, solve "
              f"{lo['solve_ms']:.3f}; base {olo.get('update_plus_solve_ms', float('nan')):.3f} ms); "
              f"srf-vbar problem (29), PIQP: update + solve {q['srf']['update_plus_solve_ms']:.3f} ms "
              f"(base {oq.get('srf', {}).get('update_plus_solve_ms', float('nan')):.3f} ms)")
    if "cold" in new:
        c = new["cold"]
        print(f"cold start with an empty numba cache (compiles every kernel): imports {c['cold']['imports_s']:.2f} s, "
              f"first station-keeping + srf-vbar runs {c['cold']['first_runs_s']:.2f} s; with the cache: imports "
              f"{c['cached']['imports_s']:.2f} s, runs {c['cached']['first_runs_s']:.2f} s "
              f"(compile time ~ {c['cold']['first_runs_s'] - c['cached']['first_runs_s']:.2f} s, once per machine)")
    if "campaigns" in new:
        print("\n50-run srf campaigns, 2 workers (the first includes the pool's cold start)")
        for name, n in new["campaigns"].items():
            o = old.get("campaigns", {}).get(name, {})
            print(f"  {name:<22} {n['wall_s']:6.2f} s (base {o.get('wall_s', float('nan')):6.2f} s) "
                  f"{_ratio(o.get('wall_s'), n['wall_s'])}  goal < 5 s" + ("  [cold pool]" if n["cold_pool"] else ""))
    if "reach_table" in new:
        n, o = new["reach_table"]["total_s"], old.get("reach_table", {}).get("total_s")
        print(f"\nreach table (20 combinations, 300x300, no backward LP): {n:.3f} s (base {o or float('nan'):.3f} s) "
              f"{_ratio(o, n)}")
        n, o = new["reach_table"].get("reproduce_s"), old.get("reach_table", {}).get("reproduce_s")
        if n is not None:
            print(f"reach table as in proxops reproduce (backward LP included): {n:.3f} s "
                  f"(base {o or float('nan'):.3f} s) {_ratio(o, n)}  goal < 0.5 s")
        lp = new["reach_table"].get("support_lp")
        if lp:
            print(f"  one support LP (63 x 42, cost change only): DAQP LP mode {lp['daqp_ms']:.3f} ms, HiGHS hot "
                  f"dual {lp['highs_dual_ms']:.3f} ms, primal {lp['highs_primal_ms']:.3f} ms; "
                  f"max support difference {lp['max_support_diff_m']:.1e} m")
    if "reach_mc" in new:
        n, o = new["reach_mc"], old.get("reach_mc", {})
        print(f"reach mc ({n['runs']} runs, 2 workers): {n['wall_s']:.1f} s (base {o.get('wall_s', float('nan')):.1f} s)"
              f"  goal < 30 s; runs' CPU {n.get('cpu_s', float('nan')):.1f} s (/ 2 = "
              f"{n.get('cpu_s', float('nan')) / 2:.1f} s on two free cores), {n.get('feasible', '-')} feasible")
        if "workers_cpu_s" in n:
            others = n.get("others_cpu_s")
            print(f"  CPU during it: this process {n['parent_cpu_s']:.1f} s, pool workers {n['workers_cpu_s']:.1f} s "
                  f"(start-up included), other processes of the machine "
                  f"{'n/a' if others is None else f'{others:.1f} s'} (2 cores x {n['wall_s']:.1f} s = "
                  f"{2 * n['wall_s']:.1f} CPU-s available)")
    if new.get("reach_mc_cli"):
        n, o = new["reach_mc_cli"], old.get("reach_mc_cli") or {}
        print(f"`proxops reach mc --workers 2 --json`, whole command (process start to exit): {n['wall_s']:.1f} s "
              f"(base {o.get('wall_s', float('nan')):.1f} s)  goal < 30 s; its campaign {n['campaign_s']:.1f} s "
              f"(base {o.get('campaign_s', float('nan')):.1f} s), outside the campaign {n['outside_campaign_s']:.1f} s "
              f"(base {o.get('outside_campaign_s', float('nan')):.1f} s); load {n['load_before']:.2f} -> "
              f"{n['load_after']:.2f}")
    if "cli" in new:
        for key, _ in CLI_RUNS:
            n, o = new["cli"].get(key), old.get("cli", {}).get(key)
            if n is None:
                continue
            goal = f"  goal < {CLI_GOALS[key]} s" if key in CLI_GOALS else ""
            print(f"CLI {key:<22} {n:6.3f} s (base {o or float('nan'):6.3f} s) {_ratio(o, n)}{goal}")
    if "cli_mc" in new:
        print("`proxops mc NAME --runs 50 --workers 2` from a fresh process (wall, process start to exit)")
        for name in CAMPAIGNS:
            n, o = new["cli_mc"][name], old.get("cli_mc", {}).get(name, {})
            print(f"  {name:<22} {n['wall_s']:6.2f} s (base {o.get('wall_s', float('nan')):6.2f} s) "
                  f"{_ratio(o.get('wall_s'), n['wall_s'])}  goal < 5 s  ({n['succeeded']}/50 succeeded)")
            if "start_s" in n:
                nan = float("nan")
                print(f"    start-up {n['start_s']:.2f} s (base {o.get('start_s', nan):.2f}), runs {n['runs_s']:.2f} s "
                      f"(base {o.get('runs_s', nan):.2f}), tail {n['tail_s']:.2f} s (base {o.get('tail_s', nan):.2f})")
    print(f"\nload average: {new.get('load_before', float('nan')):.2f} -> {new.get('load_after', float('nan')):.2f} "
          f"(this tree), {old.get('load_before', float('nan')):.2f} -> {old.get('load_after', float('nan')):.2f} (baseline)")


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    repeats = 3
    for a in argv:
        if a.startswith("--repeats="):
            repeats = int(a.split("=", 1)[1])
    parts = ["runs", "qp", "reach_table"] + (["campaigns"] if "--quick" not in argv else [])
    if "--reach-mc" in argv:
        parts.append("reach_mc")
    for a in argv:
        if a.startswith("--parts="):  # e.g. --parts=campaigns,reach_mc
            parts = a.split("=", 1)[1].split(",")
    print(f"load average {os.getloadavg()[0]:.2f} on {len(os.sched_getaffinity(0))} usable cpus")
    base_src = None if "--no-baseline" in argv else baseline_tree()
    if "--store" in argv:
        if base_src is None:
            raise SystemExit("--store needs the git history (commit %s)" % BASELINE_COMMIT)
        old = measure_tree(base_src / "src", repeats, parts)
        old["cli"] = cli_times(base_src / "src", repeats)
        if "campaigns" in parts:
            old["cli_mc"] = cli_campaign_times(base_src / "src")
        if "reach_mc" in parts:
            old["reach_mc_cli"] = cli_reach_mc_time(base_src / "src")
        old.update(commit=BASELINE_COMMIT, machine=f"{len(os.sched_getaffinity(0))} cpus",
                   measured=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                   command="python benchmarks/bench_closed_loop.py --store" + (" --reach-mc" if "reach_mc" in parts else ""))
        BASELINE_JSON.write_text(json.dumps(old, indent=1) + "\n")
        print(f"wrote {BASELINE_JSON}")
        return
    if base_src is not None:  # interleave: baseline, this tree (the machine's load drifts)
        old = measure_tree(base_src / "src", repeats, parts)
        if "runs" in parts:
            old["cli"] = cli_times(base_src / "src", repeats)
        if "campaigns" in parts:
            old["cli_mc"] = cli_campaign_times(base_src / "src")
        if "reach_mc" in parts:
            old["reach_mc_cli"] = cli_reach_mc_time(base_src / "src")
        old_label = f"commit {BASELINE_COMMIT} measured now, back to back ({base_src})"
    else:
        old = json.loads(BASELINE_JSON.read_text()) if BASELINE_JSON.exists() else {}
        old_label = (f"STORED numbers of commit {old.get('commit')} ({old.get('measured')}, load "
                     f"{old.get('load_before', float('nan')):.2f} -> {old.get('load_after', float('nan')):.2f}) from "
                     f"{BASELINE_JSON.name}; {old.get('note', '')}" if old else "none")
    new = measure_tree(ROOT / "src", repeats, parts)
    if "runs" in parts:
        new["cli"] = cli_times(ROOT / "src", repeats)
    if "campaigns" in parts:
        new["cli_mc"] = cli_campaign_times(ROOT / "src")
    if "reach_mc" in parts:
        new["reach_mc_cli"] = cli_reach_mc_time(ROOT / "src")
    if "--quick" not in argv and "runs" in parts:
        new["cold"] = cold_compile(ROOT / "src")
    report(new, old, old_label)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(sys.argv[2:])
    else:
        main()
