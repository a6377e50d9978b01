"""The los Table 3 sweep (Iskender 2026 §10.6): tumble rate x a_max grid in
hard and soft constraint modes, through the campaign engine or a plain loop.

``python -m proxops.analysis.los_sweep sweep [--workers N] [--out DIR] [--no-campaign]``
runs it and prints Table 3 in the paper's layout (formatting: :func:`proxops.systems.los.sweep_table`).
"""

from __future__ import annotations

from pathlib import Path

from proxops.systems.los import (SWEEP_METRICS, SWEEP_A_MAX_MPS2, SWEEP_RATES_DEG_S, build_setup, summarize_result,
                                 sweep_frame, sweep_table as _format_table)
from proxops.scenarios.loader import load_scenario
from proxops.sim.engine import simulate
from proxops.analysis.campaign import run_campaign, load_campaign


def run_sweep(scenario: str = "los-sweep", workers: int | None = 1, out=None, use_campaign: bool = True,
              overrides=(), progress: bool = False):
    """Run the Table 3 sweep; returns a DataFrame with one row per (w_t, a_max, mode).

    With ``use_campaign`` (default) the runs go through the campaign engine
    (:func:`proxops.analysis.campaign.run_campaign`, grid dispersions of los-sweep.toml;
    ``out`` keeps them on disk, ``workers`` > 1 runs in parallel); otherwise a plain loop
    over the same grid (no dependency on the campaign engine)."""
    import pandas as pd

    if use_campaign:
        res = run_campaign(scenario, workers=workers, out=out, overrides=list(overrides), progress=progress)
        return sweep_frame(res.table)

    base = load_scenario(scenario, list(overrides)).scenario
    rows = []
    for mode in ("hard", "soft"):
        for w in SWEEP_RATES_DEG_S:
            for a in SWEEP_A_MAX_MPS2:
                sc = base.model_copy(deep=True)
                sc.target.tumble_rate_deg_s = w
                sc.chaser.a_max_mps2 = a
                sc.mpc.constraint_mode = mode
                result = simulate(build_setup(sc), seed=sc.sim.seed)
                summ = summarize_result(sc, result)
                rows.append({"tumble_rate_deg_s": w, "a_max_mps2": a, "mode": mode,
                             **{k: summ.get(k, result.summary().get(k)) for k in SWEEP_METRICS if k != "total_dv_mps"},
                             "total_dv_mps": float(result.dv_cum[-1])})
    return pd.DataFrame(rows)



def sweep_table(source) -> str:
    """Table 3 (Markdown) from a sweep DataFrame, campaign rows or a campaign folder."""
    import pandas as pd

    if not isinstance(source, pd.DataFrame):  # a campaign folder

        source = sweep_frame(load_campaign(Path(source)).table)
    return _format_table(source)


def main(argv=None) -> None:
    """``python -m proxops.analysis.los_sweep sweep [--workers N] [--out DIR] [--no-campaign]``:
    run the Table 3 sweep and print it in the paper's layout."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m proxops.analysis.los_sweep")
    parser.add_argument("command", choices=["sweep"])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", default=None)
    parser.add_argument("--no-campaign", action="store_true", help="plain loop instead of the campaign engine")
    parser.add_argument("--set", action="append", default=[], help="scenario override key=value")
    args = parser.parse_args(argv)
    df = run_sweep(workers=args.workers, out=args.out, use_campaign=not args.no_campaign, overrides=args.set,
                   progress=True)
    print(sweep_table(df))


if __name__ == "__main__":
    main()
