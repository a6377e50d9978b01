"""Set-up of the full truth (:class:`proxops.propagation.composed.ComposedTruth`): the NRLMSISE-00
density table along the target's predicted path.

The table depends on the target's initial state, the epoch, the Earth orientation, the space
weather over the table's times, the models that move the target (drag off) and the table's
length, not on the chaser: every run of a campaign that disperses the chaser reads the same
table. It is memoised on all of these, in the process (a copy per truth) and on disk
(:mod:`proxops.environment.disk_memo`, keyed also by the pymsis version and, through the folder,
by the package sources). Measured (benchmarks/bench_truth.py ``construction_share``).

A new table (new target, epoch, span or weather) is computed at nodes and interpolated to its rows
(:func:`_compute`): the target path is predicted once to the nodes every LEVEL_EVERY rows (90 s); there
ln rho, the height and the two height derivatives come from three pymsis points at one place (the path
point and +-DENSITY_DH_M along its ellipsoid normal, consecutive in the call so NRLMSISE-00 reuses its
horizontal terms for the two shifted heights: ~1 us instead of ~3.5 us a point), the cross-track
derivative from two points +-DENSITY_DC_M off the orbit plane at every SIDE_EVERY rows (180 s); the
rows between nodes by 8-point Lagrange interpolation in time, never across a jump of NRLMSISE-00's
inputs (a new UTC day: day of year, daily F10.7 and Ap). 676 pymsis points for two orbits instead of
2015, the path at 90 s steps of order 8 instead of 45 s of order 6 (9.9 m instead of 7.0 m from the
100x100 18 s path over two orbits, 107 m instead of 79 m over a day).
Until 2026-11-28 every row was computed (the table was 45-55 % of the 2-orbit propagation it serves).
Measured against that table, 2026-11-28 (500 km, 51.6 deg, 2022-05-01, 100x100 + drag + Sun/Moon,
two orbits): the tabulated density vs direct pymsis along the propagated pair every 10 s 8.5e-6 /
7.7e-6 (target / chaser 100 m ahead) instead of 7.8e-6 / 7.9e-6, chaser 20 km ahead + 4 km radial +
2 km cross-track 3.39e-5 instead of 3.42e-5; the relative position after two orbits moved by
0.0086 mm at 100 m, 2 km and 20 km; against Orekit (tests/test_orekit_validation.py, 100x100 +
drag + Sun/Moon, two orbits) 0.1918 mm at 2 km and 2.6307 mm at 20 km instead of 0.1873 and 2.6265 mm. Interpolation errors of the columns against
every row computed (the same path, interior rows): ln rho 3.7e-6 at 90 s nodes (1.3e-5 at 120 s,
2.4e-4 at 180 s: ln rho along the orbit has structure at ~2 min), the cross-track term at 2 km
3e-7 at 180 s (a 360 s spacing moved the 20 km case by 0.11 mm).
"""

from __future__ import annotations

import numpy as np

from numba import njit

from proxops.core.memo import memo_get
from proxops.environment.disk_memo import digest, disk_get
from proxops.errors import ProxopsError
from proxops.propagation import kernels, kernels_full as kf, kernels_multistep as km

DENSITY_STEP_S = 30.0
DENSITY_MARGIN_S = 600.0  # the table reaches this far past the horizon (extended on demand beyond)
PATH_DEGREE = 30  # the target path that places the density table is predicted to this degree/order at most,
PATH_STEP_S = 90.0  # with the multistep path at this step (s) and order: 9.9 m from the 100x100 18 s path over 2 orbits
PATH_ORDER = 8  # (degree 20: 15 m, which raised the table's error against direct pymsis to 1.0e-5 / 1.14e-5)
DENSITY_DH_M = 5000.0  # height step of the density table's derivatives (m)
DENSITY_DC_M = 20000.0  # cross-track step of its horizontal derivative (m)
LEVEL_EVERY = 3  # ln rho, height and the height derivatives computed every LEVEL_EVERY-th row
SIDE_EVERY = 6  # the cross-track derivative every SIDE_EVERY-th row (a multiple of LEVEL_EVERY)
LAGRANGE_POINTS = 8  # the rows between by this many-point Lagrange interpolation
EDGE_ROWS = 6  # the first and last rows of a segment are all nodes (the cross-track ones every LEVEL_EVERY-th)
_TABLES: dict = {}  # digest of the inputs -> table (n, 5), per process
_FIELD_DIGESTS: dict = {}  # (degree, order) -> digest of the field's C, S, K (1.4 MB at 100x100: hashed once)


