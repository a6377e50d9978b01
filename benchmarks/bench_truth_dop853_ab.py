"""A/B: the DOP853 loop written once and compiled per right-hand side (kernels.dop853_for) against the
hand-written copies it replaced (kernels.py / kernels_full.py at REV, loaded in the same process as
separate modules). Bit-identity is asserted; CPU-time medians of alternated runs (ABBA) and the
median of the per-pair ratios, for the J2 fast path (one orbit with control; 3 orbits of dense
samples) and the full truth's numba DOP853 (one orbit; 100x100 + drag + Sun/Moon, 20x20 + drag +
Sun/Moon + SRP with its shadow-crossing restarts).
Run: ``.venv/bin/python benchmarks/bench_truth_dop853_ab.py [REV] [N]`` (default REV 3bd4607, the last
commit with the copies; N = 31 pairs). The first run compiles the old copies (~1-2 min).
"""

from __future__ import annotations

import importlib.util
import os
import statistics
import subprocess
import sys
import time

import numpy as np

from proxops._numba_cache import cache_dir
from proxops.environment.forces import Spacecraft
from proxops.propagation import kernels as k, kernels_full as kf
from proxops.propagation.composed import ComposedTruth, ForceModels
from proxops.propagation.truth import RelativeTruth

sys.path.insert(0, os.path.dirname(__file__))
import bench_truth as b  # noqa: E402


def old_modules(rev: str):
    """kernels and kernels_full of ``rev`` as modules (files kept under the numba cache dir, so their
    compiled code is cached between runs)."""
    root = subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True, check=True,
                          cwd=os.path.dirname(__file__)).stdout.strip()  # fmt: skip
    folder = os.path.join(cache_dir(), f"ab-{rev}")
    os.makedirs(folder, exist_ok=True)
    mods = []
    for name in ("kernels", "kernels_full"):
        path = os.path.join(folder, f"{name}_{rev}.py")
        text = subprocess.run(["git", "show", f"{rev}:src/proxops/propagation/{name}.py"], capture_output=True,
                              text=True, check=True, cwd=root).stdout  # fmt: skip
        if not os.path.exists(path) or open(path).read() != text:
            with open(path, "w") as f:
                f.write(text)
        spec = importlib.util.spec_from_file_location(f"proxops.propagation._ab_{name}", path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod
        spec.loader.exec_module(mod)
        mods.append(mod)
    return mods


def main() -> None:
    rev = sys.argv[1] if len(sys.argv) > 1 else "3bd4607"
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 31
    ko, kfo = old_modules(rev)
    rt = RelativeTruth(b.ORBIT, np.array([300.0, 2000.0, -50.0, 0.1, -0.2, 0.05]), j2=True)
    y0, u = rt.initial_state(), np.array([1e-5, 2e-5, -1e-5])
    dense_times = np.linspace(0.0, 3.0 * b.PERIOD, 721)
    srp = ForceModels(epoch=b.EPOCH, degree=20, order=20, drag=True, sun=True, moon=True, srp=True,
                      target=Spacecraft(mass_kg=500.0, area_m2=2.0, name="truth.target"),
                      chaser=Spacecraft(mass_kg=100.0, area_m2=1.5, cr=1.5, name="truth.chaser"))  # fmt: skip

    def full(models):
        tr = ComposedTruth(b.ORBIT, b.BENCH_X0, models, horizon_s=b.PERIOD, integrator="dop853")

        def run(mod):
            out = np.empty((2, 12))
            mod.integrate_full(tr.initial_state()[:12].copy(), np.array([0.0, b.PERIOD]), np.zeros(3), tr.p,
                               *tr._arrays(), tr._dens, tr.rtol, tr.atol, out)  # fmt: skip
            return out[1]

        return run

    cases = (
        ("J2, one orbit with control, x20", k, ko, lambda m: [m.propagate_dop853(y0, b.PERIOD, u, rt.params, rt.rtol,
                                                                                 rt.atol)[0] for _ in range(20)][-1]),
        ("J2, 3 orbits, 721 dense samples, x5", k, ko,
         lambda m: [m.free_drift_hill(y0, dense_times, rt.params, rt.rtol, rt.atol)[0] for _ in range(5)][-1]),
        ("full 20x20 + drag + Sun/Moon + SRP", kf, kfo, full(srp)),
        ("full 100x100 + drag + Sun/Moon", kf, kfo, full(b.BENCH_MODELS)),
    )  # fmt: skip
    print(f"DOP853 loop written once (new) vs the hand-written copies of {rev} (old); load {os.getloadavg()[0]:.1f}")
    for label, new, old, fn in cases:
        assert np.array_equal(fn(new), fn(old)), label
        reps = n if "100x100" not in label else max(3, n // 4)
        tn, to = [], []
        for r in range(reps):
            for mod, acc in ((new, tn), (old, to)) if r % 2 == 0 else ((old, to), (new, tn)):
                t0 = time.process_time()
                fn(mod)
                acc.append(time.process_time() - t0)
        ratio = statistics.median(a / c for a, c in zip(tn, to))
        print(f"  {label:<38} new {statistics.median(tn) * 1e3:8.3f} ms, old {statistics.median(to) * 1e3:8.3f} ms, "
              f"median pair ratio new/old {ratio:.3f} (bit-identical; {reps} pairs; load {os.getloadavg()[0]:.1f})",
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
