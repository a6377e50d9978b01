"""Campaign throughput: serial, 2 local worker processes, Dask LocalCluster with 2 workers.

Prints runs per minute, parallel efficiency T_serial / (2 T_parallel) (goal >= 85 %) on warm
workers (and counting the one-off pool start-up), and the Dask overhead per run (goal < 5 ms): measured directly on
no-op items and as extra worker-seconds per run in the campaign.

    .venv/bin/python benchmarks/bench_campaign.py [N_RUNS]

The scenario is the built-in station-keeping-mc (J2 truth, dispersions, error-level grid).
Efficiency needs an otherwise idle 2-core machine: the load average is printed with the result.
Every backend runs with one BLAS thread per process (the script re-executes itself so), as the
pool and Dask workers do; threaded BLAS on 2 processes x 2 cores made runs 2.5x slower.
"""

from __future__ import annotations

import os
import sys
import time

SCENARIO = "station-keeping-mc"
OVERRIDES = ["sim.duration_s=2000"]


def timed_campaign(n_runs: int, **kw) -> tuple[float, object]:
    from proxops.analysis.campaign import run_campaign

    t0 = time.perf_counter()
    res = run_campaign(SCENARIO, n_runs=n_runs, seed=1, overrides=OVERRIDES, progress=False, **kw)
    return time.perf_counter() - t0, res


def main(n_runs: int = 120) -> None:
    if os.environ.get("OPENBLAS_NUM_THREADS") != "1":
        # measure every backend with one BLAS thread per process (as the pool and Dask workers
        # run): re-run this script in a fresh interpreter where that holds from the start
        import subprocess

        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
        subprocess.run([sys.executable, __file__, str(n_runs)], env=env, check=True)
        return
    import pandas as pd
    from distributed import Client, LocalCluster

    from proxops.analysis.campaign import map_runs

    print(f"cpus usable: {len(os.sched_getaffinity(0))}, load average before: {os.getloadavg()[0]:.2f}")
    timed_campaign(2, workers=1)  # warm caches (imports, numba) in this process

    t_serial, serial = timed_campaign(n_runs, workers=1)
    t0 = time.perf_counter()
    timed_campaign(4, workers=2)  # cold start: spawn 2 workers, imports, JIT caches (the pool is then reused)
    t_pool_start = time.perf_counter() - t0 - 4 * t_serial / n_runs / 2
    t_pool, pool = timed_campaign(n_runs, workers=2)

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster, set_as_default=False) as client:
        timed_campaign(4, scheduler=client)  # warm the workers (imports, first build)
        t_dask, dask = timed_campaign(n_runs, scheduler=client)
        n_noop = 4000
        t0 = time.perf_counter()
        map_runs(abs, range(n_noop), scheduler=client)
        dask_noop_ms = (time.perf_counter() - t0) / n_noop * 1e3
    t0 = time.perf_counter()
    map_runs(abs, range(n_noop), workers=2)
    pool_noop_ms = (time.perf_counter() - t0) / n_noop * 1e3

    same = all(
        a.deterministic_table().equals(b.deterministic_table()) for a, b in ((serial, pool), (serial, dask))
    )
    per_run_s = t_serial / n_runs
    eff_pool = t_serial / (2 * t_pool)
    eff_pool_cold = t_serial / (2 * (t_pool + t_pool_start))
    eff_dask = t_serial / (2 * t_dask)
    dask_extra_ms = (2 * t_dask - t_serial) / n_runs * 1e3
    rows = [
        ("serial (1 process)", t_serial, 1.0, None),
        ("local pool, 2 workers", t_pool, eff_pool, None),
        ("Dask LocalCluster, 2 workers", t_dask, eff_dask, None),
    ]
    print(f"\n{n_runs} runs of {SCENARIO} ({' '.join(OVERRIDES)}), {per_run_s * 1e3:.1f} ms per run serial")
    print(pd.DataFrame(
        [(name, f"{t:.2f}", f"{n_runs / t * 60:.0f}", f"{e * 100:.0f} %") for name, t, e, _ in rows],
        columns=["backend", "wall s", "runs/min", "parallel efficiency"]).to_string(index=False))
    print(f"\nlocal pool, warm (kept between campaigns of one process): {eff_pool * 100:.0f} % efficiency "
          "(goal >= 85 %)")
    print(f"cold start of the pool (spawn 2 workers, imports, JIT caches): {t_pool_start:.2f} s once per process; "
          f"counting it, this campaign's efficiency is {eff_pool_cold * 100:.0f} %")
    print(f"local pool overhead on no-op items: {pool_noop_ms:.3f} ms per item")
    print(f"Dask overhead on no-op items: {dask_noop_ms:.3f} ms per item (goal < 5 ms)")
    print(f"Dask extra worker time in the campaign: {dask_extra_ms:.1f} ms per run "
          "(includes load imbalance and the machine's other load)")
    print("\ncontention-independent view (the machine is shared; wall-clock ratios above include other load):")
    for name, res, t in (("pool", pool, t_pool), ("Dask", dask, t_dask)):
        util = res.table["run_wall_s"].sum() / (2 * t)  # share of worker time spent inside runs
        cpu_ratio = serial.table["run_cpu_s"].mean() / res.table["run_cpu_s"].mean()  # CPU cost per run vs serial
        wall_ratio = res.table["run_wall_s"].mean() / serial.table["run_wall_s"].mean()
        print(f"  {name}: worker utilisation {util * 100:.0f} %, CPU per run serial/{name} {cpu_ratio:.2f}, "
              f"-> efficiency on an idle machine ~ {util * min(cpu_ratio, 1.0) * 100:.0f} % "
              f"(run wall time inflated x{wall_ratio:.2f} by contention)")
    print(f"identical rows serial / pool / Dask: {same}")
    print(f"load average after: {os.getloadavg()[0]:.2f} (efficiency figures assume an idle machine)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 120)
