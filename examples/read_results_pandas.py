"""A saved run read back with pandas and pyarrow: every column is named with its frame and unit,
and the Parquet schema says what each one is."""

import tempfile
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
from _common import QUICK

from proxops import api

loaded = api.load_scenario("station-keeping", ["sim.duration_s=600"] if QUICK else [])
setup = loaded.system.build(loaded.scenario)
result = api.simulate(setup, seed=1)
with tempfile.TemporaryDirectory() as d:
    result.save(d)
    frame = pd.read_parquet(Path(d) / "steps.parquet")
    schema = pq.read_schema(Path(d) / "steps.parquet")
    print(list(frame.columns[:7]))
    for name in ("x_hill_m", "vy_hill_mps", "cmd_ux_hill_mps2"):
        meta = {k.decode(): v.decode() for k, v in schema.field(name).metadata.items()}
        print(f"{name}: {meta}")
    error = (frame[["est_x_hill_m", "est_y_hill_m", "est_z_hill_m"]].to_numpy()
             - frame[["x_hill_m", "y_hill_m", "z_hill_m"]].to_numpy())
    print(f"navigation error (RMS per axis, m): {(error ** 2).mean(axis=0) ** 0.5}")
