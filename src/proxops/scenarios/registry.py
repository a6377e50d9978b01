"""Systems by name, and their scenario schemas. A system turns a validated scenario into a
simulator Setup.

Each built-in system has two modules: its *schema* ``proxops.systems.schema.<module>`` (the
pydantic ``Scenario`` model and its sections, registered with ``@register_scenario(name)``;
pydantic and light proxops modules only) and its *system* ``proxops.systems.<module>`` (build,
summary and hooks; it imports the engine, plants and controllers). A system object has
``Scenario`` (the schema's model), ``build(sc) -> Setup`` and ``summarize(sc, result) -> dict``
(the other hooks default in :class:`proxops.systems.base.SystemBase`); it registers itself with
``@register_system(name)`` when its module is imported. Validating a scenario
(:func:`scenario_model`) imports the schema only; running it (:func:`get_system`) the system.
Figures live in ``proxops.plotting.<name>`` (see :mod:`proxops.plotting.systems`).

The systems fill this registry, it holds no table of them: every module of the
``proxops.systems`` package except the helpers in ``_HELPERS`` is a system whose name is
the module name with ``_`` written ``-`` (``station_keeping`` -> ``station-keeping``),
and other packages add systems through the ``proxops.systems`` entry-point group
(``name = "package.module"``; such a module registers the system, whose ``Scenario`` is then
the schema). Modules are found without importing them and imported only when used, so
``proxops scenarios`` does not import CasADi.
"""

from __future__ import annotations

import importlib
import importlib.util
import pkgutil

from proxops.errors import input_error

SYSTEMS_PACKAGE = "proxops.systems"
SCHEMA_PACKAGE = "proxops.systems.schema"
ENTRY_POINT_GROUP = "proxops.systems"
_HELPERS = {"common", "base", "cortex_loop", "cortex_setup", "full_truth"}  # modules of proxops.systems that are not systems (shared builders, SystemBase, the cortex closed loop and set-up)


def _discover(package: str) -> dict[str, str]:
    """Built-in system name -> module of ``package`` (found, not imported; subpackages skipped)."""
    spec = importlib.util.find_spec(package)
    found = {}
    for info in pkgutil.iter_modules(spec.submodule_search_locations if spec else []):
        if not info.name.startswith("_") and not info.ispkg and info.name not in _HELPERS:
            found[info.name.replace("_", "-")] = f"{package}.{info.name}"
    return dict(sorted(found.items()))


def plugin_modules() -> dict[str, str]:
    """Systems other packages declare in the ``proxops.systems`` entry-point group (read on demand:
    importlib.metadata costs ~50 ms, so the built-in names never wait for it)."""
    try:
        from importlib.metadata import entry_points

        return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}
    except Exception:  # noqa: BLE001 - broken third-party metadata never hides the built-ins
        return {}


SYSTEM_MODULES = _discover(SYSTEMS_PACKAGE)
SCHEMA_MODULES = _discover(SCHEMA_PACKAGE)

_SYSTEMS: dict[str, object] = {}
_SCENARIOS: dict[str, type] = {}
_CHECKS: dict[str, object] = {}


def register_scenario(name: str):
    """Class decorator: register the ``Scenario`` model of system ``name`` (in its schema module)."""

    def decorate(cls):
        _SCENARIOS[name] = cls
        return cls

    return decorate


def register_check(name: str):
    """Function decorator (in a schema module): the build-free check of system ``name``'s scenarios,
    ``check(sc) -> bool``. It raises the same one-line ProxopsInputError as the system's build (and
    its step count) would for every check it covers, and returns True when it covered all the checks
    the build makes for ``sc``, False when ``sc`` uses a part only the build checks (then
    :func:`check_without_build` says so and the caller builds). Plain Python and numpy: no numba,
    no plant, no solver."""

    def decorate(fn):
        _CHECKS[name] = fn
        return fn

    return decorate


def check_without_build(sc) -> bool:
    """Run the build-free check of ``sc``'s system (:func:`register_check`); True when it covered
    every check of the build, False when the system has none or ``sc`` needs the build."""
    scenario_model(sc.system)  # imports the schema module, which registers the check
    check = _CHECKS.get(sc.system)
    return bool(check(sc)) if check is not None else False


def register_system(name: str):
    """Class decorator: instantiate and register a system under ``name``."""

    def decorate(cls):
        _SYSTEMS[name] = cls()
        return cls

    return decorate


def system_module(name: str) -> str:
    """The module that registers system ``name`` (found, not imported); ProxopsInputError if none."""
    if name in _SYSTEMS:
        return type(_SYSTEMS[name]).__module__
    module = SYSTEM_MODULES.get(name) or plugin_modules().get(name)
    if module is None:
        allowed = sorted({**SYSTEM_MODULES, **plugin_modules()})
        raise input_error("system", name, f"allowed: {', '.join(allowed)}")
    return module


def get_system(name: str):
    """The system object of ``name`` (imports its system module: the engine, plants, controllers)."""
    if name not in _SYSTEMS:
        importlib.import_module(system_module(name))
    return _SYSTEMS[name]


def scenario_model(name: str) -> type:
    """The pydantic ``Scenario`` model of system ``name``: its schema module only when it has one
    (validation imports no engine), else the system's own ``Scenario`` (plug-ins, test systems)."""
    if name not in _SCENARIOS and name in SCHEMA_MODULES:
        importlib.import_module(SCHEMA_MODULES[name])
    if name in _SCENARIOS:
        return _SCENARIOS[name]
    return get_system(name).Scenario
