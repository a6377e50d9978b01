"""A decaying orbit ends the run as a plant stop, not an internal error (full truth, re-entry).

Independent checks: the geodetic height of the recorded states (proxops.environment.earth's WGS-84
conversion applied by the test to the plant's absolute state), the Karman line of the schema, and the
CLI's documented exit code 4 for a run that finished but failed.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from proxops import api
from proxops.core.constants import KARMAN_LINE_KM
from proxops.environment.earth import geodetic_height
from proxops.errors import PlantEnded

SCENARIO = """
name = "decay-130km"
system = "station-keeping"
[sim]
duration_s = 3000.0
seed = 1
[orbit]
altitude_km = 130.0
epoch_utc = "2024-01-01T00:00:00"
[truth]
model = "full"
integrator = "fast"
[truth.target]
mass_kg = 100.0
area_m2 = 10.0
[truth.chaser]
mass_kg = 100.0
area_m2 = 10.0
[initial]
position_m = [0.0, -100.0, 0.0]
velocity_mps = [0.0, 0.0, 0.0]
[navigation]
position_sigma_m = 0.1
velocity_sigma_mps = 0.001
[actuator]
max_per_axis = 0.01
[controller]
type = "lqr"
dt_s = 10.0
hold_position_m = [0.0, -100.0, 0.0]
"""


def _height_km(y) -> float:
    return geodetic_height(*map(float, y[:3])) / 1e3


def test_plant_ends_at_the_karman_line(tmp_path):
    path = tmp_path / "decay.toml"
    path.write_text(SCENARIO)
    loaded = api.load_scenario(str(path), [])
    plant = loaded.system.build(loaded.scenario).plant
    state, t, last = plant.initial_state(), 0.0, None
    try:
        while t < 3000.0:
            last = state
            state = plant.propagate(t, state, None, 20.0)
            t += 20.0
    except PlantEnded as end:
        assert "target re-entered" in end.outcome
        assert _height_km(last) >= KARMAN_LINE_KM  # the state before the step was still above the line
        return
    raise AssertionError(f"no re-entry within {t} s from 130 km (height now {_height_km(state):.1f} km)")


def test_cli_run_ends_with_plant_stop_and_exit_4(tmp_path):
    path = tmp_path / "decay.toml"
    path.write_text(SCENARIO)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    out = subprocess.run([sys.executable, "-m", "proxops.exec.entry", "run", str(path), "--json"], env=env,
                         capture_output=True, text=True)
    assert out.returncode == 4, out.stderr
    assert "Traceback" not in out.stderr and "internal error" not in out.stderr
    summary = json.loads(out.stdout)
    assert summary["stop_reason"] == "plant" and summary["success"] is False
    assert summary["outcome"].startswith("target re-entered")
    assert summary["sim_time_s"] < 3000.0
