"""Quick exit of the local pool's fork server (see ``START_METHOD`` in :mod:`proxops.exec.backends`).

The fork server is the first module :func:`proxops.exec.backends._new_pool` has it import. When the
parent process ends, the server leaves its loop with ``SystemExit`` and Python tears down every
module it imported -- with numba's kernels loaded by the warm-up that took 0.3-0.5 s (measured),
during which the server still holds the parent's stderr open: ``proxops mc ... | tee`` or a
``subprocess.run`` capturing the output waited that long after ``proxops`` itself had exited.
Imported in the server, this module registers an atexit handler (the first registered, so the last
run) that ends the server with ``os._exit(0)``. The server writes no files: the socket it listens on
lives in the parent's temporary folder, which the parent removes. Imported anywhere else (a worker,
a test) it does nothing.
"""

from __future__ import annotations

import atexit
import os
import sys


def _in_fork_server() -> bool:
    """True while ``multiprocessing.forkserver.main`` is importing its preload modules."""
    frame = sys._getframe(1)
    while frame is not None:
        code = frame.f_code
        if code.co_name == "main" and code.co_filename.endswith(os.path.join("multiprocessing", "forkserver.py")):
            return True
        frame = frame.f_back
    return False


def exit_without_teardown() -> None:
    """Flush stdout/stderr and end this process with ``os._exit(0)``: no teardown of the modules
    (the fork server's and the pool workers' last atexit handler)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(0)


def _exit_now(pid: int) -> None:
    if os.getpid() != pid:  # a process forked from the server (they end with os._exit anyway)
        return
    exit_without_teardown()


SERVER_PID: int | None = None  # the fork server's pid, in the server and the workers forked from it
if _in_fork_server():
    SERVER_PID = os.getpid()
    atexit.register(_exit_now, SERVER_PID)
