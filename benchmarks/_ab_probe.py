"""One measurement for benchmarks/ab.py, run in a fresh process with PYTHONPATH set to the
sources under test (this checkout or the previous release), so both use the same probe.

    python _ab_probe.py loop SCENARIO REPS [key=value ...]   -> one JSON line
    python _ab_probe.py cli ARG ...                          -> runs the proxops CLI (exit code kept)

``loop``: runs the scenario once to warm up (numba cache, solver set-up), then REPS times,
timing the whole ``api.run`` (set-up + closed loop) and, inside it, every solver adapter's set-up,
update, warm-start and solve calls (wrapped on the classes, so it works on any version that has the
adapters).
"""

from __future__ import annotations

import importlib
import json
import sys
import time

ADAPTERS = {  # module -> adapter classes (present in every release since the solver layer)
    "proxops.solvers.daqp_qp": ["DaqpQP"],
    "proxops.solvers.piqp_qp": ["PiqpQP"],
    "proxops.solvers.clarabel_socp": ["ClarabelSOCP"],
    "proxops.solvers.highs_lp": ["HighsLP", "HighsMILP"],
    "proxops.solvers.casadi_nlp": ["CasadiNLP"],
}
_clock = {"s": 0.0, "calls": 0, "depth": 0}  # the solver clock


SOLVER_METHODS = ("setup", "setup_native", "update", "update_native", "update_fast", "warm_start", "solve",
                  "solve_fast", "solve_bounds_fast")
# one solve each (solve_fast's fallback to solve is nested: counted once); solve_bounds_fast = DAQP's update of the
# bounds written in place into its vectors + solve_fast
SOLVE_METHODS = ("solve", "solve_fast", "solve_bounds_fast")


def _timer(fn, pick, count: bool = False):
    """``fn`` timed into the clock ``pick()`` returns at the call (a dict with "s", "depth" and, with
    ``count``, "calls"; None: not timed); a call made inside another timed call of the same clock counts
    once."""

    def timed(*args, **kwargs):
        clock = pick()
        if clock is None:
            return fn(*args, **kwargs)
        outer = clock["depth"] == 0
        clock["depth"] += 1
        t0 = time.perf_counter() if outer else 0.0
        try:
            return fn(*args, **kwargs)
        finally:
            clock["depth"] -= 1
            if outer:
                clock["s"] += time.perf_counter() - t0
                if count:
                    clock["calls"] += 1

    timed._ab_wrapped = True
    return timed


def _wrap(cls, method: str) -> None:
    """Time ``cls.method`` into the solver clock: the solver's own work (data loading, factorisation,
    iterations) and its adapter; a call made inside another solver call counts once."""
    fn = cls.__dict__.get(method)
    if fn is None or getattr(fn, "_ab_wrapped", False):
        return
    setattr(cls, method, _timer(fn, lambda: _clock, count=method in SOLVE_METHODS))


def _instrument() -> None:
    for module, names in ADAPTERS.items():
        try:
            mod = importlib.import_module(module)
        except ImportError:
            continue
        for name in names:
            cls = getattr(mod, name, None)
            if cls is not None:
                for klass in {cls, *cls.__mro__[:-1], *cls.__subclasses__()}:
                    for method in SOLVER_METHODS:
                        _wrap(klass, method)


def _timed(fn) -> tuple[float, float, int, object]:
    _clock.update(s=0.0, calls=0)
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, _clock["s"], _clock["calls"], out


def loop(scenario: str, reps: int, overrides: list[str]) -> dict:
    """The closed loop alone (``simulate`` of the system's set-up, as the README's API section does)
    and the whole run (``api.run``: set-up, loop, summary with its certificates)."""
    from proxops import api

    loaded = api.load_scenario(scenario, overrides)
    _instrument()

    def closed_loop():
        setup = loaded.system.build(loaded.scenario)  # set-up (e.g. cortex's reference plan) is not the loop
        _clock.update(s=0.0, calls=0)
        t0 = time.perf_counter()
        res = api.simulate(setup, seed=0)
        return time.perf_counter() - t0, _clock["s"], _clock["calls"], res

    api.run(loaded)  # warm-up: numba cache load, lazy imports, solver set-up
    closed_loop()
    best: dict = {}
    for _ in range(reps):
        wall, solver, calls, summary = _timed(lambda: api.run(loaded)[0])
        loop_wall, loop_solver, loop_calls, res = closed_loop()
        if not best or loop_wall < best["wall_s"]:
            steps = len(getattr(res, "t", ())) or summary.get("steps")
            best = {
                "wall_s": loop_wall, "solver_s": loop_solver, "solver_calls": loop_calls,
                "solver_share": loop_solver / loop_wall if loop_wall > 0 else None,
                "steps": steps, "step_ms": 1e3 * loop_wall / steps if steps else None,
                "run_wall_s": wall, "run_solver_share": solver / wall if wall > 0 else None,
                "status": summary.get("status") or summary.get("outcome"),
            }
    if best:
        best.update(breakdown(loaded) or {})
    return best


