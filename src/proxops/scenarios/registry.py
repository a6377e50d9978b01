"""Systems by name. A system turns a validated scenario into a simulator Setup.

A system object has ``Scenario`` (a pydantic model subclassing ScenarioBase),
``build(sc) -> Setup`` and ``summarize(sc, result) -> dict`` (the other hooks default in
:class:`proxops.systems.base.SystemBase`); it registers itself with
``@register_system(name)`` when its module is imported. Figures live in
``proxops.plotting.<name>`` (see :mod:`proxops.plotting.systems`).

The systems fill this registry, it holds no table of them: every module of the
``proxops.systems`` package except the helpers in ``_HELPERS`` is a system whose name is
the module name with ``_`` written ``-`` (``station_keeping`` -> ``station-keeping``),
and other packages add systems through the ``proxops.systems`` entry-point group
(``name = "package.module"``). Modules are found without importing them and imported
only when their system is used, so ``proxops scenarios`` does not import CasADi.
"""

from __future__ import annotations

import importlib
import importlib.util
import pkgutil

from proxops.errors import input_error

SYSTEMS_PACKAGE = "proxops.systems"
ENTRY_POINT_GROUP = "proxops.systems"
_HELPERS = {"common", "base", "cortex_loop", "cortex_setup"}  # modules of proxops.systems that are not systems (helpers, SystemBase, the cortex closed loop and set-up)


def _discover() -> dict[str, str]:
    """Built-in system name -> module, from the systems package (found, not imported)."""
    spec = importlib.util.find_spec(SYSTEMS_PACKAGE)
    found = {}
    for info in pkgutil.iter_modules(spec.submodule_search_locations if spec else []):
        if not info.name.startswith("_") and info.name not in _HELPERS:
            found[info.name.replace("_", "-")] = f"{SYSTEMS_PACKAGE}.{info.name}"
    return dict(sorted(found.items()))


def plugin_modules() -> dict[str, str]:
    """Systems other packages declare in the ``proxops.systems`` entry-point group (read on demand:
    importlib.metadata costs ~50 ms, so the built-in names never wait for it)."""
    try:
        from importlib.metadata import entry_points

        return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}
    except Exception:  # noqa: BLE001 - broken third-party metadata never hides the built-ins
        return {}


SYSTEM_MODULES = _discover()

_SYSTEMS: dict[str, object] = {}


def register_system(name: str):
    """Class decorator: instantiate and register a system under ``name``."""

    def decorate(cls):
        _SYSTEMS[name] = cls()
        return cls

    return decorate


def get_system(name: str):
    if name not in _SYSTEMS:
        module = SYSTEM_MODULES.get(name) or plugin_modules().get(name)
        if module is None:
            allowed = sorted({**SYSTEM_MODULES, **plugin_modules()})
            raise input_error("system", name, f"allowed: {', '.join(allowed)}")
        importlib.import_module(module)
    return _SYSTEMS[name]
