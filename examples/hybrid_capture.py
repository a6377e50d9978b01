"""hybrid: hybrid-MPC capture of a tumbling chief; the contact and latch events of the run."""

from _common import QUICK

from proxops import api

overrides = ["sim.duration_s=60"] if QUICK else []
loaded = api.load_scenario("hybrid-capture", overrides)
summary, results = api.run(loaded)
print(f"status {summary['status']}")
result = next(iter(results.values()))
for t, kind, message in result.events[:10]:
    print(f"{t:8.2f} s  {kind:8s} {message}")