PLANT_METHODS = ("relative_state", "propagate", "propagate_events", "apply_impulse", "coast", "mode")


def _wrap_kernels(pick) -> list:
    """Every numba kernel a proxops module holds as a module attribute, replaced by a timer into the clock
    ``pick()`` names (numba code calling numba code is compiled and untouched: only the calls from Python
    are timed, dispatch included). Returns the (module, name, kernel) to put back."""
    from numba.core.registry import CPUDispatcher

    undo = []
    for name, mod in list(sys.modules.items()):
        if not name.startswith("proxops") or mod is None:
            continue
        for attr, value in list(vars(mod).items()):
            if isinstance(value, CPUDispatcher):
                undo.append((mod, attr, value))
                setattr(mod, attr, _timer(value, pick))
    return undo


def breakdown(loaded) -> dict | None:
    """Where one more closed loop's wall goes, in disjoint parts: the solver adapters (as the timed
    loops count them), the plant's methods the engine calls (the truth's propagation, its relative
    state, impulses, coasts) and, inside both and outside, the compiled (numba) kernels called from
    Python. A separate loop, so these wrappers do not touch the timed loops. Keys (shares of this loop):

    - breakdown_solver_share: the solver clock (adapter calls, their Python included);
    - plant_share: the plant's methods; plant_kernel_share: the compiled part of them;
    - kernel_share: kernels outside the solver and the plant (the controller's and the engine's
      numerics: QP construction, guidance, linearisation);
    - python_share: the rest, with the plant's own Python (plant_share - plant_kernel_share);
    - compiled_bound: the solver's share if every line of Python outside the solver took no time,
      solver / (solver + plant kernels + kernels);
    - controller_share: the controller's steps (the onboard computation: its solver calls, kernels and
      Python), and solver_share_of_controller, the solver's part of them.

    A kernel is found as a proxops module attribute, so one reached another way counts as Python; a
    kernel's clock includes its dispatch and its wrapper (~0.5 us a call)."""
    from proxops import api

    plant_clock = {"s": 0.0, "depth": 0}
    kernel_clock = {"s": 0.0, "depth": 0}
    plant_kernel_clock = {"s": 0.0, "depth": 0}
    controller_clock = {"s": 0.0, "depth": 0}

    def kernel_clock_now():  # inside a solver call: the solver's; inside a plant call: the plant's kernels
        if _clock["depth"]:
            return None
        return plant_kernel_clock if plant_clock["depth"] else kernel_clock

    undo = _wrap_kernels(kernel_clock_now)
    try:
        setup = loaded.system.build(loaded.scenario)
        plant = setup.plant
        for name in PLANT_METHODS:
            fn = getattr(plant, name, None)
            if fn is not None:
                setattr(plant, name, _timer(fn, lambda: None if _clock["depth"] else plant_clock))
        setup.controller.step = _timer(setup.controller.step, lambda: controller_clock)
        _clock.update(s=0.0, calls=0)
        t0 = time.perf_counter()
        api.simulate(setup, seed=0)
        wall = time.perf_counter() - t0
    finally:
        for mod, attr, value in undo:
            setattr(mod, attr, value)
    if not wall > 0:
        return None
    solver, plant_s = _clock["s"] / wall, plant_clock["s"] / wall
    kernel, plant_kernel = kernel_clock["s"] / wall, plant_kernel_clock["s"] / wall
    return {"breakdown_solver_share": solver, "plant_share": plant_s, "plant_kernel_share": plant_kernel,
            "kernel_share": kernel, "python_share": 1.0 - solver - plant_s - kernel,
            "compiled_bound": solver / (solver + plant_kernel + kernel) if solver > 0 else None,
            "controller_share": controller_clock["s"] / wall,
            "solver_share_of_controller": _clock["s"] / controller_clock["s"] if controller_clock["s"] > 0 else None}


def cli(args: list[str]) -> int:
    """Run the proxops CLI as its console script does (``main()`` reads ``sys.argv``)."""
    for name in ("proxops.exec.entry", "proxops.entry"):  # the console script's home moved between releases
        try:
            entry = importlib.import_module(name)
        except ModuleNotFoundError:
            continue
        sys.argv = ["proxops", *args]
        return entry.main() or 0
    raise SystemExit("no proxops entry point found")


if __name__ == "__main__":
    if sys.argv[1] == "loop":
        print(json.dumps(loop(sys.argv[2], int(sys.argv[3]), sys.argv[4:])))
    else:
        sys.exit(cli(sys.argv[2:]))
