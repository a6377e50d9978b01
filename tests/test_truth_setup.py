"""Set-up of the full truth: the density table against direct NRLMSISE-00 calls, and the set-up
memos (in the process and on disk) returning exactly what a fresh computation gives.

Independent references: pymsis called directly at the propagated target and chaser (the table
must stay within pymsis' own float32 noise, ~1e-6..1e-5 relative), erfa through a fresh
:func:`third_body_fit`, and a table computed afresh (``memo=False``)."""

import math
from dataclasses import replace

import numpy as np
import pytest

from proxops.environment import disk_memo, ephemeris
from proxops.environment.forces import Spacecraft
from proxops.frames.elements import circular_orbit, orbital_period
from proxops.propagation import full_setup, kernels_full as kf
from proxops.propagation.composed import ComposedTruth, ForceModels

ORBIT = circular_orbit(altitude=500e3, inc=math.radians(51.6), raan=0.3, arg_lat=0.2)
PERIOD = orbital_period(ORBIT.sma)
MODELS = ForceModels(epoch="2022-05-01T00:00:00Z", degree=20, order=20, drag=True, sun=True, moon=True,
                     target=Spacecraft(mass_kg=500.0, area_m2=2.0, name="truth.target"),
                     chaser=Spacecraft(mass_kg=100.0, area_m2=1.5, name="truth.chaser"))  # fmt: skip


@pytest.fixture
def disk(tmp_path, monkeypatch):
    """The disk memo in a temporary folder, the process memos empty."""
    monkeypatch.setattr(disk_memo, "memo_dir", lambda: str(tmp_path))
    monkeypatch.setenv("PROXOPS_SETUP_CACHE", "1")
    full_setup._TABLES.clear()
    ephemeris._cached_fit.cache_clear()
    yield tmp_path
    full_setup._TABLES.clear()
    ephemeris._cached_fit.cache_clear()


def test_density_table_within_pymsis_noise_along_the_propagated_pair_over_two_orbits():
    """Tabulated density at the propagated target (and the chaser 2 km ahead) every 10 s over two
    orbits (20x20 + drag + Sun/Moon here), against pymsis called there. Measured 2026-11-28 with
    100x100 (bench_truth.construction_share): max rel. error 8.5e-6 target, 8.8e-6 chaser with the table
    interpolated from 90 s / 180 s nodes (7.8e-6, 9.5e-6 with every 30 s row computed); pymsis computes in
    float32 (~1e-6..1e-5), so this is mostly its noise."""
    horizon = 2.0 * PERIOD
    truth = ComposedTruth(ORBIT, np.array([0.0, 2000.0, 0.0, 0.0, 0.0, 0.0]), MODELS, horizon_s=horizon)
    grid = np.arange(0.0, horizon + 1.0, 10.0)
    ys = truth._integrate(truth.initial_state()[:12].copy(), grid, np.zeros(3))
    tabled = np.array([kf.densities(tk, yk, truth.p, truth.npm, truth._dens) for tk, yk in zip(grid, ys)])
    direct = truth.atmosphere.density(np.concatenate([grid, grid]), np.vstack([ys[:, :3], ys[:, :3] + ys[:, 6:9]]))
    rel = np.abs(tabled / np.stack(np.split(direct, 2), -1) - 1.0).max(axis=0)
    assert rel[0] < 1e-5 and rel[1] < 1.2e-5, rel
    # the horizon is inside the table's rows (interpolated, not held at the last row)
    assert grid[-1] <= (truth._dens.shape[0] - 3) * full_setup.DENSITY_STEP_S


def test_memoised_table_is_the_fresh_table_and_keyed_on_the_target_not_the_chaser(disk):
    a = ComposedTruth(ORBIT, np.array([0.0, 2000.0, 0.0, 0.0, 0.0, 0.0]), MODELS, horizon_s=PERIOD)
    n = a._dens.shape[0]
    fresh = full_setup.density_table(a, n, memo=False)
    assert np.array_equal(a._dens, fresh)
    assert len(list(disk.glob("density-*.npy"))) == 1
    # another chaser state and spacecraft: the same table, from the process memo (no new file)
    other = replace(MODELS, chaser=Spacecraft(mass_kg=50.0, area_m2=3.0, name="truth.chaser"))
    b = ComposedTruth(ORBIT, np.array([100.0, -5000.0, 20.0, 0.0, 0.0, 0.0]), other, horizon_s=PERIOD)
    assert np.array_equal(b._dens, fresh) and b._dens is not a._dens
    assert len(list(disk.glob("density-*.npy"))) == 1
    # a target 1 km higher: another table
    higher = circular_orbit(altitude=501e3, inc=math.radians(51.6), raan=0.3, arg_lat=0.2)
    c = ComposedTruth(higher, np.zeros(6), MODELS, horizon_s=PERIOD)
    assert not np.array_equal(c._dens[:, 1], fresh[:, 1])
    assert len(list(disk.glob("density-*.npy"))) == 2
    # a new process (memo empty) reads the disk; a damaged file is recomputed and rewritten
    full_setup._TABLES.clear()
    d = ComposedTruth(ORBIT, np.zeros(6), MODELS, horizon_s=PERIOD)
    assert np.array_equal(d._dens, fresh)
    path = next(p for p in disk.glob("density-*.npy") if np.array_equal(np.load(p), fresh))
    path.write_bytes(b"not an array")
    full_setup._TABLES.clear()
    e = ComposedTruth(ORBIT, np.zeros(6), MODELS, horizon_s=PERIOD)
    assert np.array_equal(e._dens, fresh) and np.array_equal(np.load(path), fresh)


