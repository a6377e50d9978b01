"""``proxops hop-times``: the SRF guidance expert (Silva et al. 2026 Algorithm 1) from the shell.

Mounted by :mod:`proxops.cli` as a command::

    proxops hop-times --approach-deg 90 --hops 5 --gamma 0.5 --start-m 2000 --end-m 100 --json

JSON: ``{"approach_deg", "period_s", "total_s", "sma_m", "hops": [{start_m, end_m, rho, phi_rad,
duration_s, period_fraction}, ...]}``.
"""

from __future__ import annotations

import json
import math
from typing import Annotated, Optional

import typer

from proxops.errors import input_error
from proxops.core.constants import R_EARTH
from proxops.core.cw import mean_motion
from proxops.guidance.hop_times import plan_hops

DEFAULT_SMA_KM = 8100.0  # Silva et al. 2026 Table 2
MAX_HOPS = 50  # as the scenario key approach.hops


def hop_times(
    approach_deg: Annotated[float, typer.Option("--approach-deg", help="Approach angle from the V-bar towards the R-bar, deg (0 = V-bar, 90 = R-bar).")],
    hops: Annotated[int, typer.Option("--hops", help="Number of hops (>= 1).")] = 5,
    gamma: Annotated[float, typer.Option("--gamma", help="Hop aggressiveness: ratio of successive hop lengths, 0 < gamma < 1.")] = 0.5,
    start_m: Annotated[float, typer.Option("--start-m", help="Start distance from the target, m.")] = 2000.0,
    end_m: Annotated[float, typer.Option("--end-m", help="End (reference point) distance from the target, m.")] = 100.0,
    altitude_km: Annotated[Optional[float], typer.Option("--altitude-km", help="Circular target altitude above 6378.137 km.")] = None,
    sma_km: Annotated[Optional[float], typer.Option("--sma-km", help="Target semi-major axis, km (default 8100, Table 2).")] = None,
    vbar_period_fraction: Annotated[float, typer.Option("--vbar-period-fraction", help="V-bar hop duration in orbital periods (eq. 8: 0.5).")] = 0.5,
    as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False,
):
    """Hop distances and times of the SRF guidance expert (Algorithm 1, eqs. 8, 14, 17-25)."""

    if altitude_km is not None and sma_km is not None:
        raise input_error("--altitude-km/--sma-km", f"{altitude_km}/{sma_km}", "give at most one of them", "km")
    sma_m = (R_EARTH + altitude_km * 1e3) if altitude_km is not None else (sma_km if sma_km is not None else DEFAULT_SMA_KM) * 1e3
    if not (math.isfinite(sma_m) and sma_m > R_EARTH):
        raise input_error("semi-major axis", sma_m / 1e3, f"must exceed the Earth radius {R_EARTH / 1e3:.3f}", "km")
    if not (math.isfinite(approach_deg) and -360.0 <= approach_deg <= 360.0):
        raise input_error("--approach-deg", approach_deg, "allowed -360 to 360 (0 V-bar, 90 R-bar)", "deg")
    if not 1 <= hops <= MAX_HOPS:
        raise input_error("--hops", hops, f"must be a whole number from 1 to {MAX_HOPS}")
    if not (0.0 < vbar_period_fraction < 1.0):
        raise input_error("--vbar-period-fraction", vbar_period_fraction, "must satisfy 0 < f < 1")
    plan = plan_hops(math.radians(approach_deg), hops, gamma, start_m, end_m, mean_motion(sma_m),
                     vbar_period_fraction=vbar_period_fraction)
    out = plan.as_dict()
    out["approach_deg"] = approach_deg
    out["sma_m"] = sma_m
    if as_json:
        typer.echo(json.dumps(out))
        return
    lines = [f"approach {approach_deg:g} deg, t_orb = {plan.period_s:.1f} s, {hops} hops, total {out['total_s']:.1f} s "
             f"({out['total_s'] / plan.period_s:.3f} t_orb)",
             f"{'hop':>3} {'start_m':>9} {'end_m':>9} {'rho':>7} {'phi_rad':>8} {'duration_s':>10} {'t/t_orb':>8}"]
    for k, h in enumerate(plan.hops, 1):
        lines.append(f"{k:>3} {h.start_m:9.1f} {h.end_m:9.1f} {h.rho:7.4f} {h.phi_rad:8.5f} {h.duration_s:10.1f} "
                     f"{h.period_fraction:8.5f}")
    typer.echo("\n".join(lines))