def density_table(truth, n: int, *, memo: bool = True) -> np.ndarray:
    """Density table (n, 5) of ``truth`` (a ComposedTruth) at ``n`` rows every DENSITY_STEP_S from t = 0.

    Columns: ln rho, geodetic height, d ln rho/dh, d2 ln rho/dh2 and the cross-track d ln rho/dc,
    from one pymsis call at nodes, interpolated to the rows (module doc). The path only places the table
    (the relative motion is propagated with the full field): it is predicted with the field to
    degree/order PATH_DEGREE at most, by the multistep path at PATH_STEP_S. ``memo=False``
    computes it afresh (tests, benchmarks). (Derivative columns sampled every 4th row and resampled
    by Catmull-Rom were tried earlier: their 30 s wiggles raised the multistep-vs-DOP853 difference
    at 100 m from 0.0006 to 0.010 mm; the 8-point Lagrange resampling here is smooth.)"""
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
    atmosphere = truth.atmosphere
    dates = atmosphere.dates(times)
    f107, f107a, ap = atmosphere.weather.drivers(dates)
    # a row where NRLMSISE-00's inputs jump (a new UTC day: its day of year, daily F10.7 and Ap; pymsis takes
    # the daily Ap only) starts a segment: the interpolation between nodes never crosses one
    day = dates.astype("datetime64[D]").astype(np.int64)
    jump = (np.diff(day) != 0) | (np.diff(f107) != 0) | (np.diff(f107a) != 0) | (np.diff(ap[:, 0]) != 0)
    seg = np.concatenate(([0], np.cumsum(jump)))
    heads = np.flatnonzero(np.concatenate(([True], jump)))
    ends = np.append(heads[1:], n) - 1
    rows = _node_rows(heads, ends, LEVEL_EVERY, EDGE_ROWS, 1)
    side_rows = _node_rows(heads, ends, SIDE_EVERY, 2 * EDGE_ROWS, LEVEL_EVERY)
    side_rows = side_rows[np.isin(side_rows, rows)]
    t_nodes = times[rows]
    y0 = np.append(truth._target0, np.zeros(6))
    out = np.empty((t_nodes.size, 12))
    adams = km.adams_coefficients(PATH_ORDER) + km.lookahead_coefficients(PATH_ORDER, *km.DEFAULT_LOOKAHEAD)
    status, *_ = km.integrate_multistep(y0, t_nodes, np.zeros(3), p, *truth._arrays(), np.zeros((2, 5)), PATH_STEP_S,
                                        *adams, p[kf.I_GRAV] == 2.0, truth.rtol, truth.atol, out)  # fmt: skip
    if status != kernels.STATUS_OK:
        raise ProxopsError("target path prediction for the density table failed")
    rotation = truth.rotation
    geo = kf.geodetic_rows(rotation.to_ecef(t_nodes, out[:, :3]))
    m = t_nodes.size
    # at each node the path point and +-dh along its ellipsoid normal: the same latitude and longitude at
    # heights h +- dh, consecutive in one pymsis call (NRLMSISE-00 reuses its horizontal terms for a point at
    # the previous point's place and time). +-5 km: the second difference of ln rho resolves the curvature
    # (~4e-11 /m^2 at 500 km) above pymsis' float32 noise (1e-5 / dh^2 = 4e-13 /m^2)
    dh = DENSITY_DH_M
    stack = np.repeat(geo, 3, axis=0)
    stack[1::3, 2] += dh
    stack[2::3, 2] -= dh
    # cross-track gradient at constant geodetic height (the chaser's along-track offset is taken by its
    # lead time, its height by the two height derivatives): points +-dc along the orbit normal at fewer
    # nodes, moved to the path's geodetic height
    k = np.searchsorted(rows, side_rows)
    r, v = out[k, :3], out[k, 3:6]
    normal = np.stack([r[:, 1] * v[:, 2] - r[:, 2] * v[:, 1], r[:, 2] * v[:, 0] - r[:, 0] * v[:, 2],
                       r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0]], -1)  # fmt: skip
    normal *= DENSITY_DC_M / np.sqrt(np.sum(normal * normal, axis=1))[:, None]
    ts = t_nodes[k]
    side = kf.geodetic_rows(rotation.to_ecef(np.concatenate((ts, ts)), np.concatenate((r + normal, r - normal))))
    side[:, 2] = np.concatenate((geo[k, 2], geo[k, 2]))
    ln = np.log(atmosphere.density_geodetic(np.concatenate((np.repeat(t_nodes, 3), ts, ts)), np.vstack((stack, side))))
    l0, lu, ld = ln[0 : 3 * m : 3], ln[1 : 3 * m : 3], ln[2 : 3 * m : 3]
    lp, lm = np.split(ln[3 * m :], 2)
    level = np.stack((l0, geo[:, 2], (lu - ld) / (2 * dh), (lu - 2.0 * l0 + ld) / dh**2), -1)
    table = np.empty((n, 5))
    _lagrange_rows(times, seg, t_nodes, seg[rows], level, LAGRANGE_POINTS, table[:, :4])
    _lagrange_rows(times, seg, ts, seg[side_rows], ((lp - lm) / (2 * DENSITY_DC_M))[:, None], LAGRANGE_POINTS,
                   table[:, 4:])  # fmt: skip
    return table


