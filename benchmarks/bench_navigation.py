"""Relative-navigation EKF cost (issue 17): time per propagation step (exact CW STM from the
per-step cache, covariance prediction) and per measurement update (range-bearing and pose;
Jacobian, gate, Joseph update), goal < 20 us each; and the wall-time slowdown of a small
station-keeping campaign, of one srf-vbar run and of one cortex run (cortex-nominal against
cortex-nominal-ekf, CW truth: the engine loop, not the truth integrator, is compared) on the filter
against noise on the truth; the update with the collapse test on (re-initialisation armed).

    python benchmarks/bench_navigation.py [N_CALLS] [N_RUNS]

Best of 5 repeats; the machine is shared, so the load average is printed with the numbers.
"""

from __future__ import annotations

import os
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

GOAL_US = 20.0


def _per_call_us(fn, n: int, repeats: int = 5) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for i in range(n):
            fn(i)
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def filter_costs(n_calls: int) -> dict[str, float]:
    from proxops.core.cw import mean_motion
    from proxops.navigation.ekf import RelativeEKF, SensorModel

    n = mean_motion(6378137.0 + 500e3)
    out = {}
    for kind in ("range-bearing", "pose"):
        sensor = SensorModel(kind=kind, range_sigma_m=0.5, angle_sigma_rad=1e-3)
        ekf = RelativeEKF(n, sensor, np.diag([1.0] * 3 + [1e-4] * 3), q_m2_s3=1e-9)
        x = np.array([30.0, -400.0, 10.0, 0.0, 0.0, 0.0])
        ekf.reset(0.0, x)
        dt = 10.0
        ekf.matrices(dt)  # the cache is filled once per run (one step length)

        def prop(i):
            ekf.propagate(ekf.t + dt)

        out["propagate_us"] = _per_call_us(prop, n_calls)
        z = sensor.h(ekf.x)
        p_keep = ekf.P.copy()

        def upd(i):
            ekf.P = p_keep
            ekf.update(0.0, z)

        out[f"update_{kind}_us"] = _per_call_us(upd, n_calls)
    armed = RelativeEKF(n, SensorModel(kind="pose", range_sigma_m=0.5), np.diag([1.0] * 3 + [1e-4] * 3), q_m2_s3=1e-9,
                        reinit_after_rejections=5)
    armed.reset(0.0, np.array([30.0, -400.0, 10.0, 0.0, 0.0, 0.0]))
    z, p_keep = armed.sensor.h(armed.x), armed.P.copy()

    def upd_armed(i):
        armed.P = p_keep
        armed.update(0.0, z)

    out["update_pose_reinit_armed_us"] = _per_call_us(upd_armed, n_calls)
    return out


def campaign_slowdown(n_runs: int) -> tuple[float, float]:
    from proxops.analysis.campaign import run_campaign

    times = []
    for extra in ([], ["navigation.model=ekf"]):  # warm-up: JIT compilation and imports, not timed
        run_campaign("station-keeping-mc", n_runs=1, seed=1, workers=1, progress=False,
                     overrides=["sim.duration_s=200", *extra])
    for extra in ([], ["navigation.model=ekf"]):
        t0 = time.perf_counter()
        run_campaign("station-keeping-mc", n_runs=n_runs, seed=1, workers=1, progress=False,
                     overrides=["sim.duration_s=2000", *extra])
        times.append(time.perf_counter() - t0)
    return times[0], times[1]


def srf_run_slowdown(repeats: int = 3) -> tuple[float, float]:
    """Best-of wall time of one srf-vbar run with noise on the truth and with srf-vbar-ekf."""
    from proxops.scenarios.loader import load_scenario
    from proxops.sim.engine import simulate

    out = []
    for name in ("srf-vbar", "srf-vbar-ekf"):
        ld = load_scenario(name)
        best = float("inf")
        for _ in range(repeats):
            setup = ld.system.build(ld.scenario)
            t0 = time.perf_counter()
            simulate(setup, seed=1)
            best = min(best, time.perf_counter() - t0)
        out.append(best)
    return out[0], out[1]


def cortex_run_slowdown(repeats: int = 3) -> tuple[float, float, int]:
    """Best-of wall time of one cortex closed loop (CW truth, no eclipse) on noise-free navigation
    (cortex-nominal) and on the filter (cortex-nominal-ekf); and the steps of the ekf run."""
    from proxops.scenarios.loader import load_scenario
    from proxops.sim.engine import simulate

    out, steps = [], 0
    for name in ("cortex-nominal", "cortex-nominal-ekf"):
        ld = load_scenario(name, ["truth.model=cw", "eclipse.model=none"])
        best = float("inf")
        for _ in range(repeats):
            setup = ld.system.build(ld.scenario)
            t0 = time.perf_counter()
            res = simulate(setup, seed=1)
            best = min(best, time.perf_counter() - t0)
            steps = len(res.t) - 1
        out.append(best)
    return out[0], out[1], steps


def main(n_calls: int = 20000, n_runs: int = 8) -> None:
    print(f"load average {os.getloadavg()[0]:.2f}")
    for key, us in filter_costs(n_calls).items():
        print(f"{key:28s} {us:8.2f} us   (goal < {GOAL_US:g} us: {'met' if us < GOAL_US else 'NOT met'})")
    t_noise, t_ekf = campaign_slowdown(n_runs)
    print(f"station-keeping-mc, {n_runs} runs x 2000 s, 1 worker: noise {t_noise:.2f} s, ekf {t_ekf:.2f} s, "
          f"slowdown x{t_ekf / t_noise:.2f}")
    t_noise, t_ekf = srf_run_slowdown()
    print(f"one srf run (1082 steps): srf-vbar {t_noise:.3f} s, srf-vbar-ekf {t_ekf:.3f} s, slowdown x{t_ekf / t_noise:.2f}"
          f" ({(t_ekf - t_noise) / 1082 * 1e6:.0f} us per navigation tick, sensor draw included)")
    t_noise, t_ekf, steps = cortex_run_slowdown()
    print(f"one cortex run ({steps} steps, CW truth): cortex-nominal {t_noise:.3f} s, cortex-nominal-ekf {t_ekf:.3f} s, "
          f"slowdown x{t_ekf / t_noise:.2f} (the two runs fly different trajectories: CP_g solves differ)")


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:3]]
    main(*args)
