"""Station keeping about a hold point with LQR or PD on continuous thrust.

The smallest complete system: it exercises the scenario schema, truth, navigation,
actuator model and engine; the Python API examples and the campaign tests use it.
"""

from __future__ import annotations

import numpy as np

from proxops.control.station_keeping import LqrStationKeeping, PdStationKeeping
from proxops.core.cw import mean_motion
from proxops.scenarios.registry import register_system
from proxops.sim.engine import Setup
from proxops.systems.base import SystemBase
from proxops.systems.common import navigation_model, translational_plant
from proxops.systems.schema._build_free import actuator_model, initial_hill_state
from proxops.systems.schema.station_keeping import StationKeepingScenario


@register_system("station-keeping")
class StationKeepingSystem(SystemBase):
    Scenario = StationKeepingScenario

    def build(self, sc: StationKeepingScenario) -> Setup:
        n = mean_motion(sc.orbit.sma_m)
        c = sc.controller
        if c.type == "lqr":
            ctrl = LqrStationKeeping(n, c.dt_s, c.hold_position_m, c.q_pos, c.q_vel, c.r)
        else:
            ctrl = PdStationKeeping(n, c.dt_s, c.hold_position_m, c.kp, c.kd)
        plant = translational_plant(sc.orbit, sc.truth, initial_hill_state(sc.initial))
        actuator = actuator_model(sc.actuator)
        return Setup(plant=plant, controller=ctrl, duration_s=sc.sim.duration_s,
                     navigation=navigation_model(sc.navigation, orbit=sc.orbit, control_dt_s=ctrl.dt,
                                                 system="station-keeping", actuator=actuator),
                     actuator=actuator,
                     check_substeps=sc.sim.check_substeps)

    def summarize(self, sc: StationKeepingScenario, result) -> dict:
        err = result.position[-1] - np.asarray(sc.controller.hold_position_m)
        return {"hold_error_m": float(np.linalg.norm(err))}
