"""The passive-safety certificate (issue 26) against the closed-form CW free drift.

From x0 = [0, y0, 0, 0, vy0, 0] the CW solution (Hill, x radial, y along-track) is
x(t) = (2 vy0 / n)(1 - cos nt), y(t) = y0 + (4 vy0 / n) sin nt - 3 vy0 t: the orbit-mean along-track
centre moves by exactly -3 vy0 T per orbit (the periodic terms average to zero over a whole period).
"""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from proxops.constraints.keep_out import KeepOutSphere
from proxops.constraints.passive_safety import certify_free_drift

N = 2 * math.pi / 5800.0  # rad/s
T = 2 * math.pi / N
KOZ = KeepOutSphere(50.0, np.zeros(3))


def _cw(y0, vy0, t, x0=0.0, vx0=0.0):
    """Closed-form in-plane CW motion (Vallado eq. 6-66 with z = 0) from [x0, y0, 0, vx0, vy0, 0]."""
    s, c = np.sin(N * t), np.cos(N * t)
    x = (4 - 3 * c) * x0 + s / N * vx0 + 2 / N * (1 - c) * vy0
    y = 6 * (s - N * t) * x0 + y0 - 2 / N * (1 - c) * vx0 + (4 * s - 3 * N * t) / N * vy0
    vx = 3 * N * s * x0 + c * vx0 + 2 * s * vy0
    vy = 6 * N * (c - 1) * x0 - 2 * s * vx0 + (4 * c - 3) * vy0
    return np.column_stack([x, y, np.zeros_like(t), vx, vy, np.zeros_like(t)])


def _times(window):
    return np.linspace(0.0, window * T, int(window * 720) + 1)


def test_drift_toward_the_target_is_signed_negative_and_its_koz_entry_timed():
    y0, vy0 = 200.0, 1e-3  # the centre moves -3 vy0 T = -17.4 m per orbit: toward the target at +y
    t = _times(10)
    cert = certify_free_drift(t, _cw(y0, vy0, t), KOZ, T, 10)
    # first time the closed-form range reaches 50 m (a root of |r(t)| - 50 bracketed on a fine grid)
    fine = np.linspace(0.0, 10 * T, 200_001)
    rng = np.linalg.norm(_cw(y0, vy0, fine)[:, :3], axis=1) - 50.0
    k = int(np.argmax(rng < 0))
    t_in = brentq(lambda s: float(np.linalg.norm(_cw(y0, vy0, np.array([s]))[0, :3]) - 50.0), fine[k - 1], fine[k])
    assert not cert["safe"] and cert["verdict"].startswith("enters KOZ at")
    # the reported entry is the start of the sampled segment that dips inside: within one sample before the root
    assert t_in - T / 720 - 1e-6 <= cert["first_koz_entry_s"] <= t_in + 1e-6
    assert cert["first_koz_entry_orbits"] == pytest.approx(cert["first_koz_entry_s"] / T)


def test_drift_away_is_positive_and_only_then_indefinite():
    y0, vy0 = 200.0, -1e-3  # centre moves +17.4 m per orbit away from the target
    t = _times(5)
    cert = certify_free_drift(t, _cw(y0, vy0, t), KOZ, T, 5)
    assert cert["safe"] and cert["indefinite"] and cert["verdict"].startswith("indefinite: drift away")
    assert len(cert["along_track_drift_per_orbit_m"]) == 4  # W - 1 centre steps
    assert cert["along_track_drift_per_orbit_m"] == pytest.approx([3e-3 * T] * 4, rel=1e-6)
    # the mirror image (chaser at -y, drifting to -y) is also away from the target: same signed drift
    m = _cw(-y0, -vy0, t)
    cert_m = certify_free_drift(t, m, KOZ, T, 5)
    assert cert_m["along_track_drift_per_orbit_m"] == pytest.approx([3e-3 * T] * 4, rel=1e-6)
    assert cert_m["indefinite"]


def test_window_boundary_names_the_window_and_catches_a_late_entry():
    """A slow inward drift that enters the KOZ in orbit 6: safe over 5 orbits, not over 6 (the verdict
    names its window; a longer window finds the entry)."""
    y0 = 50.0 + 5.5 * 3e-4 * T  # the centre reaches 50 m after 5.5 orbits at -3e-4 T = -1.74 m/orbit
    vy0 = 1e-4
    t5, t7 = _times(5), _times(7)
    c5 = certify_free_drift(t5, _cw(y0, vy0, t5), KOZ, T, 5)
    c7 = certify_free_drift(t7, _cw(y0, vy0, t7), KOZ, T, 7)
    assert c5["safe"] and c5["verdict"] == "safe over 5 orbits" and not c5["indefinite"]
    assert not c7["safe"] and 5.0 < c7["first_koz_entry_orbits"] < 7.0
    assert all(d == pytest.approx(-3e-4 * T, rel=1e-6) for d in c7["along_track_drift_per_orbit_m"])


