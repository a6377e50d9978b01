"""``proxops reproduce``: every headline claim of each paper beside ours, with a verdict.

Three tables: the paper claims (``claim | paper value (where) | ours | verdict``, verdicts and their
rules in :mod:`proxops.report.claims.common`), our own goals (wall times, our Monte Carlo success
rates: met / not met, never a paper verdict) and the navigation table (each ``*-ekf`` built-in beside
its base scenario). The claims live in ``proxops/report/claims/<system>.py``.

``quick=True`` runs reduced campaigns (each reduced row says what was reduced) so the whole table
finishes in under 2 minutes on 2 cores; the full run is the reproduction of record and keeps its
campaigns in ``<out>/cache`` (keyed by scenario, runs, seed, overrides and proxops version), so a
second full run reuses them.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict
from pathlib import Path

from proxops.report.claims import SYSTEM_NAMES, systems
from proxops.report.claims.common import (CALIBRATED, EXPLAINED, INCONSISTENT, NOT_ATTEMPTED, REPRODUCED,  # noqa: F401
                                          RUN_CACHE, UNEXPLAINED, VERDICT_RULES, VERDICTS, Claim, Context, Goal)
from proxops.report.claims.cortex import cortex_claims  # noqa: F401
from proxops.report.claims.hybrid import hybrid_claims  # noqa: F401
from proxops.report.claims.los import los_claims  # noqa: F401
from proxops.report.claims.navigation import TERMINAL_KEYS, navigation_pairs, navigation_table  # noqa: F401
from proxops.report.claims.reach import reach_claims  # noqa: F401
from proxops.report.claims.srf import designed_dv, srf_claims  # noqa: F401
from proxops.report.claims.underactuated import underactuated_claims  # noqa: F401
from proxops.errors import input_error

SYSTEMS = SYSTEM_NAMES
WALL_GOAL_S = {False: 20 * 60.0, True: 120.0}  # full < 20 min, --quick < 2 min on 2 cores


def reproduce(target: str = "all", quick: bool = False, out: str | Path | None = None, workers: int = 2,
              progress: bool = False, navigation: bool | None = None) -> dict:
    """Run the claims of ``target`` (a system name or "all"); returns {rows, goals, navigation,
    verdict_rules, timings_s, wall_time_s, campaigns, quick, machine, figures}. ``navigation``
    (default: with "all") adds the *-ekf table."""

    names = list(SYSTEM_NAMES) if target == "all" else [target]
    if any(n not in SYSTEM_NAMES for n in names):
        raise input_error("system", target, f"must be one of {', '.join(SYSTEM_NAMES)} or all")
    if workers < 1:
        raise input_error("workers", workers, "must be >= 1")
    ctx = Context(quick=quick, workers=workers, out=Path(out) if out is not None else None, progress=progress)
    RUN_CACHE["dir"] = ctx.out / "cache" if ctx.out is not None else None
    RUN_CACHE["memo"] = {}
    t_start = time.perf_counter()
    funcs = systems()
    rows, timings = [], {}
    for n in names:
        t0 = time.perf_counter()
        rows += funcs[n](ctx)
        timings[n] = time.perf_counter() - t0
    nav = []
    if navigation if navigation is not None else target == "all":
        t0 = time.perf_counter()
        nav = navigation_table(ctx)
        timings["navigation"] = time.perf_counter() - t0
    wall = time.perf_counter() - t_start
    load = list(os.getloadavg())
    if target == "all":
        goal = WALL_GOAL_S[quick]
        reused = sum(c["reused"] for c in ctx.campaigns)
        ctx.goals.append(Goal(
            "all", "`proxops reproduce all" + (" --quick`" if quick else "`") + " wall time",
            f"< {goal / 60:.0f} min on 2 cores", f"{wall:.0f} s; {reused} of {len(ctx.campaigns)} campaigns "
            "reused from the cache", wall < goal,
            f"{os.cpu_count()} CPUs, load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} at the end "
            "(other processes share the cores)", data={"wall_s": wall, "workers": workers}))
    figures = sorted(ctx.out.rglob("*.png")) if ctx.out is not None else []
    return {"quick": quick, "rows": [asdict(r) for r in rows], "goals": [asdict(g) for g in ctx.goals],
            "navigation": nav, "verdict_rules": list(VERDICT_RULES), "timings_s": timings, "wall_time_s": wall,
            "campaigns": ctx.campaigns, "machine": {"cpus": os.cpu_count(), "load_average_1_5_15": load},
            "figures": [{"title": p.parent.name + "/" + p.stem, "path": str(p)} for p in figures]}


def _cell(s) -> str:
    return str(s).replace("|", "/").replace("\n", " ")


def _num(v, digits=3) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        return f"{v:.{digits}g}"
    return str(v)


def markdown(result: dict, notes: bool = True) -> str:
    """The three tables (and the notes, the verdict rules) as Markdown."""
    lines = ["| system | claim | paper (where) | ours | verdict |", "| --- | --- | --- | --- | --- |"]
    for r in result["rows"]:
        verdict = r["verdict"] + (" (reduced)" if r.get("reduced") else "")
        labels = r.get("labels") or []
        if labels:
            verdict += "; " + "; ".join(lab.split(":")[0] for lab in labels)
        lines.append(f"| {r['system']} | {_cell(r['claim'])} | {_cell(r['paper'])} | {_cell(r['ours'])} | {verdict} |")
    goals = result.get("goals") or []
    if goals:
        lines += ["", "Our own goals (not paper claims)", "", "| system | goal | target | ours | met |",
                  "| --- | --- | --- | --- | --- |"]
        for g in goals:
            met = "-" if g["met"] is None else ("met" if g["met"] else "not met")
            lines.append(f"| {g['system']} | {_cell(g['goal'])} | {_cell(g['target'])} | {_cell(g['ours'])} | {met} |")
    nav = result.get("navigation") or []
    if nav:
        lines += ["", "Navigation: each *-ekf built-in beside its base scenario (each its own sim.seed; terminal error = "
                  "the first of the summary keys " + ", ".join(TERMINAL_KEYS) + " present)", "",
                  "| scenario | base | success (ekf / base) | Δv m/s (ekf / base) | terminal error m (ekf / base) "
                  "| nav_nees_mean | att_nees_mean |", "| --- | --- | --- | --- | --- | --- | --- |"]
        for n in nav:
            e, b = n["ekf"], n["base"]
            lines.append(f"| {n['scenario']} | {n['base_scenario']} | {_num(e.get('success'))} / {_num(b.get('success'))} "
                         f"| {_num(e.get('dv_mps'))} / {_num(b.get('dv_mps'))} | {_num(e.get('terminal_error_m'))} / "
                         f"{_num(b.get('terminal_error_m'))} | {_num(e.get('nav_nees_mean'))} | {_num(e.get('att_nees_mean'))} |")
    lines += ["", "Verdict rules", ""] + [f"- {v}" for v in result.get("verdict_rules", VERDICT_RULES)]
    if notes:
        lines += ["", "Notes", ""]
        for i, r in enumerate(result["rows"], 1):
            extra = f" Reduced in --quick: {r['reduced']}." if r.get("reduced") else ""
            tol = f" Tolerance: {r['tolerance']}." if r.get("tolerance") else ""
            labels = (" Labels: " + " ".join(r["labels"])) if r.get("labels") else ""
            lines.append(f"{i}. **{r['system']}: {r['claim']}** -- {r['note']}{tol}{labels}{extra}")
        for g in goals:
            if g.get("note"):
                lines.append(f"- goal **{g['system']}: {g['goal']}** -- {g['note']}")
    t = result["timings_s"]
    m = result.get("machine", {})
    load = ", ".join(f"{v:.1f}" for v in m.get("load_average_1_5_15", []))
    wall = result.get("wall_time_s")
    lines += ["", f"Wall time per system ({m.get('cpus', '?')} CPUs, load average {load or '?'} at the end): "
              + ", ".join(f"{k} {v:.1f} s" for k, v in t.items())
              + (f"; total {wall:.1f} s" if wall is not None else "")]
    return "\n".join(lines)


def write_markdown(result: dict, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = ["# Reproduction of record" if not result["quick"] else "# Reproduction (--quick: reduced campaigns)", "",
            "Generated by `proxops reproduce" + (" --quick" if result["quick"] else "") + "`.", "", markdown(result)]
    if result["figures"]:
        text += ["", "## Figures", ""]
        for fig in result["figures"]:
            rel = Path(fig["path"])
            try:
                rel = rel.relative_to(path.parent)
            except ValueError:
                pass
            text.append(f"![{fig['title']}]({rel})")
    path.write_text("\n".join(text) + "\n")
    return path
