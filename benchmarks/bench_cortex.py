"""Benchmark of CORTEX reference generation (cortex-convex-guidance.md §5.1.1, issue 14).

1. Compute time of one full plan (outer search, CP1 with KOS planes, CP2 with plume
   successive convexification, holds on the real eclipse profile, plan checks) over the
   N = 100 Fibonacci axes, in this process: median / IQR / max, next to the paper's
   30.9 s (IQR 7.23 s) and the goal of issue 32 (median < 0.05 s per axis).
2. Median time of one CP1 and one CP2 SOCP solve (Clarabel) over those plans.
3. Wall time of the 100-axis campaign on 2 workers through the campaign engine
   (``proxops cortex references --n 100 --workers 2``; goal < 5 s, issue 32), including process start.
4. The 100-axis statistics (delta-v, TOF) and the fixed axis of §5.1.2 next to the paper.

Run: ``.venv/bin/python benchmarks/bench_cortex.py [--n 100] [--no-campaign]``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from proxops.guidance.cortex.config import PAPER_FIXED_AXIS_HILL, fibonacci_axes  # noqa: E402
from proxops.guidance.cortex.reference import plan_reference  # noqa: E402
from proxops.scenarios.loader import load_scenario  # noqa: E402
from proxops.systems.cortex import PAPER_5_1_1, PAPER_5_1_2  # noqa: E402
from proxops.systems.cortex_setup import config_from_scenario, eclipse_profile  # noqa: E402

GOAL_MEDIAN_S = 0.05  # issue 32 (issue 14: 0.1)
GOAL_CAMPAIGN_S = 5.0  # issue 32 (issue 14: 15)


def _stats(v):
    q1, q2, q3 = np.percentile(v, [25, 50, 75])
    return q2, q3 - q1, float(np.max(v))


def plans(n: int) -> None:
    sc = load_scenario("cortex-reference").scenario
    cfg = config_from_scenario(sc)
    prof = eclipse_profile(sc)
    plan_reference(PAPER_FIXED_AXIS_HILL, cfg, eclipse=prof)  # warm-up (imports, first Clarabel set-up)
    times, cp1, cp2, dv, tof, bad = [], [], [], [], [], 0
    for e in fibonacci_axes(n):
        t0 = time.perf_counter()
        p = plan_reference(e, cfg, eclipse=prof)
        times.append(time.perf_counter() - t0)
        cp1 += p.cp1_solve_times_s
        cp2 += p.cp2_solve_times_s
        if p.ok:
            dv.append(p.dv_total_mps)
            tof.append(p.tof_s / 60)
        else:
            bad += 1
    med, iqr, mx = _stats(np.array(times))
    print(f"one full plan over {n} Fibonacci axes (this process, serial): median {med:.4f} s, IQR {iqr:.4f} s, "
          f"max {mx:.4f} s | paper {PAPER_5_1_1['compute_median_s']} s (IQR {PAPER_5_1_1['compute_iqr_s']} s): "
          f"{PAPER_5_1_1['compute_median_s'] / med:.0f}x faster | goal {GOAL_MEDIAN_S} s: ratio {med / GOAL_MEDIAN_S:.2f}")
    print(f"SOCP solve (Clarabel): CP1 median {np.median(cp1) * 1e3:.3f} ms over {len(cp1)} solves, "
          f"CP2 median {np.median(cp2) * 1e3:.3f} ms over {len(cp2)} solves")
    dmed, diqr, _ = _stats(np.array(dv))
    tmed, tiqr, _ = _stats(np.array(tof))
    print(f"{n - bad}/{n} plans ok; delta-v median {dmed:.4f} m/s IQR {diqr:.4f} (paper {PAPER_5_1_1['dv_median_mps']} / "
          f"{PAPER_5_1_1['dv_iqr_mps']}); TOF tau1+tau2 median {tmed:.2f} min IQR {tiqr:.4f} "
          f"(paper {PAPER_5_1_1['tof_median_min']} / {PAPER_5_1_1['tof_iqr_min']})")
    p = plan_reference(PAPER_FIXED_AXIS_HILL, cfg, eclipse=prof)
    print(f"fixed axis §5.1.2 (Hill [-0.7071, -0.7071, 0]): tau1 {p.tau1_s / 60:.2f} min, tau2 {p.tau2_s / 60:.2f} min, "
          f"TOF {p.tof_s / 60:.2f} min, holds {p.hold1_s:.0f} + {p.hold2_s:.0f} s, dv {p.dv_total_mps:.4f} m/s | paper "
          f"{PAPER_5_1_2['tau1_min']} + {PAPER_5_1_2['tau2_min']} = {PAPER_5_1_2['tof_min']} min, {PAPER_5_1_2['dv_mps']} m/s")


def campaign(n: int, workers: int = 2) -> None:
    from proxops.analysis.campaign import run_campaign, shutdown_pools
    from proxops.cli_cortex import references_scenario

    data = references_scenario("cortex-reference", n)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = run_campaign(data, workers=workers, out=os.path.join(tmp, "c"), progress=False)
        wall = time.perf_counter() - t0
    shutdown_pools()
    ok = int(res.table["success"].sum())
    print(f"{n}-axis campaign on {workers} workers (campaign engine, Parquet rows, pool start included): "
          f"{wall:.2f} s, {ok}/{n} ok | goal {GOAL_CAMPAIGN_S} s: ratio {wall / GOAL_CAMPAIGN_S:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--no-campaign", action="store_true")
    args = ap.parse_args()
    plans(args.n)
    if not args.no_campaign:
        campaign(args.n)


if __name__ == "__main__":
    main()
