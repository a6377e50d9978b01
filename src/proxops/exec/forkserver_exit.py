"""Quick exit of the local pool's fork server, and the end of the whole pool with its parent (see
``START_METHOD`` in :mod:`proxops.exec.backends`).

The fork server is the first module :func:`proxops.exec.backends._new_pool` has it import. When the
parent process ends, the server leaves its loop with ``SystemExit`` and Python tears down every
module it imported -- with numba's kernels loaded by the warm-up that took 0.3-0.5 s (measured),
during which the server still holds the parent's stderr open: ``proxops mc ... | tee`` or a
``subprocess.run`` capturing the output waited that long after ``proxops`` itself had exited.
Imported in the server, this module registers an atexit handler (the first registered, so the last
run) that ends the server with ``os._exit(0)``. The server writes no files: the socket it listens on
lives in the parent's temporary folder, which the parent removes. In the server it also defers
numpy's unused submodules (:func:`proxops.exec.startup.defer_when_numpy_is_imported`) before the
other preload modules import numpy. Imported anywhere else (a worker, a test) it does nothing.

Dying with the parent: a pool worker holds the write ends of its own task queue and of the fork
server's "alive" pipe, and the server and the workers hold the resource tracker's pipe, so after a
``kill -9`` of ``proxops`` none of them ever saw an end of file: the fork server, the workers and the
tracker lived on (10+ min measured) holding the caller's stdout/stderr open. :func:`die_with_parent`
chains Linux's parent-death signal: the fork server gets SIGKILL when ``proxops`` dies, each worker
when the fork server dies, and the resource tracker then reads the end of its pipe and exits.
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


PARENT_ENV = "PROXOPS_POOL_PARENT"  # pid of the process that starts the fork server (set only meanwhile)
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def die_with_parent(parent_pid: int | None) -> bool:
    """Have the kernel send SIGKILL to this process when its parent ends (``prctl(PR_SET_PDEATHSIG)``;
    strictly: when the parent's *thread* that started it ends); if the parent ``parent_pid`` has
    already ended (this process was re-parented before the call), end now. Linux only: False
    elsewhere (and when libc's ``prctl`` cannot be called), True when armed."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes
        import signal

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if parent_pid is not None and os.getppid() != parent_pid:  # the parent died before the call
        os._exit(0)
    return True


SERVER_PID: int | None = None  # the fork server's pid, in the server and the workers forked from it
if _in_fork_server():
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # as forkserver.main does after the imports: Ctrl-C is the parent's
    SERVER_PID = os.getpid()
    # numpy.f2py and numpy.testing deferred before the other preload modules import numpy (scipy, through
    # numba, reads every numpy attribute): 60-100 ms of CPU off the server's start, the critical path of a
    # campaign's start; the workers forked from it inherit the deferred modules (importlib only here)
    from proxops.exec.startup import defer_when_numpy_is_imported

    defer_when_numpy_is_imported()
    atexit.register(_exit_now, SERVER_PID)
    _parent = os.environ.pop(PARENT_ENV, None)  # set by the pool's creator when it started us from its main thread
    if _parent is not None and _parent.isdigit():
        die_with_parent(int(_parent))
