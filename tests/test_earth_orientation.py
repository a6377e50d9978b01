"""Earth orientation (proxops.environment.earth) against astropy's GCRS -> ITRS (IAU 2006/2000A,
CIO-based, with astropy's own bundled IERS tables): an independent route and EOP source."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxops.environment.earth import earth_rotation
from proxops.environment.spaceweather import eop_at

EPOCHS = ["1995-06-01T06:00:00", "2008-09-20T12:25:40", "2022-05-01T00:00:00", "2024-05-01T18:00:00"]


def _astropy_itrs(iso: str, dt_s: float) -> np.ndarray:
    """ITRS images (3, 3) of the GCRS unit axes (rows) at ``iso`` + ``dt_s``."""
    from astropy import units as u
    from astropy.coordinates import GCRS, ITRS, CartesianRepresentation
    from astropy.time import Time
    from astropy.utils import iers

    iers.conf.auto_download = False
    t = Time(iso, scale="utc") + dt_s * u.s
    out = []
    for axis in np.eye(3):
        g = GCRS(CartesianRepresentation(axis * 7e6 * u.m), obstime=t).transform_to(ITRS(obstime=t))
        out.append(g.cartesian.xyz.to_value(u.m) / 7e6)
    return np.array(out)


def _worst_arcsec(a: np.ndarray, b: np.ndarray) -> float:
    return max(math.degrees(math.acos(min(1.0, float(x @ y) / np.linalg.norm(x) / np.linalg.norm(y)))) * 3600
               for x, y in zip(a, b))  # fmt: skip


@pytest.mark.parametrize("iso", EPOCHS)
def test_itrf_rotation_with_shipped_eop_on_astropy(iso):
    """With the shipped UT1 - UTC and polar motion the GCRF -> ITRF rotation is within 5 mas of
    astropy at the epoch and 30 mas after 3 h (the frozen precession-nutation: the pole moves in the
    sky, < 0.15"/day); without polar motion it is 0.3-0.6" off (the pole offset itself), so the
    test sees it. Measured 2026-11-27: 0.000-0.003" at 0 h, 0.009-0.012" at 3 h, 0.07-0.10" at
    24 h; 0.38-0.53" without polar motion."""
    e = eop_at(iso + "Z")
    er = earth_rotation(iso + "Z", e["ut1_utc_s"], e["x_arcsec"], e["y_arcsec"])
    no_pm = earth_rotation(iso + "Z", e["ut1_utc_s"])
    for dt, tol in ((0.0, 0.005), (3 * 3600.0, 0.03), (86400.0, 0.15)):
        ref = _astropy_itrs(iso, dt)
        mine = er.to_ecef(dt, np.eye(3))
        assert _worst_arcsec(ref, mine) < tol, (iso, dt, _worst_arcsec(ref, mine))
        assert np.allclose(er.to_eci(dt, mine), np.eye(3), atol=1e-15)
        assert np.allclose(mine, np.array([er.matrix(dt) @ a for a in np.eye(3)]), atol=1e-15)
    assert _worst_arcsec(_astropy_itrs(iso, 0.0), no_pm.to_ecef(0.0, np.eye(3))) > 0.3


def test_polar_motion_reaches_the_kernel():
    """The propagation kernel's Earth-fixed frame (kernels_full._to_ecef) is the ITRF of
    EarthRotation.matrix, polar motion included (to 1e-8 m at 7000 km; polar motion itself
    moves the point by ~10 m), and the harmonics
    acceleration is rotated back with W^T (a radial field stays radial in ECI)."""
    from proxops.propagation import kernels_full as kf

    iso = "2022-05-01T00:00:00Z"
    e = eop_at(iso)
    er = earth_rotation(iso, e["ut1_utc_s"], e["x_arcsec"], e["y_arcsec"])
    p = np.zeros(kf.N_P)
    p[kf.I_THETA0], p[kf.I_OMEGA] = er.theta0, er.omega
    p[kf.I_PM : kf.I_PM + 9] = (er.polar - np.eye(3)).ravel()
    r = np.array([4.1e6, -3.3e6, 4.5e6])
    for t in (0.0, 5000.0):
        mine = np.array(kf._to_ecef(t, *r, p, np.ascontiguousarray(er.npm)))
        assert np.linalg.norm(mine - er.matrix(t) @ r) < 1e-8
        back = np.array(kf._polar(*mine, p, 0))
        assert np.linalg.norm(back - (er.polar.T @ mine)) < 1e-8
