"""The DOP853 step and accept/reject loop written once (kernels._dop853_step, kernels._accepted_step)
and compiled per right-hand side (kernels.dop853_for): bit for bit the hand-written loop.

Independent reference: the DOP853 loop written out here in plain Python (the tableau of
kernels, scipy's error norm and step control as kernels' module doc states them), calling the same
jitted right-hand side; float64 in the same order of operations gives the same bits. The full
truth's copy is checked against the relative one through the J2 composed truth
(tests/test_propagation_composed.py, bit-identical to RelativeTruth), and both generated copies
are found in numba's disk cache under their own names."""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from proxops.frames.elements import circular_orbit, orbital_period
from proxops.propagation import kernels as k, kernels_full as kf
from proxops.propagation.truth import RelativeTruth

ORBIT = circular_orbit(altitude=500e3, inc=math.radians(51.6), raan=0.3, arg_lat=0.2)
PERIOD = orbital_period(ORBIT.sma)


def _python_dop853(y0, t_end, u, p, rtol, atol):
    """State after t_end s: DOP853 from t = 0 with kernels' first step, scipy's step control."""
    y, t = y0.copy(), 0.0
    f0 = np.empty(12)
    k.rhs_relative(y, u, p, f0)
    h_abs = min(t_end, k.initial_step_orbit(y, p, rtol))
    while t < t_end:
        rejected = False
        while True:
            clipped = t + h_abs >= t_end
            h = t_end - t if clipped else h_abs
            K = np.empty((k.N_STAGES + 1, 12))
            K[0] = f0
            for s in range(1, k.N_STAGES):
                work = np.empty(12)
                for i in range(12):
                    acc = 0.0
                    for j in range(s):
                        acc += k.A[s, j] * K[j, i]
                    work[i] = y[i] + h * acc
                k.rhs_relative(work, u, p, K[s])
            y_new = np.empty(12)
            for i in range(12):
                acc = 0.0
                for j in range(k.N_STAGES):
                    acc += k.B[j] * K[j, i]
                y_new[i] = y[i] + h * acc
            k.rhs_relative(y_new, u, p, K[k.N_STAGES])
            err = k.dop853_error_norm(y, y_new, K, h, rtol, atol)
            if err < 1.0:
                factor = k.MAX_FACTOR if err == 0.0 else min(k.MAX_FACTOR, k.SAFETY * err**k.ERROR_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                h_abs = max(h * factor, h_abs) if clipped else h * factor
                break
            h_abs = h * max(k.MIN_FACTOR, k.SAFETY * err**k.ERROR_EXPONENT)
            rejected = True
        t = t_end if clipped else t + h
        y, f0 = y_new, K[k.N_STAGES].copy()
    return y


def test_generated_relative_loop_is_the_hand_written_loop_bit_for_bit_over_two_orbits():
    truth = RelativeTruth(ORBIT, np.array([300.0, 20000.0, -500.0, 0.1, -0.3, 0.05]), j2=True)
    u = np.array([2e-5, -1e-5, 3e-5])
    y0 = truth.initial_state()
    ours, status, n_steps = k.propagate_dop853(y0, 2.0 * PERIOD, u, truth.params, truth.rtol, truth.atol)
    assert status == k.STATUS_OK and n_steps > 50
    assert np.array_equal(ours, _python_dop853(y0, 2.0 * PERIOD, u, truth.params, truth.rtol, truth.atol))


_PROBE = """
import json, math, numpy as np
from proxops.frames.elements import circular_orbit
from proxops.propagation import kernels as k, kernels_full as kf
from proxops.propagation.composed import ComposedTruth, ForceModels
from proxops.propagation.truth import RelativeTruth
orbit = circular_orbit(altitude=500e3, inc=0.9, raan=0.3, arg_lat=0.2)
rel = RelativeTruth(orbit, np.array([0.0, 2000.0, 0.0, 0.0, 0.0, 0.0]), j2=True)
full = ComposedTruth(orbit, np.array([0.0, 2000.0, 0.0, 0.0, 0.0, 0.0]), ForceModels(degree=4, order=4), horizon_s=60.0)
y = rel.initial_state()
K, work, y_new, f0, u = np.empty((k.N_STAGES + 1, 12)), np.empty(12), np.empty(12), np.empty(12), np.zeros(3)
k.rhs_relative(y, u, rel.params, f0)
k.dop853_step(0.0, y, f0, 10.0, u, (rel.params,), K, work, y_new)
k._accepted_relative(y, f0, 0.0, 10.0, 20.0, u, (rel.params,), k.SAFETY, 1e-10, 1e-6, K, work, y_new, 0, True)
args = (full.p, *full._arrays(), full._dens)
kf.rhs_full(0.0, y, u, *args, f0)
kf._step(0.0, y, f0, 10.0, u, args, K, work, y_new)
kf._accepted_step(y, f0, 0.0, 10.0, 20.0, u, args, full.p[kf.I_SAFETY], 1e-10, 1e-6, K, work, y_new, 0, True)
print(json.dumps({f.__name__: [sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values())]
                  for f in (k.dop853_step, k._accepted_relative, kf._step, kf._accepted_step)}))
"""


@pytest.mark.slow  # two numba processes (~3 s CPU each)
def test_generated_copies_load_from_the_disk_cache_in_a_new_process():
    """Two processes run each generated copy once: the second loads all four from numba's disk cache
    (a closure or a function argument would miss there: benchmarks/bench_truth_dop853_cache.py)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    runs = [subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True)
            for _ in range(2)]  # fmt: skip
    second = json.loads(runs[1].stdout.strip().splitlines()[-1])
    assert set(second) == {"relative_step", "relative_accepted_step", "full_step", "full_accepted_step"}
    assert all(hits == 1 and misses == 0 for hits, misses in second.values()), second
