"""A Monte Carlo campaign with a dispersion of your own: the station-keeping hold with a 5 m
(1 sigma) initial position error, statistics with pandas."""

import tempfile

from _common import QUICK

from proxops import api

runs = 4 if QUICK else 50
overrides = ["sim.duration_s=600", 'dispersions."initial.position_m"={sigma = 5.0}']
with tempfile.TemporaryDirectory() as out:
    campaign = api.run_campaign("station-keeping-mc", n_runs=runs, workers=1, out=out, overrides=overrides,
                                progress=False)
    table = campaign.table
    print(f"{len(table)} runs, {int(table['success'].sum())} succeeded")
    print(table["metric.total_dv_mps"].describe()[["mean", "std", "min", "max"]].to_string())
