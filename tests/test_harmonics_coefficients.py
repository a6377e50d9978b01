"""The recursion coefficients of the harmonic field (environment/harmonics.py, recursion_coefficients,
whole-array form) against the loop over (n, m) written from its docstring's definitions (the Holmes &
Featherstone normalised recursion factors a_nm, b_nm and the coefficient products c1..c3 C/S)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxops.environment.harmonics import SphericalHarmonics, recursion_coefficients


def loop_form(nmax: int, C: np.ndarray, S: np.ndarray) -> np.ndarray:
    K = np.zeros((16, nmax + 3, nmax + 3))
    for n in range(nmax + 3):
        for m in range(n + 1):
            if n >= m + 1:
                K[0, n, m] = math.sqrt((2.0 * n + 1.0) * (2.0 * n - 1.0) / ((n - m) * (n + m)))
            if n >= m + 2:
                K[1, n, m] = math.sqrt((2.0 * n + 1.0) * (n + m - 1.0) * (n - m - 1.0) / ((2.0 * n - 3.0) * (n + m) * (n - m)))
            if n > nmax:
                continue
            tn, tn3 = 2.0 * n + 1.0, 2.0 * n + 3.0
            if m == 0:
                c1, c2 = math.sqrt(tn * (n + 1.0) * (n + 2.0) / (2.0 * tn3)), 0.0
            else:
                c1 = math.sqrt(tn * (n + m + 1.0) * (n + m + 2.0) / tn3)
                c2 = math.sqrt((2.0 if m == 1 else 1.0) * tn * (n - m + 1.0) * (n - m + 2.0) / tn3)
            c3 = math.sqrt(tn * (n + m + 1.0) * (n - m + 1.0) / tn3)
            K[2:8, n, m] = c1 * C[n, m], c1 * S[n, m], c2 * C[n, m], c2 * S[n, m], c3 * C[n, m], c3 * S[n, m]
    pairs = K[8:].reshape(nmax + 3, nmax + 3, 8)
    for k, (plane, sign) in enumerate(((4, 1), (5, 1), (5, 1), (4, -1), (2, -1), (3, 1), (3, -1), (2, -1))):
        pairs[:, :, k] = sign * K[plane]
    return K


@pytest.mark.parametrize("degree, order, central", [(2, 0, False), (2, 2, False), (20, 20, True), (120, 120, False)])
def test_recursion_coefficients_equal_the_loop_form_bit_for_bit(degree, order, central):
    field = SphericalHarmonics(degree, order, include_central=central)
    assert np.array_equal(recursion_coefficients(degree, field.C, field.S), loop_form(degree, field.C, field.S))
    # a_nm of the first off-diagonal term: sqrt(2n + 1) for m = n - 1 (Holmes & Featherstone 2002)
    assert field.K[0, 3, 2] == pytest.approx(math.sqrt(7.0), rel=1e-15)
