"""The campaign report opens in a real browser: Debian's headless Chromium (driven through its
chromedriver by selenium) loads report.html from disk with the network unused, logs no console
error, shows the headline (success rate and its Wilson interval, recomputed here with scipy from
the campaign's own run table) and loads every figure. A screenshot is saved beside the report.

`make test` installs the chromium and chromium-driver Debian packages before the suite."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest
from scipy.stats import binomtest
from typer.testing import CliRunner

from proxops.cli import app

CHROMIUM, DRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("campaign") / "vbar-mc"
    done = CliRunner().invoke(app, ["mc", "srf-vbar-mc", "--runs", "20", "--workers", "1", "--out", str(out), "--report"])
    assert done.exit_code == 0, done.output
    return out


def _browser():
    if not (Path(CHROMIUM).exists() and Path(DRIVER).exists()):
        pytest.fail("Debian's chromium and chromium-driver are needed: `make test` installs them "
                    "(apt-get install chromium chromium-driver)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", "--window-size=1300,1600"):
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(executable_path=DRIVER), options=opts)


def test_html_report_loads_in_chromium_with_its_headline_and_figures(report):
    page = report / "report" / "report.html"
    assert page.is_file()
    runs = pd.concat(pd.read_parquet(p) for p in sorted((report / "runs").glob("*.parquet")))
    n, k = len(runs), int(runs["success"].astype(bool).sum())
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    figures = sorted(p.name for p in (report / "report").glob("*.png"))
    assert figures, "the report draws figures"
    driver = _browser()
    try:
        driver.get(page.as_uri())
        text = driver.find_element("tag name", "body").text
        severe = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        images = driver.execute_script(
            "return Array.from(document.images).map(i => [i.alt, i.complete && i.naturalWidth > 0, i.src.slice(0, 22)])")
        external = driver.execute_script(
            "return performance.getEntriesByType('resource').map(r => r.name).filter(n => !n.startsWith('data:'))")
        driver.save_screenshot(str(report / "report" / "report-screenshot.png"))
    finally:
        driver.quit()
    assert severe == []
    assert external == []  # self-contained: nothing fetched
    assert "success rate" in text and f"{100.0 * k / n:.1f} %" in text
    assert f"95 % interval [{100 * ci.low:.1f} %, {100 * ci.high:.1f} %]" in text
    assert f"{k} of {n} runs" in text
    assert len(images) == len(figures) and all(ok for _, ok, _ in images), images
    assert all(src == "data:image/png;base64," for _, _, src in images)
    assert (report / "report" / "report-screenshot.png").stat().st_size > 10_000
    keep = Path(__file__).resolve().parents[1] / "out" / "browser"
    keep.mkdir(parents=True, exist_ok=True)
    shutil.copy(report / "report" / "report-screenshot.png", keep / "report-screenshot.png")  # for a person to look at


def test_run_report_loads_in_chromium(tmp_path):
    """`proxops run srf-vbar --out DIR --report`: DIR/report.html in Chromium shows the run's outcome and
    Δv as summary.json has them and loads every figure of the folder."""
    import json

    out = tmp_path / "vbar"
    done = CliRunner().invoke(app, ["run", "srf-vbar", "--out", str(out), "--report", "--json"])
    assert done.exit_code == 0, done.output
    summary = json.loads((out / "summary.json").read_text())
    figures = sorted(p.name for p in out.glob("*.png"))
    driver = _browser()
    try:
        driver.get((out / "report.html").as_uri())
        text = driver.find_element("tag name", "body").text
        severe = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        images = driver.execute_script("return Array.from(document.images).map(i => i.complete && i.naturalWidth > 0)")
    finally:
        driver.quit()
    assert severe == [] and figures and len(images) == len(figures) and all(images)
    assert summary["status"] in text and f"{summary['total_dv_mps']:.4f} m/s" in text
