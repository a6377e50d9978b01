"""cortex: one convex reference (fly-around outside the keep-out sphere, then the final approach
in the cone) on the fixed docking axis of the paper's section 5.1.2."""

from _common import QUICK  # noqa: F401 (the whole approach is quick)

from proxops import api

loaded = api.load_scenario("cortex-reference")
summary, _ = api.run(loaded)
keys = [k for k in ("status", "total_dv_mps", "time_of_flight_s") if k in summary]
print(", ".join(f"{k} {summary[k]}" for k in keys))
