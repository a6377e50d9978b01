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

import atexit
import json
import os
import sys

ENV = "PROXOPS_WARM_SCENARIO"


def warm_up(scenario: str, overrides=()) -> bool:
    """Load and build ``scenario`` with ``overrides`` in this process; True if it built."""
    try:
        from proxops.scenarios.loader import load_scenario

        loaded = load_scenario(scenario, list(overrides))
        loaded.system.check(loaded.scenario)
        return True
    except Exception:  # noqa: BLE001 - reported by the workers' own check, never here
        return False


def _exit_server_without_teardown(server_pid: int) -> None:
    """atexit handler of the fork server: end it without the interpreter's teardown of the modules
    it imported for the warm-up (0.3-0.5 s with numba's kernels loaded, measured), during which it
    still holds the stdout/stderr it inherited, so a reader of the command's output (a pipe,
    ``| jq``) waited that long after the command had exited. Workers forked from the server
    inherit the handler and skip it (they end through ``exec.backends._worker_exit``)."""
    if os.getpid() != server_pid:
        return
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(0)


def _from_environment() -> None:
    text = os.environ.pop(ENV, None)
    if not text:
        return
    atexit.register(_exit_server_without_teardown, os.getpid())
    try:
        spec = json.loads(text)
        warm_up(str(spec["scenario"]), [str(o) for o in spec.get("overrides", ())])
    except Exception:  # noqa: BLE001 - a malformed variable only skips the warm-up
        pass


_from_environment()
