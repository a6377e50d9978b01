"""The whole wall of ``proxops mc`` (issue 32 item 3): what the parent and the pool's fork server load,
asserted on the modules they hold (state, not time), and the rows of a campaign started the way the
command starts it (fork server warmed by the scenario's build) equal to the same runs made alone.

References: the modules a process holds (``sys.modules``); each run repeated alone in this process
with :func:`proxops.analysis.runs.execute` from its seed and dispersed values (bit for bit).
"""

from __future__ import annotations

import copy
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

SRC_DIR = Path(__file__).parent.parent / "src"


def _python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(SRC_DIR)})


def test_fork_server_and_its_workers_hold_numpy_f2py_unexecuted(tmp_path):
    """The fork server defers numpy.f2py / numpy.testing before its preload modules import scipy (which
    reads every numpy attribute): a worker forked from it holds scipy, and numpy.f2py only as the
    deferred module (its code, numpy.f2py.f2py2e, never ran); numpy.testing still works there."""
    code = (
        "import sys\n"
        "from proxops.exec.backends import START_METHOD, _new_pool\n"
        "def probe():\n"
        "    import sys, numpy\n"
        "    state = ('scipy' in sys.modules, 'numpy.f2py.f2py2e' in sys.modules,\n"
        "             'numpy.testing._private.utils' in sys.modules)\n"
        "    numpy.testing.assert_equal(1, 1)  # deferred, not broken\n"
        "    return state\n"
        "if __name__ == '__main__':\n"
        "    if START_METHOD != 'forkserver':\n"
        "        print('skip'); sys.exit(0)\n"
        "    pool = _new_pool(1, ('proxops.analysis.campaign_worker', 'proxops.systems.srf'))\n"
        "    print(pool.submit(probe).result())\n"
        "    pool.shutdown()\n"
    )
    script = tmp_path / "probe.py"  # a file: the workers import the probe from the main module's path
    script.write_text(code)
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(SRC_DIR)})
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout.strip().splitlines()[-1]
    if out == "skip":
        return
    # scipy was imported by the server's preload, f2py's and numpy.testing's code never ran
    assert out == "(True, False, False)", out


def test_campaign_summary_without_a_filter_loads_no_numba():
    """The parent of a campaign never loads numba (the workers run): the summary and the printed table
    of a campaign without a navigation filter leave it out (navigation_consistency returned None before
    importing the navigation package, whose __init__ loads numba); with NEES columns the consistency is
    still there."""
    code = (
        "import json, sys\n"
        "import pandas as pd\n"
        "from proxops.analysis.campaign import CampaignResult\n"
        "from proxops.cli_campaign import format_campaign\n"
        "t = pd.DataFrame({'run_id': [0, 1, 2], 'seed': [5, 6, 7], 'grid_index': [0, 0, 0],\n"
        "                  'outcome': ['success'] * 3, 'success': [True] * 3, 'status': ['docked'] * 3,\n"
        "                  'error': [''] * 3, 'metric.total_dv_mps': [1.0, 2.0, 3.0]})\n"
        "r = CampaignResult(table=t, manifest={'scenario': 'x', 'n_runs': 3, 'seed': 1})\n"
        "s = r.summary()\n"
        "text = format_campaign(s, r.headline_statistics())\n"
        "plain = ('numba' in sys.modules, 'navigation_consistency' in s, s['statistics']['total_dv_mps']['median'])\n"
        "t2 = t.assign(**{'metric.nav_nees_mean': [6.0, 6.0, 6.0], 'metric.nav_nees_dim': [6, 6, 6],\n"
        "                 'metric.nav_nees_epochs': [10, 10, 10], 'metric.nav_nees_in_band': [1.0, 1.0, 1.0]})\n"
        "s2 = CampaignResult(table=t2, manifest={'scenario': 'x', 'n_runs': 3, 'seed': 1}).summary()\n"
        "print(json.dumps([plain, s2['navigation_consistency']['nees']]))\n"
    )
    proc = _python(code)
    assert proc.returncode == 0, proc.stderr
    plain, nees = json.loads(proc.stdout.strip().splitlines()[-1])
    assert plain == [False, False, 2.0]  # median of 1, 2, 3
    # mean 6 of 3 runs of dimension 6: chi2(18)/3 two-sided 95 % band [8.23, 31.53] / 3 (tables)
    assert nees["runs"] == 3 and nees["dim"] == 6 and nees["mean"] == 6.0
    assert math.isclose(nees["band"][0], 8.2307 / 3, rel_tol=1e-4) and math.isclose(nees["band"][1], 31.5264 / 3,
                                                                                     rel_tol=1e-4)
    assert nees["consistent"] is True


def test_cli_campaign_rows_equal_the_same_runs_made_alone(tmp_path):
    """`proxops mc srf-vbar-mc --runs 3 --workers 2` (pool prestarted, fork server warmed by the build,
    runs batched) against each run repeated alone in this process from its seed and dispersed values:
    every outcome and metric equal bit for bit (timings aside)."""
    from proxops.analysis.campaign import is_timing_column, load_campaign
    from proxops.analysis.campaign_worker import flatten_summary
    from proxops.analysis.runs import execute
    from proxops.scenarios.dispersions import apply_values
    from proxops.scenarios.loader import validate_scenario

    out = tmp_path / "mc"
    proc = subprocess.run([sys.executable, "-m", "proxops.exec.entry", "mc", "srf-vbar-mc", "--runs", "3", "--workers",
                           "2", "--out", str(out), "--no-progress", "--json"], capture_output=True, text=True,
                          timeout=300, env={**os.environ, "PYTHONPATH": str(SRC_DIR)})
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["succeeded"] == 3
    campaign = load_campaign(out)
    data = {k: v for k, v in campaign.manifest["scenario_data"].items() if k != "dispersions"}
    nominal = validate_scenario(copy.deepcopy(data)).scenario
    for row in campaign.table.to_dict("records"):
        values = {c[len("disp."):]: v for c, v in row.items() if c.startswith("disp.")}
        loaded = validate_scenario(apply_values(copy.deepcopy(data), values, nominal))
        summary, results = execute(loaded, seed=int(row["seed"]))
        alone = flatten_summary(summary)
        metrics = {c: v for c, v in row.items() if c.startswith("metric.") and not is_timing_column(c)}
        assert metrics, row
        for col, val in metrics.items():
            if col not in alone:  # an event counter another run of the campaign had: 0 here (storage._tidy)
                assert col.startswith("metric.events.") and val == 0, (row["run_id"], col, val)
                continue
            want = alone[col]
            same = (val == want) or (isinstance(val, float) and np.isnan(val) and isinstance(want, float)
                                      and np.isnan(want))
            assert same, (row["run_id"], col, val, want)
        assert row["success"] == summary["success"] and row["status"] == str(summary["status"])
