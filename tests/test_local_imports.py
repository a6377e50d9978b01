"""Imports: function-local ``proxops`` imports counted (issue 31 item 5), no module-level import
circle, every module importable first, and the commands that do not simulate stay light (issue 32
item 5): asserted on the modules a command leaves in ``sys.modules`` (state, not time)."""

from __future__ import annotations

import ast
import importlib
import json
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import proxops

PACKAGE = Path(proxops.__file__).parent

# Function-local proxops imports in src/proxops (ast count below): 333 at the start of 2026-11-27's
# session, lowered by hoisting them to module level where that adds no heavy library (numba, scipy,
# pandas, matplotlib, solvers) to the paths that must stay light: the commands that do not simulate,
# a station-keeping run, a campaign's parent process (it validates scenarios, never runs them).
# 139 after the merge of the cortex set-up module (systems/cortex_setup.py) the same day. 2026-11-28:
# each system split into its schema (proxops.systems.schema.<name>: what validation imports) and its
# system module (build, summary: imports at module level), and those of cli_*, exec/, analysis/,
# report/, runner and the small ones elsewhere hoisted. The 18 left in systems/ and scenarios/ load an
# optional heavy part only where it is used: the full truth, the EKF and its eclipse model, the TLE and
# OPM readers, the engine in SystemBase and the cortex planner/loop (a planner's check needs neither), and
# hybrid's physics checks (its schema validates with the two-body model objects); the others each have
# their reason beside them.
# Goal < 60. Lower this number as more go; never raise it.
MAX_LOCAL_IMPORTS = 30


def _is_proxops_import(node: ast.AST) -> bool:
    if isinstance(node, ast.ImportFrom):
        return node.level > 0 or (node.module or "").split(".")[0] == "proxops"
    if isinstance(node, ast.Import):
        return any(alias.name.split(".")[0] == "proxops" for alias in node.names)
    return False


def local_imports() -> dict[str, int]:
    """File -> number of import statements of proxops inside function bodies (each counted once)."""
    counts: dict[str, int] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        found = set()
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                found.update(id(n) for n in ast.walk(fn) if _is_proxops_import(n))
        if found:
            counts[str(path.relative_to(PACKAGE))] = len(found)
    return counts


def test_local_import_count_does_not_rise():
    counts = local_imports()
    total = sum(counts.values())
    worst = ", ".join(f"{f} {n}" for f, n in sorted(counts.items(), key=lambda kv: -kv[1])[:8])
    assert total <= MAX_LOCAL_IMPORTS, (f"{total} function-local proxops imports (allowed {MAX_LOCAL_IMPORTS}): "
                                        f"import at module level instead; most in {worst}")


def test_the_counter_sees_every_kind_of_local_import():
    """The ast count on a known text: 4 local imports (absolute, relative, ``import proxops.x``, nested
    function), none of the module-level or third-party ones."""
    text = ("import proxops.a\nfrom proxops import b\nimport numpy\n"
            "def f():\n    from proxops.c import d\n    import proxops.e as e\n    import json\n"
            "    def g():\n        from . import h\n    return g\n"
            "class K:\n    def m(self):\n        from proxops import z\n")
    tree = ast.parse(text)
    found = {id(n) for fn in ast.walk(tree) if isinstance(fn, ast.FunctionDef)
             for n in ast.walk(fn) if _is_proxops_import(n)}
    assert len(found) == 4


def _module_names() -> dict[str, Path]:
    names = {}
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        names[".".join(parts)] = path
    return names