def test_an_ellipse_around_the_target_is_never_indefinite():
    """The cortex safe orbit (2:1 ellipse about the target, semi-axes 18.75 / 37.5 m, r_KOS 15 m):
    drift-free it is safe over the window, but it encloses the target, so no drift sign makes it
    'indefinite'; a drift of 1 m/orbit leaves it safe over 5 orbits (min range from the closed form)."""
    koz = KeepOutSphere(15.0, np.zeros(3))
    t = _times(5)
    x0, vx0 = 0.0, 0.5 * N * 37.5
    for vy0 in (0.0, -1.0 / (3 * T)):  # 0 and +1 m/orbit along-track
        x = _cw(37.5, vy0, t, x0=x0, vx0=vx0)
        cert = certify_free_drift(t, x, koz, T, 5)
        assert cert["safe"] and not cert["indefinite"] and cert["verdict"] == "safe over 5 orbits"
        fine = _cw(37.5, vy0, np.linspace(0, 5 * T, 400_001), x0=x0, vx0=vx0)
        assert cert["min_range_m"] == pytest.approx(np.linalg.norm(fine[:, :3], axis=1).min(), abs=1e-3)


def test_window_longer_than_the_drift_is_refused():
    t = _times(2)
    with pytest.raises(ValueError, match="window"):
        certify_free_drift(t, _cw(200.0, 0.0, t), KOZ, T, 3)


def _brute_minima(t, x, center):
    """Every segment's minimum distance to ``center`` by the definition (numpy, no skipping): both samples
    and the 19 interior points of the cubic Hermite interpolant."""
    s = np.linspace(0.0, 1.0, 21)[1:-1, None]
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    out = np.empty(len(t) - 1)
    for k in range(len(t) - 1):
        dt = t[k + 1] - t[k]
        p0, p1 = x[k, :3] - center, x[k + 1, :3] - center
        pts = h00 * p0 + h10 * dt * x[k, 3:6] + h01 * p1 + h11 * dt * x[k + 1, 3:6]
        out[k] = min(np.linalg.norm(p0), np.linalg.norm(p1), np.linalg.norm(pts, axis=1).min())
    return out


@pytest.mark.parametrize("seed", range(4))
def test_one_pass_certificate_equals_the_separate_checks_at_the_tangent_radius(seed):
    """free_drift_checks computes the entry, the per-orbit and whole minima in one jitted pass. Against the
    definition (every segment's minimum, numpy) and the separate functions, on CW drifts over 15 orbits
    (noise added, centre off the origin for odd seeds) with the KOZ radius AT the drift's minimum (tangent:
    no segment dips strictly inside, so no entry, while drift_safety's strict 'safe' is False) and one ulp
    above it (the tangent segment enters): same verdicts, the same entry sample, minima per orbit."""
    from proxops.constraints.passive_safety import drift_safety, first_entry_time, free_drift_checks, hermite_min_range

    rng = np.random.default_rng(seed)
    W = 15
    t = np.linspace(0.0, W * T, W * 60 + 1)
    x0 = np.concatenate([rng.uniform(-300, 300, 3), rng.uniform(-0.05, 0.05, 3)])
    x = np.array([_cw_full(x0, tk) for tk in t]) + rng.normal(0.0, 0.01, (t.size, 6))
    center = rng.uniform(-20, 20, 3) if seed % 2 else np.zeros(3)
    seg = _brute_minima(t, x, center)
    k_at = [int(np.argmin(np.abs(t - m * T))) for m in range(W + 1)]
    for radius in (float(seg.min()), float(np.nextafter(seg.min(), np.inf))):
        koz = KeepOutSphere(radius, center)
        cert, checks = free_drift_checks(t, x, koz, T, W)
        assert cert == certify_free_drift(t, x, koz, T, W)
        assert checks["orbit_index"] == k_at
        assert checks["first_entry_s"] == first_entry_time(t, x, center, radius)
        assert checks["safety"] == drift_safety(t, x, koz)
        assert checks["safety"]["min_koz_distance_m"] == pytest.approx(seg.min() - radius, abs=1e-9)
        assert not checks["safety"]["safe"]  # 0 or -1 ulp from the surface: not strictly outside
        per = [seg[a:b].min() for a, b in zip(k_at[:-1], k_at[1:])]
        assert cert["min_range_per_orbit_m"] == pytest.approx(per, rel=1e-12)
        assert cert["min_range_per_orbit_m"] == [hermite_min_range(t[a:b + 1], x[a:b + 1], center)
                                                 for a, b in zip(k_at[:-1], k_at[1:])]
        dips = np.nonzero(seg < radius)[0]
        if radius == seg.min():
            assert dips.size == 0 and cert["safe"] and cert["first_koz_entry_s"] is None
        else:
            assert dips.size and not cert["safe"] and cert["first_koz_entry_s"] == t[dips[0]]
            assert cert["verdict"] == f"enters KOZ at {t[dips[0]] / T:.2f} orbits"


def _cw_full(x0, t):
    """Closed-form CW state at t from x0 (cw_stm is the code under test elsewhere; this is Vallado eq. 6-66)."""
    s, c = math.sin(N * t), math.cos(N * t)
    x, y, z, vx, vy, vz = x0
    return np.array([
        (4 - 3 * c) * x + s / N * vx + 2 / N * (1 - c) * vy,
        6 * (s - N * t) * x + y - 2 / N * (1 - c) * vx + (4 * s - 3 * N * t) / N * vy,
        c * z + s / N * vz,
        3 * N * s * x + c * vx + 2 * s * vy,
        6 * N * (c - 1) * x - 2 * s * vx + (4 * c - 3) * vy,
        -N * s * z + c * vz,
    ])
