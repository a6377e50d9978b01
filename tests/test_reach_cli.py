"""`proxops reach` command group: JSON layout, files, bad input (exit code 2)."""

from __future__ import annotations

import json

import numpy as np
from typer.testing import CliRunner

from proxops.analysis import reach as R
from proxops.cli_reach import reach_app

runner = CliRunner()


def test_table_json_layout_and_paper_cells():
    res = runner.invoke(reach_app, ["table", "--grid", "300", "--no-backward", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    combos = out["combinations"]
    assert len(combos) == 20
    keys = {"omega_deg_s", "a_max_mps2", "nominal_pct", "stochastic_pct", "robust_pct", "backward_pct",
            "hierarchy_violations"}
    assert keys.issubset(combos[0])
    table = np.array([c["nominal_pct"] for c in combos]).reshape(5, 4)
    np.testing.assert_allclose(table, R.PAPER_TABLE2_PCT, atol=0.2)  # Table 2
    assert out["hierarchy_violations_total"] == 0


def test_table_with_backward_writes_figures(tmp_path):
    res = runner.invoke(reach_app, ["table", "--grid", "40", "--out", str(tmp_path), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert all(c["backward_pct"] is not None for c in out["combinations"])
    for name in ("fig1_hierarchy.png", "scaling.png", "double_integrator.png", "table.json"):
        assert (tmp_path / name).stat().st_size > 0


def test_map_command(tmp_path):
    res = runner.invoke(reach_app, ["map", "--omega-deg", "2", "--amax", "0.1", "--out", str(tmp_path), "--grid", "60",
                                    "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["r_sync_m"] == round(2 * 0.1 / np.radians(2) ** 2, 3)  # eq. (14)
    assert (tmp_path / "reach_w2_a0.1.png").exists()


def test_bad_inputs_exit_2(tmp_path):
    for args in (["table", "--grid", "2"], ["map", "--omega-deg", "0", "--amax", "0.1", "--out", str(tmp_path)],
                 ["map", "--omega-deg", "2", "--amax", "-1", "--out", str(tmp_path)],
                 ["table", "--backward-start", "sideways"], ["mc", "--out", str(tmp_path), "--workers", "0"]):
        res = runner.invoke(reach_app, args)
        assert res.exit_code == 2, (args, res.output)
        assert "error:" in res.output


def test_mc_command_small(tmp_path):
    """4 ICs x 2 combinations, 30 s: the campaign, maps, figures and summary JSON; every number of
    the certification check equal to a direct recomputation from the folder's outcomes (each map
    on its own, without the field cache the command shares between combinations)."""
    from proxops.analysis import feasibility_maps as F

    res = runner.invoke(reach_app, ["mc", "--out", str(tmp_path), "--workers", "1", "--duration-s", "30",
                                    "--n-y", "2", "--n-x", "3", "--omega-deg", "2", "--omega-deg", "1", "--amax",
                                    "0.1", "--grid", "40", "--no-progress", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["runs"] == 12 and out["new_runs"] == 12 and out["errors"] == 0
    assert len(out["combinations"]) == 2
    for name in ("fig2_mc_sweep.png", "fig3_overlay.png", "mc_summary.json"):
        assert (tmp_path / name).exists()
    outcomes = F.read_outcomes(tmp_path)
    for row in out["combinations"]:
        F._GEOMETRY_CACHE.clear()
        g = R.body_grid(n_points=40)
        combo = R.analyse_combo(g, row["omega_deg_s"], row["a_max_mps2"], backward=False)
        fmap = F.feasibility_map(outcomes, g, row["omega_deg_s"], row["a_max_mps2"])
        sites = np.column_stack([fmap.sites, np.zeros(len(fmap.sites))])
        sites_nom = R.certified_mask(R.LosCorridor(), sites, np.radians(row["omega_deg_s"]), row["a_max_mps2"])
        expected = {"omega_deg_s": row["omega_deg_s"], "a_max_mps2": row["a_max_mps2"],
                    "nominal_pct": combo.pct["nominal"], **F.certification_check(fmap, g, combo.nominal, sites_nom)}
        assert row == expected
    # the sweep's totals (analysis.feasibility_maps.aggregate_sweep) are the sums over the rows
    for key in ("nominal_grid_points", "nominal_grid_points_in_ic_hull", "nominal_ics"):
        total = sum(r[key] for r in out["combinations"])
        bad = sum(r[f"{key}_mc_infeasible"] for r in out["combinations"])
        assert out[key.replace("nominal_", "nominal_certified_")] == total
        assert out[key.replace("nominal_", "nominal_certified_") + "_mc_infeasible"] == bad


def test_mc_paper_axes_known_before_the_analysis_import():
    """proxops.exec.entry sizes the pool it starts early for `reach mc` from exec.prestart's own copy of
    the paper's axes (before importing analysis.reach)."""
    from proxops.exec import prestart

    assert prestart.REACH_OMEGAS_DEG_S == R.PAPER_OMEGAS_DEG_S
    assert prestart.REACH_A_MAX_MPS2 == R.PAPER_A_MAX_MPS2
