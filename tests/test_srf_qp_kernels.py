"""The jitted pieces of the srf MPC's QP assembly against their definitions (KeepOutSphere eqs. 26-28).

_cbf_rows_kernel builds the (29j) rows of the free drift (supporting half-spaces and the CBF condition
linearised about a reference drift); _drift_check_kernel gives the true distance and g = hdot + alpha h
of a drift. Both replace numpy expressions written from KeepOutSphere.halfspace / cbf_linearization /
cbf_value: the rows must be those numbers bit for bit (the srf trajectories are unchanged), here on random
drifts (CW STMs of a 2 h orbit), with the KOZ centre at and off the origin, with and without a reference
impulse, and with reference points grazing the sphere.
"""

import math

import numpy as np
import pytest

from proxops.constraints.keep_out import KeepOutSphere
from proxops.control.srf_mpc import _cbf_rows_kernel, _drift_check_kernel, _drift_stms

N_ORB = 2 * math.pi / 7255.0
PHI = _drift_stms(N_ORB, np.linspace(7255.0 / 36, 7255.0, 36))
UM, ALPHA = 3.0, 0.01


def _rows_by_definition(koz, x, ur):
    """The (29j) rows as SrfMpc._build wrote them in numpy from KeepOutSphere's definitions."""
    cx = PHI @ x
    D = PHI[:, :, 3:6]
    xr = cx + D @ ur
    n_hat, b_half = koz.halfspace(xr[:, :3])
    half = np.einsum("fk,fkl->fl", n_hat, D[:, :3, :]) * UM / 1000.0
    half_lo = (b_half - np.einsum("fk,fk->f", n_hat, cx[:, :3])) / 1000.0
    grad, g_ref = koz.cbf_linearization(xr, ALPHA)
    gu = np.einsum("fk,fkl->fl", grad, D)
    scale = np.maximum(np.linalg.norm(gu, axis=1) * UM, 1e-12)
    return cx, xr, half, half_lo, gu * UM / scale[:, None], (gu @ ur - g_ref) / scale


@pytest.mark.parametrize("seed", range(4))
def test_cbf_rows_kernel_gives_the_rows_of_the_definition_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for trial in range(60):
        centre = rng.uniform(-20.0, 20.0, 3) if trial % 3 == 0 else np.zeros(3)
        koz = KeepOutSphere(60.0, centre)
        x = np.concatenate([rng.uniform(-2000.0, 2000.0, 3), rng.uniform(-0.5, 0.5, 3)])
        if trial % 5 == 0:  # start on the sphere: the reference drift grazes it
            x[:3] = centre + 60.0 * x[:3] / np.linalg.norm(x[:3])
        ur = rng.uniform(-0.3, 0.3, 3) if trial % 2 else np.zeros(3)
        cx, xr, half, half_lo, lin, lin_lo = _rows_by_definition(koz, x, ur)
        h, h_lo, li, gu, g_ref, scale, n_hat, ok = _cbf_rows_kernel(PHI, cx, xr, koz.center_m, 60.0, ALPHA, UM, 1e-12)
        assert ok
        if np.any(centre):  # the caller's path for an off-origin centre (numpy's n . c)
            h_lo = (60.0 + n_hat @ centre - np.einsum("fk,fk->f", n_hat, cx[:, :3])) / 1000.0
        assert np.array_equal(h, half) and np.array_equal(h_lo, half_lo)
        assert np.array_equal(li, lin) and np.array_equal((gu @ ur - g_ref) / scale, lin_lo)


def test_cbf_rows_kernel_refuses_a_reference_at_the_centre():
    x = np.zeros(6)  # the unforced drift from the centre stays at the centre
    cx = PHI @ x
    *_, ok = _cbf_rows_kernel(PHI, cx, cx.copy(), np.zeros(3), 60.0, ALPHA, UM, 1e-12)
    assert not ok


def test_drift_check_kernel_matches_the_definition_on_and_off_the_sphere():
    rng = np.random.default_rng(7)
    for centre in (np.zeros(3), np.array([3.0, -7.0, 1.0])):
        koz = KeepOutSphere(60.0, centre)
        xs = np.concatenate([rng.uniform(-300.0, 300.0, (200, 3)), rng.uniform(-1.0, 1.0, (200, 3))], axis=1)
        xs[:20, :3] = centre + 60.0 * xs[:20, :3] / np.linalg.norm(xs[:20, :3], axis=1, keepdims=True)
        dist, g = _drift_check_kernel(xs, centre, 60.0, ALPHA)
        assert np.array_equal(dist, np.linalg.norm(xs[:, :3] - centre, axis=1))
        assert np.array_equal(g, koz.cbf_value(xs, ALPHA))
        # independent value on the sphere: h = 0 there, so g = hdot = 2 (p - c) . v
        assert g[:20] == pytest.approx(2.0 * np.sum((xs[:20, :3] - centre) * xs[:20, 3:], axis=1), abs=1e-9)


def test_max_violation_kernel_equals_the_numpy_definition():
    """_Qp.max_violation's jitted pass against the definition written with scipy/numpy (rows switched off
    at +-inf, bounds at +-inf, points inside and outside), and exactly 0 at a feasible point."""
    import scipy.sparse as sp

    from proxops.control.srf_mpc import _Qp

    rng = np.random.default_rng(3)
    for trial in range(40):
        n, p, m = 30, 5, 25
        A = sp.random(p, n, density=0.4, random_state=trial, format="csc")
        G = sp.random(m, n, density=0.3, random_state=trial + 100, format="csc")
        z0 = rng.uniform(0.0, 1.0, n)
        gz = G @ z0
        lo, hi = gz - rng.uniform(0, 0.1, m), gz + rng.uniform(0, 0.1, m)
        lo[:3], hi[3:6] = -np.inf, np.inf
        lb, ub = np.zeros(n), np.ones(n)
        lb[-2:], ub[-2:] = -np.inf, np.inf
        qp = _Qp(None, None, A, A @ z0, G, lo, hi, lb, ub, 1)
        z = z0 if trial % 4 == 0 else z0 + rng.normal(0.0, 0.05, n)
        eq = np.abs(A @ z - qp.b_eq)
        g = G @ z
        ref = max(eq.max(), np.maximum(np.maximum(lo - g, g - hi), 0.0).max(),
                  np.maximum(np.maximum(lb - z, z - ub), 0.0).max())
        got = qp.max_violation(z)
        assert got == ref
        if trial % 4 == 0:
            assert got <= 1e-15  # z0 satisfies every row (up to the rounding of A z0)
