"""Start-up of the command line (issue 32 item 5): whole-command wall and CPU time of the commands
that do not simulate (goal < 0.15 s) and of ``proxops run station-keeping`` (goal < 0.6 s on 2 idle
cores, numba cache warm), the heavy libraries each imports, and the import profile of the run (top
modules by cumulative import time from ``python -X importtime``), and the third-party floors under
``validate srf-vbar`` (python, typer, pydantic in use, numpy) and the run (also numba, scipy.linalg,
numba's first kernel load): no proxops code; a goal below its floor is printed as such.

Timings on a loaded machine are not claims: the load average is printed with them; the import
profile's shares inside one process are the reliable figures. ``python benchmarks/bench_startup.py
--repeat 7``; ``--base /tmp/base/src`` alternates every command with another tree (e.g. the previous
release: ``git archive b3055eb src | tar -x -C /tmp/base``) and prints the CPU ratio.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
HEAVY = ("numpy", "pydantic", "numba", "scipy", "pandas", "pyarrow", "matplotlib", "casadi", "daqp", "piqp",
         "clarabel", "highspy")
COMMANDS = {  # name: (argv, goal in s, whole command on 2 idle cores)
    "--version": (["--version"], 0.15),
    "--help": (["--help"], 0.15),
    "keys": (["keys"], 0.15),
    "keys srf": (["keys", "srf"], 0.15),
    "scenarios": (["scenarios"], 0.15),
    "validate station-keeping": (["validate", "station-keeping"], 0.15),
    "validate srf-vbar": (["validate", "srf-vbar"], 0.15),  # the schema's build-free check: no numba
    "run station-keeping": (["run", "station-keeping"], 0.6),
}
_WRAPPER = ("import atexit, json, sys\n"
            "atexit.register(lambda: sys.stderr.write('MODULES ' + json.dumps(sorted(sys.modules)) + '\\n'))\n"
            "sys.argv = ['proxops', *json.loads(sys.argv[1])]\n"
            "from proxops.exec.entry import main\nmain()\n")


def _env(src: Path = SRC) -> dict:
    return {**os.environ, "PYTHONPATH": str(src), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def _run(argv: list[str], *flags: str, src: Path = SRC) -> tuple[float, float, subprocess.CompletedProcess]:
    """(wall s, CPU s of the child, the finished process) of ``python [flags] -c WRAPPER argv`` with
    the package under ``src``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, *flags, "-c", _WRAPPER, json.dumps(argv)], capture_output=True,
                          text=True, env=_env(src), timeout=600)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc


def _modules(proc: subprocess.CompletedProcess) -> list[str]:
    line = next((l for l in proc.stderr.splitlines() if l.startswith("MODULES ")), None)
    return json.loads(line[len("MODULES "):]) if line else []


_MARKS = ("import json, sys, time\n"
          "rows, w0 = [('python start', time.process_time(), 0.0)], time.perf_counter()\n"
          "from proxops.exec.startup import defer_when_numpy_is_imported, skip_pydantic_plugin_scan\n"
          "skip_pydantic_plugin_scan(); defer_when_numpy_is_imported()\n"
          "c0 = time.process_time()\n"
          "def mark(name):\n"
          "    global c0, w0\n"
          "    c, w = time.process_time(), time.perf_counter()\n"
          "    rows.append((name, c - c0, w - w0)); c0, w0 = c, w\n")
_FLOORS = {  # command: the third-party steps under it (no proxops code), each timed after the ones before
    "validate srf-vbar": (
        "import typer; mark('typer')\n"
        "import pydantic\nclass M(pydantic.BaseModel):\n    x: float\n"
        "M.model_validate({'x': 1.0}); mark('pydantic (one model built and used)')\n"
        "import numpy; mark('numpy (the srf check: Algorithm 1 hop plan)')\n"),
    "run station-keeping": (
        "import typer; mark('typer')\n"
        "import pydantic\nclass M(pydantic.BaseModel):\n    x: float\n"
        "M.model_validate({'x': 1.0}); mark('pydantic (one model built and used)')\n"
        "import numpy; mark('numpy')\n"
        "import numba; mark('numba')\n"
        "import scipy.linalg; mark('scipy.linalg (numba checks BLAS through it)')\n"
        "from numba.core.registry import cpu_target\n"
        "cpu_target.target_context.refresh(); mark(\"numba's target refresh (first kernel load)\")\n"),
}


def third_party_floor(command: str = "run station-keeping") -> list[tuple[str, float, float]]:
    """(step, CPU s, wall s) of the third-party start-up ``command`` pays before and besides its
    proxops code (:data:`_FLOORS`): the interpreter's start (CPU since the process began), typer,
    pydantic with one model class built and used (the scenario models need pydantic.main, its fields
    and core schema: far more than ``import pydantic``), numpy; for a simulating command also numba,
    scipy.linalg (numba's first kernel load imports it for its BLAS check:
    numba.np.arraymath._check_blas, at the import of arraymath, whatever the kernel) and numba's
    target refresh (every registry its first cached-kernel load imports). With the console script's
    start-up trimming (:mod:`proxops.exec.startup`: pydantic's plugin loader and numpy.f2py/testing left
    out), whose import is not counted."""
    code = _MARKS + _FLOORS[command] + "print(json.dumps(rows))\n"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(), timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-300:])
    return [tuple(r) for r in json.loads(proc.stdout.strip().splitlines()[-1])]