def _module_level_imports(tree: ast.Module, name: str, is_package: bool, known) -> set[str]:
    """proxops modules imported when ``name`` is executed (not in functions nor under TYPE_CHECKING)."""
    found: set[str] = set()

    def visit(body):
        for node in body:
            if isinstance(node, ast.Import):
                found.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = name.split(".") if is_package else name.split(".")[:-1]
                    base = base[: len(base) - (node.level - 1)]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                found.add(module)
                found.update(f"{module}.{a.name}" for a in node.names)
            elif isinstance(node, ast.If) and not (isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"):
                visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                visit(node.body)

    visit(tree.body)
    out = set()
    for module in found:
        parts = module.split(".")
        for i in range(2, len(parts) + 1):  # importing a.b.c executes a.b too
            prefix = ".".join(parts[:i])
            if prefix in known and prefix != name and not name.startswith(prefix + "."):
                out.add(prefix)
    return out


def test_no_module_level_import_circle():
    """Tarjan's strongly connected components of the module-level import graph: none with 2+ modules."""
    names = _module_names()
    graph = {n: _module_level_imports(ast.parse(p.read_text(encoding="utf-8")), n, p.name == "__init__.py", names)
             for n, p in names.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def strong(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                circles.append(sorted(comp))

    for v in graph:
        if v not in index:
            strong(v)
    assert not circles, f"module-level import circles: {circles}"
    # the check sees a circle: a -> b -> a
    graph = {"a": {"b"}, "b": {"a"}}
    index.clear(), low.clear()
    strong("a")
    assert circles == [["a", "b"]]


@pytest.mark.slow
def test_every_module_imports_first():
    """Each module imported first in a proxops-free interpreter state (third-party modules stay
    loaded): a circle closed by a module-level import fails whichever module starts it."""
    names = sorted(m.name for m in pkgutil.walk_packages(proxops.__path__, "proxops."))
    saved = {k: v for k, v in sys.modules.items() if k == "proxops" or k.startswith("proxops.")}
    failures = []
    try:
        for name in names:
            for key in [k for k in sys.modules if k == "proxops" or k.startswith("proxops.")]:
                del sys.modules[key]
            try:
                importlib.import_module(name)
            except Exception as exc:  # noqa: BLE001 - collected and reported together
                failures.append(f"{name}: {type(exc).__name__}: {exc}")
    finally:
        for key in [k for k in sys.modules if k == "proxops" or k.startswith("proxops.")]:
            del sys.modules[key]
        sys.modules.update(saved)
    assert len(names) > 150 and not failures, failures


HEAVY = ("numba", "scipy", "pandas", "pyarrow", "casadi", "daqp", "piqp", "clarabel", "highspy", "matplotlib")


def _modules_after(*argv: str) -> set[str]:
    """The top-level packages a ``proxops`` command has imported when it exits."""
    return {m.split(".")[0] for m in _all_modules_after(*argv)}


def _all_modules_after(*argv: str) -> set[str]:
    """The modules a ``proxops`` command (through the console entry point) has imported when it exits."""
    code = ("import atexit, json, sys\n"
            "atexit.register(lambda: sys.stderr.write('MODULES ' + json.dumps(sorted(sys.modules)) + '\\n'))\n"
            f"sys.argv = ['proxops', *{list(argv)!r}]\n"
            "from proxops.exec.entry import main\nmain()\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**__import__("os").environ, "PYTHONPATH": str(PACKAGE.parent)})
    assert proc.returncode == 0, proc.stderr
    line = next(l for l in proc.stderr.splitlines() if l.startswith("MODULES "))
    return set(json.loads(line[len("MODULES "):]))


@pytest.mark.parametrize("argv", [
    ("--help",),
    ("keys",),
    ("keys", "srf", "--json"),
    ("keys", "--all", "--markdown"),
    ("scenarios",),
    ("scenarios", "--json"),
    ("--debug", "--version"),
])
def test_commands_that_do_not_simulate_import_nothing_heavy(argv):
    """`keys` reads the checked-in listing (scenarios/keys.json), `scenarios` the built-in files with
    tomllib, and typer's parameter coercion leaves pydantic out for values click parsed
    (proxops.cli_common): no pydantic, no numpy, no pool machinery, no system and no schema."""
    modules = _all_modules_after(*argv)
    top = {m.split(".")[0] for m in modules}
    assert "proxops" in top and "typer" in top  # the command ran
    assert not top & (set(HEAVY) | {"numpy", "pydantic"}), sorted(top & (set(HEAVY) | {"numpy", "pydantic"}))
    unexpected = {m for m in modules if m.startswith(("proxops.systems", "proxops.scenarios.loader",
                                                       "proxops.scenarios.reference", "proxops.exec.backends",
                                                       "proxops.exec.prestart", "multiprocessing"))}
    assert not unexpected, sorted(unexpected)


def test_light_coercion_still_rejects_and_converts_like_typer():
    """Values click did not parse to the annotated type still go through typer's own coercion: a bad
    number is one error line (exit 2), a good one arrives as a number."""
    for value, says in (("two", "Input should be a valid integer"),  # typer's own message
                        ("0", "--runs 0: give a whole number of runs >= 1")):  # mc compared an int with 1
        code = (f"import sys\nsys.argv = ['proxops', 'mc', 'srf-vbar-mc', '--runs', {value!r}]\n"
                "from proxops.exec.entry import main\nmain()\n")
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                              env={**__import__("os").environ, "PYTHONPATH": str(PACKAGE.parent)})
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and says in proc.stderr, proc.stderr


def test_validate_and_run_import_no_dataframes_plots_or_solvers():
    """validate (its schema's build-free check: tests/test_validate_without_build.py) and a
    station-keeping run import no dataframe, plotting or solver library."""
    for argv in (("validate", "station-keeping"),
                 ("run", "station-keeping", "--set", "truth.model=cw", "--set", "sim.duration_s=100")):
        modules = _all_modules_after(*argv)
        top = {m.split(".")[0] for m in modules}
        unexpected = top & {"pandas", "pyarrow", "matplotlib", "casadi", "daqp", "piqp", "clarabel", "highspy"}
        assert not unexpected, (argv, sorted(unexpected))
        # nor the optional outputs, the campaign engine, the pool or the key reference's generator
        unexpected = modules & {"proxops.analysis.export", "proxops.analysis.campaign", "proxops.plotting.common",
                                "proxops.report.campaign", "proxops.exec.backends", "proxops.exec.prestart",
                                "proxops.scenarios.reference", "multiprocessing.pool"}
        assert not unexpected, (argv, sorted(unexpected))


def test_a_campaigns_parent_validates_without_numba_scipy_or_plots():
    """A campaign's parent process loads the campaign, statistics and report layers and validates the
    scenario (it never runs one: the workers do): for srf, whose system module
    imports the engine where a run needs it, no numba, scipy, matplotlib or solver (as on main)."""
    code = ("import json, sys\n"
            "import proxops.analysis.campaign, proxops.analysis.statistics, proxops.report.campaign\n"
            "from proxops.scenarios.loader import load_scenario\n"
            "for name in ('srf-vbar-mc', 'srf-rbar-mc'):\n    load_scenario(name)\n"
            "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**__import__("os").environ, "PYTHONPATH": str(PACKAGE.parent)})
    assert proc.returncode == 0, proc.stderr
    top = set(json.loads(proc.stdout.strip().splitlines()[-1]))
    assert "pandas" in top  # the campaign layer was loaded
    assert not top & (set(HEAVY) - {"pandas", "pyarrow"}), sorted(top & set(HEAVY))


def test_lazy_command_table_short_help_is_the_commands_own():
    """`proxops --help` lists each command from the table without importing it: its text must be the
    first paragraph of the command's own help."""
    import typer

    from proxops.cli import COMMANDS, app

    root = typer.main.get_command(app)
    for name, entry in COMMANDS.items():
        cmd = root.get_command(None, name)
        assert cmd is not None, name
        own = " ".join((cmd.help or "").split("\n\n")[0].split())
        assert " ".join(entry.short_help.split()) == own, name
    assert root.list_commands(None) == list(COMMANDS)


def _modules_after_code(code: str) -> set[str]:
    """Top-level names of the modules a fresh interpreter holds after running ``code``."""
    code += "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))\n"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**__import__("os").environ, "PYTHONPATH": str(PACKAGE.parent)})
    assert proc.returncode == 0, proc.stderr
    return set(json.loads(proc.stdout.strip().splitlines()[-1]))


def test_validating_a_scenario_imports_its_schema_not_its_system():
    """Loading (validating) scenarios of five systems, the full truth and an EKF among them, imports their
    schema modules only: no system module, no engine, no numba, scipy or solver (hybrid is left out:
    its schema's physics checks build the two-body model objects, numba)."""
    names = ("srf-vbar-mc", "los-tumble-ekf", "station-keeping-mc", "underactuated-case1", "cortex-nominal")
    modules = _modules_after_code("from proxops.scenarios.loader import load_scenario\n"
                                  f"for name in {names!r}:\n    load_scenario(name)\n")
    systems = {m for m in modules if m.startswith("proxops.systems.")}
    assert systems == {"proxops.systems.schema", *(f"proxops.systems.schema.{s}" for s in
                                                   ("srf", "los", "station_keeping", "underactuated", "cortex",
                                                    "_build_free"))}  # the build-free checks' light pieces
    assert {m for m in modules if m.startswith("proxops.sim")} <= {"proxops.sim", "proxops.sim.steps"}  # no engine
    assert not {m.split(".")[0] for m in modules} & set(HEAVY), sorted({m.split(".")[0] for m in modules} & set(HEAVY))


def test_keys_of_a_system_reads_no_system_module():
    """`keys los` reads the checked-in key listing (test_keys proves it equal to the live schema): no
    schema, no system module (engine, numba, solvers)."""
    modules = _all_modules_after("keys", "los")
    assert not {m for m in modules if m.startswith("proxops.systems")}, sorted(m for m in modules if m.startswith("proxops.systems"))
    top = {m.split(".")[0] for m in modules}
    assert not top & set(HEAVY), sorted(top & set(HEAVY))


def test_validate_of_a_planner_imports_no_numba_scipy_or_solvers():
    """`validate cortex-reference`: schema plus the planner's own checks (no closed loop to build), so
    nothing heavy; `validate station-keeping` runs its schema's build-free check (plant, actuator and
    the step count without building: proxops.sim.steps), so neither its system module nor the engine;
    `validate station-keeping-ekf` (the filter checks itself) builds its closed loop."""
    planner = _all_modules_after("validate", "cortex-reference")
    assert "proxops.systems.cortex" in planner and "proxops.sim.engine" not in planner
    top = {m.split(".")[0] for m in planner}
    assert not top & set(HEAVY), sorted(top & set(HEAVY))
    build_free = _all_modules_after("validate", "station-keeping")
    assert "proxops.systems.station_keeping" not in build_free and "proxops.sim.engine" not in build_free
    assert not {m.split(".")[0] for m in build_free} & set(HEAVY), sorted({m.split(".")[0] for m in build_free} & set(HEAVY))
    closed_loop = _all_modules_after("validate", "station-keeping-ekf")
    assert "proxops.systems.station_keeping" in closed_loop and "proxops.sim.engine" in closed_loop


def test_every_system_has_one_schema_registered_under_its_name():
    """The schema modules and the system modules name the same systems, and each system's ``Scenario``
    is the model its schema registered (one definition, found by validation and by a run alike)."""
    from proxops.scenarios.registry import SCHEMA_MODULES, SYSTEM_MODULES, get_system, scenario_model

    assert sorted(SCHEMA_MODULES) == sorted(SYSTEM_MODULES) and len(SYSTEM_MODULES) == 6
    for name in SYSTEM_MODULES:
        assert get_system(name).Scenario is scenario_model(name), name

