"""srf: V-bar hopping inside an MPC (radial impulses every half orbit), one closed loop on the
J2 truth with navigation noise and thruster errors; the hop impulses read from the time series."""

import numpy as np
from _common import QUICK  # noqa: F401 (the whole approach is quick)

from proxops import api

overrides: list[str] = []  # the whole approach (about 0.1 s of computing)
loaded = api.load_scenario("srf-vbar", overrides)
summary, results = api.run(loaded)
print(f"status {summary['status']}, total dv {summary['total_dv_mps']:.4f} m/s, final range {summary['final_range_m']:.1f} m")

frame = results["run"].to_frame()
dv = np.linalg.norm(frame[["applied_ux_hill_mps", "applied_uy_hill_mps", "applied_uz_hill_mps"]].to_numpy(), axis=1)
burns = frame.loc[dv > 1e-6, "t_s"]
print(f"{len(burns)} impulses; first at {burns.iloc[0]:.0f} s" if len(burns) else "no impulse")
