"""Systems by name. A system turns a validated scenario into a simulator Setup.

A system object has ``Scenario`` (a pydantic model subclassing ScenarioBase),
``build(sc) -> Setup``, ``summarize(sc, result) -> dict`` and optionally
``figures(sc, result, out_dir) -> list[Path]``. Modules are imported lazily so that
``proxops scenarios`` does not import CasADi.
"""

from __future__ import annotations

import importlib

SYSTEM_MODULES = {
    "station-keeping": "proxops.systems.station_keeping",
    "srf": "proxops.systems.srf",
    "los": "proxops.systems.los",
    "underactuated": "proxops.systems.underactuated",
    "cortex": "proxops.systems.cortex",
}

_SYSTEMS: dict[str, object] = {}


def register_system(name: str):
    """Class decorator: instantiate and register a system under ``name``."""

    def decorate(cls):
        _SYSTEMS[name] = cls()
        return cls

    return decorate


def get_system(name: str):
    from proxops.errors import input_error

    if name not in _SYSTEMS:
        module = SYSTEM_MODULES.get(name)
        if module is None:
            raise input_error("system", name, f"allowed: {', '.join(sorted(SYSTEM_MODULES))}")
        importlib.import_module(module)
    return _SYSTEMS[name]
