"""HillPredictor's one-call prediction (the navigation filter's J2 process model) against the chain of
RelativeTruth methods it fuses (with_relative_state, apply_impulse, propagate, relative_state): equal bit
for bit, held accelerations and impulses, forward and after a restart of the cached target."""

import numpy as np

from proxops.frames.elements import OrbitalElements
from proxops.propagation.relative_predictor import HillPredictor


def _chain(model, y_target, x, u, kind, dt):
    y = model.with_relative_state(y_target, x)
    if kind == "impulse":
        if np.any(u):
            y = model.apply_impulse(0.0, y, u)
        return model.relative_state(model.propagate(0.0, y, None, dt))
    return model.relative_state(model.propagate(0.0, y, u, dt))


def test_predict_equals_the_truth_methods_bit_for_bit():
    pred = HillPredictor(OrbitalElements(6378137.0 + 500e3, 0.001, 0.9, 0.1, 0.2, 0.3), j2=True)
    rng = np.random.default_rng(5)
    t = 0.0
    for k in range(40):
        x = np.concatenate([rng.standard_normal(3) * 10.0 ** rng.uniform(0, 4), rng.standard_normal(3) * 0.1])
        kind = "impulse" if k % 3 == 0 else "acceleration"
        u = np.zeros(3) if k % 5 == 0 else rng.standard_normal(3) * (0.05 if kind == "impulse" else 1e-3)
        dt = float(rng.uniform(1.0, 120.0))
        if k == 20:
            t = 10.0  # backwards: the cached target restarts from t = 0
        y_target = pred._target_at(t).copy()
        expected = _chain(pred.model, y_target, x, u, kind, dt)
        got = pred.predict(t, x, u, kind, dt)
        np.testing.assert_array_equal(got, expected)
        t += dt
