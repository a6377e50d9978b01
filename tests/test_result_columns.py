"""Saved time series are readable without the code: every column is named from the plant's
state and control layouts with its frame and unit (x_hill_m, vy_hill_mps, cmd_ux_hill_mps, ...),
and the unit, frame and meaning are in the Parquet schema; older results still load."""

import json

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
from typer.testing import CliRunner

from proxops.cli import app
from proxops.sim.result import SimResult

HILL = ["x_hill_m", "y_hill_m", "z_hill_m", "vx_hill_mps", "vy_hill_mps", "vz_hill_mps"]


def test_srf_run_writes_named_unit_tagged_columns(tmp_path):
    out = tmp_path / "vbar"
    done = CliRunner().invoke(app, ["run", "srf-vbar", "--out", str(out), "--no-figures", "--json"])
    assert done.exit_code == 0, done.output
    steps = out / "run" / "steps.parquet"
    schema = pq.read_schema(steps)
    cols = schema.names
    assert cols[:1 + 12] == ["t_s"] + HILL + ["est_" + c for c in HILL]
    # srf commands impulses: the control columns are delta-v in Hill axes, m/s
    assert cols[13:19] == ["cmd_ux_hill_mps", "cmd_uy_hill_mps", "cmd_uz_hill_mps",
                           "applied_ux_hill_mps", "applied_uy_hill_mps", "applied_uz_hill_mps"]
    meta = {n: {k.decode(): v.decode() for k, v in (schema.field(n).metadata or {}).items()} for n in cols}
    assert meta["vy_hill_mps"] == {"unit": "m/s", "frame": "hill", "meaning": "true state: vy"}
    assert meta["applied_uz_hill_mps"]["unit"] == "m/s" and meta["t_s"]["unit"] == "s"
    df = pd.read_parquet(steps)
    # invariant linking the columns to their meaning: the cumulative delta-v is the running sum
    # of the applied impulses' norms
    dv = np.linalg.norm(df[["applied_ux_hill_mps", "applied_uy_hill_mps", "applied_uz_hill_mps"]].to_numpy(), axis=1)
    assert np.isclose(df["dv_cum_mps"].iloc[-1], dv.sum(), rtol=1e-12, atol=1e-12)
    summary = json.loads((out / "summary.json").read_text())
    assert np.isclose(summary["total_dv_mps"], df["dv_cum_mps"].iloc[-1], rtol=1e-12)
    # the range column set is the true relative position
    assert np.isclose(summary["final_range_m"], np.linalg.norm(df[HILL[:3]].to_numpy()[-1]), rtol=1e-12)


def test_results_saved_with_index_columns_still_load(tmp_path):
    """Results written before the columns had names (t, x_true_<i>, ..., dv_cum) load unchanged."""
    n = 4
    rng = np.random.default_rng(3)
    x, u = rng.normal(size=(n, 6)), rng.normal(size=(n, 3))
    old = {"t": np.arange(n, dtype=float)}
    for name, arr in (("x_true", x), ("x_est", x + 1), ("u_cmd", u), ("u_applied", u * 2)):
        old.update({f"{name}_{i}": arr[:, i] for i in range(arr.shape[1])})
    old.update(dv_cum=np.arange(n, dtype=float), status=["ok"] * n, solve_time_s=np.zeros(n), mode=[""] * n)
    pd.DataFrame(old).to_parquet(tmp_path / "steps.parquet", index=False)
    pd.DataFrame({"t": [], "kind": [], "message": []}).to_parquet(tmp_path / "events.parquet", index=False)
    (tmp_path / "meta.json").write_text(json.dumps({"outcome": "completed"}))
    r = SimResult.load(tmp_path)
    assert np.array_equal(r.x_true, x) and np.array_equal(r.x_est, x + 1) and np.array_equal(r.u_applied, u * 2)
    # without a stored layout: a position and a velocity block by the stored slices
    assert list(r.to_frame().columns[:4]) == ["t_s", "position_0_m", "position_1_m", "position_2_m"]


def test_a_result_built_by_hand_round_trips(tmp_path):
    """A SimResult made without the engine (no layouts in its meta, e.g. a cortex reference plan)
    saves named columns and loads back the same arrays."""
    n = 5
    rng = np.random.default_rng(7)
    r = SimResult(t=np.arange(n, dtype=float), x_true=rng.normal(size=(n, 6)), x_est=rng.normal(size=(n, 6)),
                  u_cmd=rng.normal(size=(n, 3)), u_applied=rng.normal(size=(n, 3)), dv_cum=np.arange(n, dtype=float),
                  status=["ok"] * n, solve_time_s=np.zeros(n), mode=[""] * n, meta={"outcome": "ok"})
    r.save(tmp_path)
    back = SimResult.load(tmp_path)
    for key in ("t", "x_true", "x_est", "u_cmd", "u_applied", "dv_cum"):
        assert np.array_equal(getattr(r, key), getattr(back, key)), key
