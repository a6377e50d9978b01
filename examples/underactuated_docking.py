"""underactuated: NMPC docking of a planar CubeSat with one body-fixed thruster and a reaction
wheel, with the averaged value function of the paper's eq. 14."""

from _common import QUICK

from proxops import api

overrides = ["sim.duration_s=20"] if QUICK else []
loaded = api.load_scenario("underactuated-case1", overrides)
summary, results = api.run(loaded)
frame = next(iter(results.values())).to_frame()
print(f"status {summary['status']}, final range {summary['final_range_m']:.3f} m")
print(frame[["t_s", "x_hill_m", "y_hill_m", "theta_rad", "cmd_thrust_N"]].tail(3).to_string(index=False))
