"""los: approach to a target tumbling at 2 deg/s through its rotating line-of-sight corridor."""

from _common import QUICK

from proxops import api

overrides = ["sim.duration_s=120"] if QUICK else []
loaded = api.load_scenario("los-tumble", overrides + ["target.tumble_rate_deg_s=2.0"])
summary, _ = api.run(loaded)
print(f"status {summary['status']}, total dv {summary['total_dv_mps']:.4f} m/s, "
      f"final range {summary['final_range_m']:.2f} m, min range {summary['min_range_m']:.2f} m")