def test_memoised_sun_moon_fit_is_the_fresh_fit(disk):
    fresh = ephemeris.third_body_fit("2022-05-01T00:00:00Z")
    assert np.array_equal(ephemeris.cached_third_body_fit("2022-05-01T00:00:00Z"), fresh)
    ephemeris._cached_fit.cache_clear()  # a new process: from the disk
    assert np.array_equal(ephemeris.cached_third_body_fit("2022-05-01T00:00:00Z"), fresh)
    assert len(list(disk.glob("sunmoon-*.npy"))) == 1
    assert not np.array_equal(ephemeris.cached_third_body_fit("2022-05-02T00:00:00Z"), fresh)


def test_density_table_across_a_space_weather_jump_at_midnight():
    """Two orbits from 22:30 UTC with the shipped CSSI weather: at midnight the day of year and the daily
    F10.7 (119.7 -> 109.0 sfu) jump, and the table's nodes are interpolated on each side apart. Against
    pymsis called at the propagated target and chaser (2 km ahead) every 10 s, more than 60 s from the jump
    (the kernel's Catmull-Rom spans it for +-1 row, as it did with every row computed): < 1.2e-5. Measured
    2026-11-28: 9.3e-6 / 9.9e-6 (every row computed: 9.8e-6 / 9.7e-6; without all-node segment ends
    1.2e-5 / 1.3e-5 in the first rows)."""
    from proxops.environment.spaceweather import weather_history

    epoch = "2022-05-01T22:30:00Z"
    models = replace(MODELS, epoch=epoch, weather=weather_history(epoch))
    horizon = 2.0 * PERIOD
    truth = ComposedTruth(ORBIT, np.array([0.0, 2000.0, 0.0, 0.0, 0.0, 0.0]), models, horizon_s=horizon)
    f107 = truth.atmosphere.weather.drivers(truth.atmosphere.dates(np.array([5399.0, 5400.0])))[0]
    assert f107[0] != f107[1]  # the drivers do jump at midnight (5400 s)
    grid = np.arange(0.0, horizon + 1.0, 10.0)
    ys = truth._integrate(truth.initial_state()[:12].copy(), grid, np.zeros(3))
    tabled = np.array([kf.densities(tk, yk, truth.p, truth.npm, truth._dens) for tk, yk in zip(grid, ys)])
    direct = truth.atmosphere.density(np.concatenate([grid, grid]), np.vstack([ys[:, :3], ys[:, :3] + ys[:, 6:9]]))
    rel = np.abs(tabled / np.stack(np.split(direct, 2), -1) - 1.0)
    far = np.abs(grid - 5400.0) > 60.0
    assert rel[far].max() < 1.2e-5, rel[far].max(axis=0)
    assert rel[~far].max() > 0.05  # (the jump itself: ~12 % in density)


def test_lagrange_rows_reproduce_polynomials_and_keep_to_their_segment():
    """The interpolation of the table's rows from its nodes: a degree-7 polynomial is reproduced to rounding
    by 8 points at uneven node spacing (closed form), the nodes' values exactly, and a row never uses a node of
    another segment (two polynomials with a jump between them)."""
    t = np.arange(60) * 30.0
    seg = (t >= 900.0).astype(np.int64)  # segment 1 from row 30
    heads, ends = np.array([0, 30]), np.array([29, 59])
    rows = full_setup._node_rows(heads, ends, 3, 6, 1)
    assert {0, 1, 2, 3, 4, 5, 6, 9, 29, 30, 59}.issubset(set(rows.tolist()))

    def poly(x, s):
        u = x / 900.0 - 1.0
        return np.where(s == 0, 1.0 + u - 2 * u**3 + 0.5 * u**7, 40.0 - 3 * u**2 + u**6)

    values = np.ascontiguousarray(np.stack([poly(t[rows], seg[rows]), 2.0 * poly(t[rows], seg[rows])], -1))
    out = np.empty((t.size, 2))
    full_setup._lagrange_rows(t, seg, t[rows], seg[rows], values, 8, out)
    assert np.abs(out[:, 0] - poly(t, seg)).max() < 1e-11 and np.abs(out[:, 1] - 2.0 * poly(t, seg)).max() < 2e-11
    assert np.array_equal(out[rows], values)
