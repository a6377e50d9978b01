"""A/B benchmark: this checkout against the previous release, alternated in one run.

``make bench`` starts with this table. The previous release's sources (the commit named in
``benchmarks/previous_release``) are unpacked with ``git archive`` into ``.bench/<commit>/src``
and both versions run in the same venv, in fresh processes, alternating the order each
repetition (A B, B A, ...), so load drifts hit both sides alike. A regression shows as a ratio.

Closed loops: ``simulate`` of a built-in's set-up (the loop alone) and ``api.run`` (set-up, loop,
summary), after one warm-up run in the same process, the fastest of ``INNER_REPS`` = 5 loops in it; the solver share is the time inside every
solver adapter's set-up, update and solve calls over the wall time (see ``_ab_probe.py``). Commands: the whole process, as a user sees it.
Each row also prints the spread of the per-repetition ratios, and a goal is ``met`` only when every
repetition meets it (``met in k of n repetitions only`` when the goal lies inside their spread).

    python benchmarks/ab.py [--reps 3] [--only srf,help] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PROBE = HERE / "_ab_probe.py"

# (key, label, scenario, overrides, goal on wall s or None, solver-share goal or None) — goals of issue 32
LOOPS = [
    ("srf", "srf-vbar closed loop", "srf-vbar", [], None, 0.5),
    ("los", "los-tumble closed loop (N = 40)", "los-tumble", [], None, 0.5),
    ("cortex", "cortex-nominal, first 1800 s", "cortex-nominal", ["sim.duration_s=1800"], None, 0.5),
    ("hybrid", "hybrid-capture-exact 800 s (§VII)", "hybrid-capture-exact", [], 0.5, 0.5),
    ("hybrid-mekf", "hybrid-capture 800 s on the MEKF", "hybrid-capture", [], None, None),
]
# (key, label, argv, goal on whole wall s or None); "{out}" is a fresh temporary folder
COMMANDS = [
    ("help", "proxops --help", ["--help"], 0.15),
    ("keys", "proxops keys srf", ["keys", "srf"], 0.15),
    ("scenarios", "proxops scenarios", ["scenarios"], 0.15),
    ("validate", "proxops validate srf-vbar", ["validate", "srf-vbar"], 0.15),
    ("station-keeping", "proxops run station-keeping", ["run", "station-keeping"], 0.6),
    ("mc", "proxops mc srf-vbar-mc --runs 50 --workers 2",
     ["mc", "srf-vbar-mc", "--runs", "50", "--workers", "2", "--out", "{out}"], 4.0),
    ("references", "proxops cortex references --n 100 --workers 2",
     ["cortex", "references", "--n", "100", "--workers", "2", "--out", "{out}"], 5.0),
    ("demo", "proxops demo (six scenarios, figures, report)", ["demo", "--out", "{out}"], None),
]


def previous_release() -> str:
    return (HERE / "previous_release").read_text().split()[0]


def unpack(commit: str) -> Path | None:
    """``.bench/<commit>/src`` from ``git archive`` (None when the commit is not in this clone)."""
    dest = ROOT / ".bench" / commit
    if (dest / "src" / "proxops").is_dir():
        return dest / "src"
    ok = subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", f"{commit}^{{commit}}"],
                        capture_output=True).returncode == 0
    if not ok:
        return None
    dest.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit, "src"], capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive.stdout, check=True)
    return dest / "src"


def _env(src: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    env.pop("PROXOPS_NUMBA_CACHE_STAMPED", None)  # each source tree gets its own numba cache
    return env


INNER_REPS = 5  # loops per process (the fastest is kept: a 0.05-0.1 s loop is easily preempted once)


def run_loop(src: Path, scenario: str, overrides: list[str]) -> dict:
    out = subprocess.run([sys.executable, str(PROBE), "loop", scenario, str(INNER_REPS), *overrides], env=_env(src),
                         capture_output=True, text=True)
    if out.returncode != 0:
        return {"error": (out.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_command(src: Path, argv: list[str]) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        args = [a.replace("{out}", str(Path(tmp) / "out")) for a in argv]
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, str(PROBE), "cli", *args], env=_env(src),
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        wall = time.perf_counter() - t0
    if out.returncode not in (0, 4):  # 4: a run that finished but failed is still a measurement
        return {"error": (out.stderr.strip().splitlines() or ["?"])[-1]}
    return {"wall_s": wall}


def machine() -> str:
    model = "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores, Python {platform.python_version()}"


def load() -> str:
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "?"


def _values(rows: list[dict], key: str) -> list[float]:
    return [r[key] for r in rows if r.get(key) is not None]


def _median(rows: list[dict], key: str):
    vals = _values(rows, key)
    return statistics.median(vals) if vals else None


def _fmt(v, unit="s") -> str:
    if v is None:
        return "-"
    if unit == "%":
        return f"{100 * v:.0f} %"
    return f"{v:.3f} s" if v < 10 else f"{v:.1f} s"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=3, help="alternated repetitions per side (median reported)")
    ap.add_argument("--only", default="", help="comma-separated keys: " + ",".join(k for k, *_ in LOOPS + COMMANDS))
    ap.add_argument("--json", type=Path, help="also write every measurement to this file")
    opts = ap.parse_args(argv)
    only = {k for k in opts.only.split(",") if k}
    this_src = ROOT / "src"
    commit = previous_release()
    prev_src = unpack(commit)
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True).stdout.strip() or "?"
    dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "src"], capture_output=True,
                           text=True).stdout.strip()
    print(f"A/B: this checkout ({head}{' + uncommitted changes' if dirty else ''}) vs previous release {commit}")
    print(f"machine: {machine()}; load average at start {load()}; {opts.reps} alternated repetitions, median "
          f"(closed loops: the fastest of {INNER_REPS} in each process)")
    if prev_src is None:
        print(f"previous release {commit} is not in this clone (shallow?): only this checkout is measured")
    sides = [("this", this_src)] + ([("prev", prev_src)] if prev_src else [])
    results: dict = {}
    jobs = [("loop", k, lab, (sc, ov), goal, share) for k, lab, sc, ov, goal, share in LOOPS]
    jobs += [("cmd", k, lab, (av,), goal, None) for k, lab, av, goal in COMMANDS]
    for kind, key, label, spec, goal, share_goal in jobs:
        if only and key not in only:
            continue
        rows = {name: [] for name, _ in sides}
        if kind == "cmd":  # one untimed run per side fills the numba cache and the OS file cache
            for _, src in sides:
                run_command(src, *spec)
        for rep in range(opts.reps):
            for name, src in (sides if rep % 2 == 0 else sides[::-1]):
                rows[name].append(run_loop(src, *spec) if kind == "loop" else run_command(src, *spec))
        results[key] = {"label": label, "goal_wall_s": goal, "goal_solver_share": share_goal, **rows}
        _print_row(label, rows, goal, share_goal)
    print(f"load average at end {load()}")
    if opts.json:
        opts.json.write_text(json.dumps({"previous_release": commit, "head": head, "machine": machine(),
                                         "results": results}, indent=1))
    return 0


def _ratio_range(this: list[dict], prev: list[dict], key: str = "wall_s") -> str:
    """The spread of the per-repetition ratios (repetition i of each side ran next to each other), e.g.
    ``"reps x0.85-1.01"``: a median ratio inside a spread that crosses 1 is not a resolved change."""
    pairs = [(a[key], b[key]) for a, b in zip(this, prev) if a.get(key) and b.get(key)]
    if len(pairs) < 2:
        return ""
    ratios = [a / b for a, b in pairs]
    return f"reps x{min(ratios):.2f}-{max(ratios):.2f}"


def verdict(values: list[float], goal: float, below: bool) -> str:
    """A goal's verdict over every repetition, not only the median: ``met`` when every value meets it
    (below the goal, or at least the goal when ``below`` is False), ``NOT met`` when none does, else
    ``met in k of n`` (the goal lies inside the repetitions' spread: not resolved by this pass)."""
    ok = [(v < goal) if below else (v >= goal) for v in values]
    if all(ok):
        return "met"
    if not any(ok):
        return "NOT met"
    return f"met in {sum(ok)} of {len(ok)} repetitions only"


def _breakdown_text(rows: list) -> str:
    """The probe's breakdown of one more loop (``_ab_probe.breakdown``), medians: solver, plant (its compiled
    part), the controller's and engine's compiled kernels, Python, and the solver's share with no Python
    outside the solver (the ceiling the compiled numerics set); "" for a row without it."""
    bound = _median(rows, "compiled_bound")
    if bound is None:
        return ""
    part = {key: _fmt(_median(rows, key), "%") for key in
            ("breakdown_solver_share", "plant_share", "plant_kernel_share", "kernel_share", "python_share")}
    return (f"\n  {'':<48} breakdown: solver {part['breakdown_solver_share']}, plant {part['plant_share']}"
            f" (compiled {part['plant_kernel_share']}), other compiled kernels {part['kernel_share']},"
            f" Python {part['python_share']}; solver share with no Python outside the solver {_fmt(bound, '%')}"
            f"\n  {'':<48} the controller's steps {_fmt(_median(rows, 'controller_share'), '%')} of the loop, the solver"
            f" {_fmt(_median(rows, 'solver_share_of_controller'), '%')} of them")


def _print_row(label: str, rows: dict, goal, share_goal) -> None:
    errors = [r["error"] for side in rows.values() for r in side if "error" in r]
    prev_rows = rows.get("prev", [])
    this_wall, prev_wall = _median(rows["this"], "wall_s"), _median(prev_rows, "wall_s")
    ratio = f"x{this_wall / prev_wall:.2f}" if this_wall and prev_wall else "-"
    text = f"  {label:<48} this {_fmt(this_wall):>9}  prev {_fmt(prev_wall):>9}  this/prev {ratio:>6}"
    spread = _ratio_range(rows["this"], prev_rows)
    if spread:
        text += f" ({spread})"
    if goal is not None and this_wall is not None:
        text += f"  goal < {goal:g} s: {verdict(_values(rows['this'], 'wall_s'), goal, True)}"
    share, prev_share = _median(rows["this"], "solver_share"), _median(prev_rows, "solver_share")
    if share is not None:
        step, prev_step = _median(rows["this"], "step_ms"), _median(prev_rows, "step_ms")
        text += (f"\n  {'':<48} solver share {_fmt(share, '%')} (prev {_fmt(prev_share, '%')}),"
                 f" per recorded sample {step:.3f} ms (prev {prev_step:.3f} ms)" if step and prev_step else
                 f"\n  {'':<48} solver share {_fmt(share, '%')} (prev {_fmt(prev_share, '%')})")
        if share_goal is not None:
            text += (f"  goal >= {100 * share_goal:.0f} %: "
                     f"{verdict(_values(rows['this'], 'solver_share'), share_goal, False)}")
        plant = _median(rows["this"], "plant_share")
        if plant is not None and plant < 1.0:
            text += (f"\n  {'':<48} the plant (truth propagation, relative state) {_fmt(plant, '%')} of the loop;"
                     f" solver share of the loop without it {_fmt(share / (1.0 - plant), '%')}")
        text += _breakdown_text(rows["this"])
    run, prev_run = _median(rows["this"], "run_wall_s"), _median(prev_rows, "run_wall_s")
    if run is not None:
        text += (f"\n  {'':<48} whole run (set-up, loop, summary) {_fmt(run)} (prev {_fmt(prev_run)}),"
                 f" solver share {_fmt(_median(rows['this'], 'run_solver_share'), '%')}"
                 f" (prev {_fmt(_median(prev_rows, 'run_solver_share'), '%')})")
    if errors:
        text += f"\n  {'':<48} error: {errors[0]}"
    print(text, flush=True)


if __name__ == "__main__":
    sys.exit(main())
