"""Your own controller on the shared engine: a PD law holding 100 m behind the target on the
V-bar, plugged into the station-keeping scenario's plant, navigation and actuator in place of
the built-in LQR. A controller needs ``dt`` (s), ``reset(t0, x0)`` and ``step(t, x_est) -> Command``."""

import numpy as np
from _common import QUICK

from proxops import api


class PDHold:
    """Acceleration command a = -kp (r - r_hold) - kd v in Hill axes (m/s^2)."""

    def __init__(self, dt: float, hold_m=(0.0, -100.0, 0.0), kp: float = 4e-4, kd: float = 4e-2):
        self.dt, self.hold, self.kp, self.kd = dt, np.asarray(hold_m), kp, kd

    def reset(self, t0: float, x0: np.ndarray) -> None:
        pass

    def step(self, t: float, x_est: np.ndarray) -> api.Command:
        return api.Command(u=-self.kp * (x_est[:3] - self.hold) - self.kd * x_est[3:6], kind="acceleration")


loaded = api.load_scenario("station-keeping", ["sim.duration_s=600"] if QUICK else [])
setup = loaded.system.build(loaded.scenario)
setup.controller = PDHold(setup.controller.dt)
result = api.simulate(setup, seed=1)
s = result.summary()
print(f"PD hold: final position error {np.linalg.norm(result.position[-1] - [0, -100, 0]):.2f} m, dv {s['total_dv_mps']:.4f} m/s")