def _node_rows(heads: np.ndarray, ends: np.ndarray, every: int, edge: int, edge_every: int) -> np.ndarray:
    """Row indices of the nodes: every ``every``-th row of each segment from its first, its last, and every
    ``edge_every``-th row of its first and last ``edge`` rows (one-sided interpolation windows at a segment's
    ends: 1.2e-5 at the first rows of a table with the 90 s nodes alone, 3e-6 with every row there)."""
    rows = []
    for a, b in zip(heads, ends):
        rows += [np.arange(a, b, every), np.arange(a, min(a + edge, b), edge_every), np.arange(b, max(b - edge, a), -edge_every),
                 [b]]  # fmt: skip
    return np.unique(np.concatenate(rows).astype(np.int64))


@njit(cache=True)
def _lagrange_rows(t, seg, t_nodes, seg_nodes, values, k, out) -> None:
    """out[i] = the ``k``-point Lagrange interpolant at t[i] of ``values`` (m, c) on the nodes ``t_nodes`` of the
    row's segment (the k nodes nearest; fewer when the segment has fewer). Rows and nodes increasing in time,
    segments contiguous; at a node the node's values (exactly)."""
    m = t_nodes.size
    a = 0  # the row's segment is nodes a .. b - 1
    b = 0
    c = 0  # t_nodes[c] <= t[i] < t_nodes[c + 1] (c in a .. b - 1)
    for i in range(t.size):
        if i == 0 or seg[i] != seg[i - 1]:
            a = b
            while a < m and seg_nodes[a] < seg[i]:
                a += 1
            b = a
            while b < m and seg_nodes[b] == seg[i]:
                b += 1
            c = a
        while c < b - 1 and t_nodes[c + 1] <= t[i]:
            c += 1
        lo = min(max(c - k // 2 + 1, a), max(b - k, a))
        hi = min(lo + k, b)
        for col in range(values.shape[1]):
            out[i, col] = 0.0
        for q in range(lo, hi):
            w = 1.0
            for r in range(lo, hi):
                if r != q:
                    w *= (t[i] - t_nodes[r]) / (t_nodes[q] - t_nodes[r])
            for col in range(values.shape[1]):
                out[i, col] += w * values[q, col]
