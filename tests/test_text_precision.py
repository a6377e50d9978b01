"""Every number a person reads is rounded to something meaningful: the text outputs of a run of
each system, the propagate table and a campaign's text and report.md hold no over-precise float
(independent criterion, not the formatter's own table: no more than 7 significant digits, no
exponent below e-06, no zero written with more than 3 decimals, no Python dict or list repr)."""

from __future__ import annotations

import re

import pytest
from typer.testing import CliRunner

from proxops.cli import app

NUMBER = re.compile(r"(?<![\w.])-?\d+\.\d+(?:[eE][-+]?\d+)?|(?<![\w.])-?\d+[eE][-+]?\d+")


def over_precise(text: str) -> list[str]:
    bad = []
    for token in NUMBER.findall(text):
        mantissa, _, exponent = token.lower().partition("e")
        digits = mantissa.lstrip("-").replace(".", "").lstrip("0")
        if exponent and int(exponent) < -6:
            bad.append(token)
        elif len(digits) > 7:
            bad.append(token)
        elif float(mantissa) == 0.0 and len(mantissa.split(".")[1]) > 3:
            bad.append(token)
    return bad


def test_the_criterion_catches_the_reported_cases():
    text = "final_range_m 5.6e-16 m, chief 2.4e-42 deg/s, damping_Nms 0.000000 N m s, x 12345.678901 m"
    assert over_precise(text) == ["5.6e-16", "2.4e-42", "0.000000", "12345.678901"]
    assert over_precise("98.361 m, 0.8311 m/s, 1e-06, 3000.00 s, 2026-11-27") == []


RUNS = [
    ["run", "station-keeping", "--set", "sim.duration_s=300"],
    ["run", "srf-vbar"],
    ["run", "los-tumble", "--set", "sim.duration_s=60"],
    ["run", "underactuated-case1", "--set", "sim.duration_s=20"],
    ["run", "hybrid-capture-gentle", "--set", "sim.duration_s=20"],
    ["run", "cortex-reference"],
    ["propagate", "--scenario", "station-keeping", "--duration-s", "600", "--model", "j2"],
]


@pytest.mark.parametrize("argv", RUNS, ids=[" ".join(a[:2]) for a in RUNS])
def test_text_outputs_hold_no_over_precise_number(argv):
    done = CliRunner().invoke(app, argv)
    assert done.exit_code in (0, 4), done.output
    assert over_precise(done.stdout) == [], done.stdout
    assert not re.search(r"\{'|\['", done.stdout), done.stdout  # no Python dict/list repr


def test_campaign_text_and_report_hold_no_over_precise_number(tmp_path):
    out = tmp_path / "mc"
    done = CliRunner().invoke(app, ["mc", "station-keeping-mc", "--runs", "4", "--workers", "1", "--out", str(out),
                                    "--report", "--set", "sim.duration_s=300"])
    assert done.exit_code == 0, done.output
    assert over_precise(done.stdout) == [], done.stdout
    report = (out / "report" / "report.md").read_text()
    assert over_precise(report) == [], [ln for ln in report.splitlines() if over_precise(ln)]
