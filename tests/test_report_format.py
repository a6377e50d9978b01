"""Numbers for people are rounded to their unit's resolution and carry the unit; machine outputs
(--json, statistics.csv, summary.json) keep full precision. The reach map has a region legend."""

from __future__ import annotations

import copy
import json
import re

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from proxops.analysis.formatting import format_number, format_percent, format_quantity
from proxops.scenarios.loader import unit_of_metric
from proxops.analysis.statistics import describe, format_table4, format_text_table
from proxops.cli import app
from proxops.cli_run import format_summary
from proxops.runner import summary_markdown


@pytest.mark.parametrize("value, key, text", [
    (98.36128, "final_range_m", "98.361 m"),           # m to 1 mm
    (98.3615, "final_range_m", "98.362 m"),            # (98.3615 is 98.36150000000000659 in binary)
    (0.831149, "total_dv_mps", "0.8311 m/s"),          # m/s to 0.1 mm/s
    (0.83115001, "total_dv_mps", "0.8312 m/s"),
    (10882.527364212114, "arrival_time_s", "10882.53 s"),  # s to 10 ms
    (0.8479, "solve_time_ms.median", "0.848 ms"),      # dotted metric: the unit of the part that has one
    (3.3333e-05, "velocity_sigma_mps", "0 m/s"),   # below the resolution (0.1 mm/s): nothing to read, 0
    (5.6e-16, "final_range_m", "0 m"),             # a numerically zero range prints as 0, not 5.6e-16
    (2.4e-42, "chief_rate_final_deg_s", "0 deg/s"),
    (6.041880, "peak_contact_impulse_Ns", "6.0419 N s"),  # impulses to 0.1 mN s
    (0.0, "x_m", "0 m"),
    (5.361e-12, "check_dynamics_residual", "< 1e-06"),  # no unit: a bound, not 12 digits of noise
    (1.0e-7, "hop_distance_weight_per_m2", "1e-07 1/m^2"),
    (0.013507467, "dv_share_along_track", "0.01351"),  # no unit: 4 significant digits
    (12345.678, "steps", "12346"),
    (13, "impulses", "13"),
    (np.int64(13), "impulses", "13"),
    (True, "arrived", "true"),
    (np.bool_(False), "arrived", "false"),
    ("handover", "status", "handover"),
    (float("nan"), "final_range_m", "nan"),
])
def test_values_are_rounded_to_their_unit(value, key, text):
    assert format_quantity(value, key) == text


def test_percentages_and_units():
    assert format_percent(0.95123) == "95.1 %" and format_percent(1.0) == "100.0 %"
    assert format_quantity(0.05, "actuator.missed_probability", significant=True) == "0.05"
    assert format_quantity(0.033333, "navigation.position_sigma_m", significant=True) == "0.03333 m"
    assert unit_of_metric("max_violation.keep_out") == "" and unit_of_metric("disp.initial.position_m[1]") == "m"
    assert format_number(2.5, "deg") == "2.500"


def _stats():
    rng = np.random.default_rng(4)
    rows = {"final_range_m": 100 + rng.normal(0, 0.1, 50), "total_dv_mps": 0.8 + rng.normal(0, 1e-3, 50),
            "solve_time_ms.median": rng.uniform(0.5, 2.0, 50), "impulses": rng.integers(10, 15, 50).astype(float)}
    return pd.DataFrame.from_dict({k: describe(v) for k, v in rows.items()}, orient="index"), rows


def _decimals(cell: str) -> list[int]:
    return [len(m) for m in re.findall(r"\d\.(\d+)", cell)]


def test_table4_rounds_each_metric_to_its_unit():
    stats, rows = _stats()
    md = format_table4(stats)
    lines = {ln.split(" | ")[0].lstrip("| "): ln for ln in md.splitlines()[2:]}
    assert lines["final_range_m"].split(" | ")[1] == "m" and max(_decimals(lines["final_range_m"])) == 3
    assert max(_decimals(lines["total_dv_mps"])) == 4 and max(_decimals(lines["solve_time_ms.median"])) == 3
    # the mean printed is the mean of the data rounded to 1 mm (independent of the table code)
    assert f"| {np.mean(rows['final_range_m']):.3f} |" in lines["final_range_m"]
    text = format_text_table(stats)
    assert "unit" in text.splitlines()[0] and not any(d > 4 for d in _decimals(text))


def test_run_summaries_round_but_json_keeps_full_precision():
    s = {"scenario": "x", "system": "srf", "status": "handover", "final_range_m": 98.36128437, "final_speed_mps": 0.00612,
         "min_range_m": 98.2864, "total_dv_mps": 0.83114, "sim_time_s": 10892.6, "wall_time_s": 2.2,
         "solve_time_ms": {"median": 0.85, "p95": 1.2}, "events": {}, "period_s": 7255.018242808076,
         "abort_return_miss_max_m": 88.12273270647043, "dv_share_along_track": 0.01350746703029225,
         "a_very_long_key_name_m": 1.23456789}
    text = format_summary(s)
    assert "period_s" in text and "7255.02 s" in text and "88.123 m" in text and "0.01351" in text
    assert "7255.018" not in text and not any(d > 5 for d in _decimals(text))  # 0.01351: 4 significant
    md = "\n".join(summary_markdown(s))
    assert "| period_s | 7255.02 s |" in md and "| abort_return_miss_max_m | 88.123 m |" in md
    res = CliRunner().invoke(app, ["run", "station-keeping", "--set", "sim.duration_s=600", "--json"])
    obj = json.loads(res.stdout)
    assert max(_decimals(repr(obj["final_range_m"]))) > 6  # --json: full precision


def test_campaign_report_rounds_tables_and_csv_keeps_full_precision(tmp_path):
    import test_campaign_toy as toy
    from proxops.analysis.campaign import run_campaign
    from proxops.report.campaign import write_report

    data = copy.deepcopy(toy.TOY_SCENARIO)
    res = run_campaign(data, n_runs=6, workers=1, seed=2, out=tmp_path / "c", progress=False)
    write_report(res, figures=False)
    md = (tmp_path / "c" / "report" / "report.md").read_text()
    table_rows = [ln for ln in md.splitlines() if ln.startswith("| ") and not ln.startswith("| metric")]
    assert table_rows and not any(d > 6 for ln in table_rows for d in _decimals(ln))
    csv = pd.read_csv(tmp_path / "c" / "report" / "statistics.csv", index_col="metric")
    stats = res.statistics()
    np.testing.assert_array_equal(csv["mean"].to_numpy(), stats["mean"].to_numpy())  # bit for bit


def test_reach_map_has_a_legend_for_its_four_regions(monkeypatch, tmp_path):
    from proxops.analysis import reach as R
    from proxops.plotting import reach as P

    shown = {}

    def capture(fig, path):
        shown["legend"] = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        shown["title"] = fig.axes[0].get_legend().get_title().get_text()
        import matplotlib.pyplot as plt

        plt.close(fig)
        return path

    monkeypatch.setattr(P, "save", capture)
    g = R.body_grid(n_points=40, y_max_m=200.0)
    res = R.analyse_combo(g, 2.0, 0.1)
    P.combo_map_figure(res, g, tmp_path / "m.png")
    labels = shown["legend"]
    for region, key in (("robust", "robust"), ("stochastic", "stochastic"), ("nominal", "nominal")):
        assert any(lab.startswith(region) and f"{res.pct[key]:.1f} %" in lab for lab in labels), labels
    assert "not certified" in labels and "LOS corridor" in labels and "corridor area" in shown["title"]
    if res.backward is not None:
        assert any(lab.startswith("backward kernel") for lab in labels)
