"""Set-up of the full truth (:class:`proxops.propagation.composed.ComposedTruth`): the NRLMSISE-00
density table along the target's predicted path.

The table depends on the target's initial state, the epoch, the Earth orientation, the space
weather over the table's times, the models that move the target (drag off) and the table's
length, not on the chaser: every run of a campaign that disperses the chaser reads the same
table. It is memoised on all of these, in the process (a copy per truth) and on disk
(:mod:`proxops.environment.disk_memo`, keyed also by the pymsis version and, through the folder,
by the package sources). Measured (benchmarks/bench_truth.py ``construction_share``).
"""

from __future__ import annotations

import numpy as np

from proxops.core.memo import memo_get
from proxops.environment.disk_memo import digest, disk_get
from proxops.errors import ProxopsError
from proxops.propagation import kernels, kernels_full as kf, kernels_multistep as km

DENSITY_STEP_S = 30.0
DENSITY_MARGIN_S = 600.0  # the table reaches this far past the horizon (extended on demand beyond)
PATH_DEGREE = 30  # the target path that places the density table is predicted to this degree/order at most,
PATH_STEP_S = 45.0  # with the multistep path at this step (s) and order: 5 m from the 100x100 18 s path over 2 orbits
PATH_ORDER = km.DEFAULT_ORDER
DENSITY_DH_M = 5000.0  # height step of the density table's derivatives (m)
DENSITY_DC_M = 20000.0  # cross-track step of its horizontal derivative (m)
_TABLES: dict = {}  # digest of the inputs -> table (n, 5), per process
_FIELD_DIGESTS: dict = {}  # (degree, order) -> digest of the field's C, S, K (1.4 MB at 100x100: hashed once)


def density_table(truth, n: int, *, memo: bool = True) -> np.ndarray:
    """Density table (n, 5) of ``truth`` (a ComposedTruth) at ``n`` rows every DENSITY_STEP_S from t = 0.

    Columns: ln rho, geodetic height, d ln rho/dh, d2 ln rho/dh2 and the cross-track d ln rho/dc,
    from one pymsis call at geodetic points (jitted conversions). The path only places the table
    (the relative motion is propagated with the full field): it is predicted with the field to
    degree/order PATH_DEGREE at most, by the multistep path at PATH_STEP_S. ``memo=False``
    computes it afresh (tests, benchmarks). Derivative columns sampled every 4th row and
    resampled by Catmull-Rom were tried: 35 % instead of 55 % of the propagation, but their 30 s
    wiggles raised the multistep-vs-DOP853 difference at 100 m from 0.0006 to 0.010 mm
    (tests/test_propagation_multistep.py's bound: 0.01 mm), so every row is sampled."""
    times = np.arange(n) * DENSITY_STEP_S
    p = truth.p.copy()
    p[kf.I_DRAG] = 0.0
    p[kf.I_NMAX] = min(p[kf.I_NMAX], PATH_DEGREE)
    p[kf.I_MMAX] = min(p[kf.I_MMAX], PATH_DEGREE)
    if not memo:
        return _compute(truth, p, times)
    atmosphere = truth.atmosphere
    drivers = atmosphere.weather.drivers(atmosphere.dates(times))
    key_p = p.copy()
    key_p[[kf.I_BC_T, kf.I_BC_C, kf.I_CR_C, kf.I_DENS_T0]] = 0.0  # what does not move the target
    npm, C, S, K, _, _ = truth._arrays()
    nm = (int(truth.p[kf.I_NMAX]), int(truth.p[kf.I_MMAX]))
    field_key = memo_get(_FIELD_DIGESTS, nm, lambda: digest(C, S, K))  # (the field is one per (degree, order))
    import pymsis  # (imported by the table's computation anyway)

    key = digest("density_table", truth.epoch.iso, truth._target0, key_p, nm, field_key, npm, truth.rtol, truth.atol,
                 n, *drivers, pymsis.__version__)  # fmt: skip
    table = memo_get(_TABLES, key, lambda: disk_get("density", key, (n, 5), lambda: _compute(truth, p, times)))
    return table.copy()


def _compute(truth, p: np.ndarray, times: np.ndarray) -> np.ndarray:
    n = times.size
    y0 = np.append(truth._target0, np.zeros(6))
    out = np.empty((n, 12))
    adams = km.adams_coefficients(PATH_ORDER) + km.lookahead_coefficients(PATH_ORDER, *km.DEFAULT_LOOKAHEAD)
    status, *_ = km.integrate_multistep(y0, times, np.zeros(3), p, *truth._arrays(), np.zeros((2, 5)), PATH_STEP_S,
                                        *adams, p[kf.I_GRAV] == 2.0, truth.rtol, truth.atol, out)  # fmt: skip
    if status != kernels.STATUS_OK:
        raise ProxopsError("target path prediction for the density table failed")
    rotation = truth.rotation
    r = out[:, :3]
    geo = kf.geodetic_rows(rotation.to_ecef(times, r))
    # +-5 km: the second difference of ln rho resolves the curvature (~4e-11 /m^2 at 500 km)
    # above pymsis' float32 noise (1e-5 / dh^2 = 4e-13 /m^2)
    dh = DENSITY_DH_M
    up = np.stack([np.cos(geo[:, 0]) * np.cos(geo[:, 1]), np.cos(geo[:, 0]) * np.sin(geo[:, 1]), np.sin(geo[:, 0])], -1)
    up_eci = rotation.to_eci(times, up)
    # cross-track gradient at constant geodetic height (the chaser's along-track offset
    # is taken by its lead time, its height by the two height derivatives): points
    # +-dc along the orbit normal, moved to the target's geodetic height
    normal = np.cross(r, out[:, 3:6])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    dc = DENSITY_DC_M
    t2 = np.concatenate([times, times])
    shifted = kf.geodetic_rows(rotation.to_ecef(t2, np.vstack([r + dh * up_eci, r - dh * up_eci])))
    side = kf.geodetic_rows(rotation.to_ecef(t2, np.vstack([r + dc * normal, r - dc * normal])))
    side[:, 2] = np.concatenate([geo[:, 2], geo[:, 2]])  # moved to the target's geodetic height
    rho = truth.atmosphere.density_geodetic(np.concatenate([times, t2, t2]), np.vstack([geo, shifted, side]))
    l0, lu, ld, lp, lm = np.split(np.log(rho), 5)
    table = np.stack([l0, geo[:, 2], (lu - ld) / (2 * dh), (lu - 2.0 * l0 + ld) / dh**2, (lp - lm) / (2 * dc)],
                     axis=-1)  # fmt: skip
    return np.ascontiguousarray(table)
