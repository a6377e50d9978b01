"""Warm-up of the local pool's fork server (see ``START_METHOD`` in :mod:`proxops.exec.backends`).

``proxops mc`` lists this module last among the modules the fork server imports, with
``PROXOPS_WARM_SCENARIO`` set in the server's environment to the campaign's scenario (JSON: name or
file and the ``--set`` overrides). Importing it then builds that scenario once (``system.check``,
what each worker's :func:`proxops.analysis.campaign_worker.check_nominal` does), so every worker
forked from the server starts with the imports the build needs, its numba kernels loaded and the
per-process caches of the build filled (the hop plan, the onboard ephemeris, the prediction
blocks); without it each worker does this itself (0.3-0.5 s of CPU per srf worker, measured).

Best effort: a failure is ignored (each worker's own check reports it as the campaign's error),
and nothing is printed. Without the variable (any other import) it does nothing.
"""

from __future__ import annotations

import json
import os

from proxops.exec.prestart import ENV
from proxops.scenarios.loader import load_scenario


def warm_up(scenario: str, overrides=()) -> bool:
    """Load and build ``scenario`` with ``overrides`` in this process; True if it built."""
    try:
        loaded = load_scenario(scenario, list(overrides))
        # a system's own warm-up when it has one (a planner: its solver and caches), else its build
        getattr(loaded.system, "warm_up", loaded.system.check)(loaded.scenario)
        return True
    except Exception:  # noqa: BLE001 - reported by the workers' own check, never here
        return False


def _from_environment() -> None:
    text = os.environ.pop(ENV, None)
    if not text:
        return
    try:
        spec = json.loads(text)
        warm_up(str(spec["scenario"]), [str(o) for o in spec.get("overrides", ())])
    except Exception:  # noqa: BLE001 - a malformed variable only skips the warm-up
        pass


_from_environment()