def import_profile(argv: list[str], top: int = 15) -> list[tuple[str, float, float]]:
    """(module, self ms, cumulative ms) of the ``top`` modules by cumulative import time."""
    _, _, proc = _run(argv, "-X", "importtime")
    rows = []
    for line in proc.stderr.splitlines():
        if not line.startswith("import time:") or "self [us]" in line:
            continue
        _, self_us, cum_us, name = [p.strip() for p in line.replace("import time:", "|").split("|")]
        rows.append((name, int(self_us) / 1e3, int(cum_us) / 1e3))
    rows.sort(key=lambda r: -r[2])
    return rows[:top]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs of each command (alternated; median shown)")
    parser.add_argument("--base", type=Path, default=None,
                        help="another tree's src/ (e.g. `git archive b3055eb src | tar -x -C /tmp/base`): each "
                             "command alternates with it and the CPU ratio this/base is shown")
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
          f"load average before: {open('/proc/loadavg').read().split()[:3]}")
    _run(COMMANDS["run station-keeping"][0])  # numba's cache warm (a changed source recompiles once)
    if args.base is not None:
        _run(COMMANDS["run station-keeping"][0], src=args.base)
    times: dict[str, list[tuple[float, float]]] = {name: [] for name in COMMANDS}
    base: dict[str, list[tuple[float, float]]] = {name: [] for name in COMMANDS}
    modules: dict[str, list[str]] = {}
    for _ in range(args.repeat):  # alternate the commands (and the trees): a load change hits them all alike
        for name, (argv, _goal) in COMMANDS.items():
            for src, into in ((SRC, times), (args.base, base)):
                if src is None:
                    continue
                wall, cpu, proc = _run(argv, src=src)
                if proc.returncode != 0:
                    raise RuntimeError(f"proxops {' '.join(argv)} ({src}) exited {proc.returncode}: "
                                       f"{proc.stderr[-300:]}")
                into[name].append((wall, cpu))
                if src == SRC:
                    modules[name] = _modules(proc)
    print(f"load average after: {open('/proc/loadavg').read().split()[:3]} (under load the times are not a claim)")
    print(f"{'command':<26} {'wall s':>7} {'CPU s':>6} {'goal s':>6}  modules  heavy libraries imported")
    for name, (argv, goal) in COMMANDS.items():
        wall = statistics.median(w for w, _ in times[name])
        cpu = statistics.median(c for _, c in times[name])
        tops = sorted({m.split(".")[0] for m in modules[name]} & set(HEAVY), key=HEAVY.index)
        print(f"{name:<26} {wall:>7.3f} {cpu:>6.3f} {goal:>6.2f}  {len(modules[name]):>7}  {', '.join(tops) or '-'}")
    if args.base is not None:
        print(f"\nA/B against {args.base} (alternated in the same run; the CPU ratio is the figure to trust):")
        print(f"{'command':<26} {'base CPU s':>10} {'this CPU s':>10} {'ratio':>6}")
        for name in COMMANDS:
            b = statistics.median(c for _, c in base[name])
            t = statistics.median(c for _, c in times[name])
            print(f"{name:<26} {b:>10.3f} {t:>10.3f} {t / b:>6.2f}")
    for command in _FLOORS:
        floors = [third_party_floor(command) for _ in range(args.repeat)]
        print(f"\nthird-party floor of `proxops {command}` (median of {args.repeat} runs; no proxops code):")
        print(f"{'step':<46} {'CPU s':>6} {'wall s':>7}")
        for k, (step, _, _) in enumerate(floors[0]):
            print(f"{step:<46} {statistics.median(f[k][1] for f in floors):>6.3f} "
                  f"{statistics.median(f[k][2] for f in floors):>7.3f}")
        floor_cpu = statistics.median(sum(r[1] for r in f) for f in floors)
        goal = COMMANDS[command][1]
        cmd_cpu = statistics.median(c for _, c in times[command])
        print(f"{'total':<46} {floor_cpu:>6.3f}   goal {goal:.2f} s: "
              f"{'BELOW this floor (not reachable without dropping one of these steps)' if floor_cpu > goal else 'above the floor'}")
        print(f"`proxops {command}` CPU above this floor: {cmd_cpu - floor_cpu:+.3f} s ({cmd_cpu:.3f} s in all: proxops' "
              "imports, the scenario models, the check" + (", the build, the 5400 s run and its summary)" if "run" in command else ")"))
    for name in ("--help", "validate srf-vbar", "run station-keeping"):
        print(f"\nimport profile of `proxops {name}` (top by cumulative import time, ms; one run):")
        print(f"{'module':<44} {'self':>8} {'cumulative':>11}")
        for module, self_ms, cum_ms in import_profile(COMMANDS[name][0]):
            print(f"{module:<44} {self_ms:>8.1f} {cum_ms:>11.1f}")


if __name__ == "__main__":
    main()
