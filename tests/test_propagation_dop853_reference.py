"""The numba DOP853 loop of the relative truth (kernels.propagate_dop853): bit for bit a DOP853 loop
written out in plain Python.

Independent reference: the DOP853 loop written out here in plain Python (the tableau of
kernels, scipy's error norm and step control as kernels' module doc states them), calling the same
jitted right-hand side; float64 in the same order of operations gives the same bits. The full
truth's own copy of the loop (kernels_full) is checked against the relative one through the J2
composed truth (tests/test_propagation_composed.py, bit-identical to RelativeTruth). One loop
compiled per right-hand side was built and measured bit-identical but 1-9 % slower on 2 idle cores
(2026-11-28), so the two hand-written copies stay (issue 31 item 5: "if it measures ... no slower");
benchmarks/bench_truth_dop853_cache.py shows why a closure or function argument cannot replace them
(numba 0.68 misses its disk cache for those in every new process)."""

import math

import numpy as np

from proxops.frames.elements import circular_orbit, orbital_period
from proxops.propagation import kernels as k
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

