"""The cortex loop's per-tick shortcuts give the numbers of the plain expressions they replace:
CP_g's predicted states (one work vector, matmul into the output row) against the copy-per-step loop,
the reference impulse's node search (bisect on the node times) against numpy's searchsorted, and the
time line's end against its last kept segment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxops.control.cortex_tracking import TrackingSOCP
from proxops.guidance.cortex.timeline import Segment, Timeline

N_RAD_S = math.sqrt(3.986004418e14 / 6878.1e3**3)


def test_predicted_states_are_the_plain_loop_bit_for_bit():
    prob = TrackingSOCP(N_RAD_S, 15, 2.0, 0.0024, 10.0)
    rng = np.random.default_rng(11)
    for _ in range(20):
        x_k = rng.normal(scale=[20.0, 20.0, 5.0, 0.05, 0.05, 0.01])
        dv = rng.normal(scale=2e-3, size=(15, 3))
        expect = [x_k]
        for j in range(15):
            xj = expect[-1].copy()
            xj[3:] += dv[j]
            expect.append(prob.phi @ xj)
        assert np.array_equal(prob.predicted_states(x_k, dv), np.array(expect))


def _segment(t0=100.0):
    rng = np.random.default_rng(2)
    t = t0 + np.array([0.0, 10.0, 20.0, 30.0, 35.0])  # uneven last interval, as a plan's
    return Segment("approach", float(t[0]), float(t[-1]), t=t, x=rng.normal(size=(5, 6)), dv=rng.normal(size=(5, 3)) * 1e-3)


@pytest.mark.parametrize("dt_from_node", [-1e-3, -2e-9, 0.0, 2e-9, 1e-3])
def test_reference_impulse_picks_numpys_node_at_and_around_every_node(dt_from_node):
    seg = _segment()
    for tk in list(seg.t) + [seg.t[0] - 50.0, seg.t[-1] + 50.0]:
        t = float(tk) + dt_from_node
        k = min(max(0, int(np.searchsorted(seg.t, t + 1e-9, side="right")) - 1), len(seg.t) - 2)
        d = np.array(seg.dv[k + 1], float)
        if float(np.linalg.norm(d)) < 1e-9:
            d = np.array(seg.dv[k], float)
        assert np.array_equal(seg.impulse(t), d)


def test_timeline_end_is_the_last_kept_segment_end():
    a = _segment(0.0)
    b = Segment("hold2", 35.0, 35.0 + 1e-10, x_hold=np.zeros(6))  # shorter than 1e-9 s: dropped
    tl = Timeline(N_RAD_S, [a, b])
    assert tl.segments == [a] and tl.t_end == a.t1 == 35.0
    assert np.array_equal(tl.final_state, a.state(N_RAD_S, 35.0))
