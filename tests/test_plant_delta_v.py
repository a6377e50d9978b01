"""translational_delta_v: |u| (impulse) or |u| dt (held acceleration), bit-identical to the
dot-product norm sqrt(u @ u) it replaced, at the magnitude limits of a float."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxops.dynamics.plant import translational_delta_v


@pytest.mark.parametrize("scale", [1e-150, 1e-9, 1.0, 1e9, 1e150])
def test_norm_matches_dot_product_bits(scale):
    rng = np.random.default_rng(7)
    for u in rng.standard_normal((2000, 3)) * scale:
        assert translational_delta_v(u, "impulse", 2.0) == math.sqrt(u @ u)
        assert translational_delta_v(u, "acceleration", 2.0) == math.sqrt(u @ u) * 2.0


def test_closed_form_and_other_lengths():
    assert translational_delta_v(np.array([3.0, 4.0, 12.0]), "impulse", 5.0) == 13.0  # 3-4-12-13
    assert translational_delta_v(np.array([3.0, 4.0, 12.0]), "acceleration", 0.5) == 6.5
    assert translational_delta_v(np.zeros(3), "impulse", 1.0) == 0.0
    assert translational_delta_v(np.array([3.0, 4.0]), "impulse", 1.0) == 5.0  # planar control (2,)
