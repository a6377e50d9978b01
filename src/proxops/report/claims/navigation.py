"""The navigation table of ``proxops reproduce``: every ``*-ekf`` built-in run beside its
base scenario (the same name without ``-ekf``: noise on the truth, or exact states), same seed, so a
new ``-ekf`` scenario appears without code changes. Columns: success, Δv, terminal error and, when
the summary has them, ``nav_nees_mean`` / ``att_nees_mean`` and the mean navigation errors. A
``*-mc-ekf`` built-in is run once (its ``sim.seed``), not as a campaign."""

from __future__ import annotations

from proxops.report.claims.common import Context, run
from proxops.scenarios.catalog import builtin_names
from proxops.scenarios.loader import load_scenario


TERMINAL_KEYS = ("terminal_position_error_m", "final_position_error_m", "arrival_error_m", "final_tracking_error_m",
                 "final_range_m")  # first present: the row names the one it used
EXTRA_KEYS = ("nav_nees_mean", "att_nees_mean", "nav_position_error_m", "nav_velocity_error_mps")


def navigation_pairs() -> list[tuple[str, str]]:
    """``[(ekf scenario, base scenario)]`` of the built-ins, sorted."""

    names = set(builtin_names())
    return [(n, n[: -len("-ekf")]) for n in sorted(names) if n.endswith("-ekf") and n[: -len("-ekf")] in names]


def _scalar(v):
    if isinstance(v, dict):  # statistics dicts: their mean / median
        for k in ("mean", "median", "rms"):
            if isinstance(v.get(k), (int, float)):
                return float(v[k])
        return None
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def _cells(name: str, s: dict) -> dict:
    loaded = load_scenario(name)
    key = next((k for k in TERMINAL_KEYS if _scalar(s.get(k)) is not None), None)
    status = str(s.get("status", ""))
    ok = bool(loaded.system.success(loaded.scenario, s))
    out = {"status": status, "success": ok, "dv_mps": _scalar(s.get("total_dv_mps")),
           "terminal_error_m": _scalar(s.get(key)) if key else None, "terminal_key": key}
    for k in EXTRA_KEYS:
        if k in s:
            out[k] = _scalar(s[k])
    return out


def navigation_table(ctx: Context) -> list[dict]:
    """One row per ``(ekf, base)`` pair. ``--quick`` lists the pairs without running them (reduced: the
    filter runs cost minutes each)."""
    rows = []
    for ekf, base in navigation_pairs():
        if ctx.quick:
            rows.append({"scenario": ekf, "base_scenario": base, "ekf": {}, "base": {},
                         "reduced": "not run in --quick (full run only)"})
            continue
        e, b = run(ekf), run(base)
        rows.append({"scenario": ekf, "base_scenario": base, "ekf": _cells(ekf, e), "base": _cells(base, b), "reduced": ""})
    return rows
