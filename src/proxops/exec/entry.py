"""Console entry point of ``proxops``: nothing heavy is imported before Ctrl-C is handled.

A Ctrl-C at any moment (while Python imports the CLI, while a command runs, while worker
processes shut down) ends with one ``interrupted`` line and exit code 130, never a traceback.
"""

import signal
import sys

from proxops import __version__
from proxops.exec.startup import defer_when_numpy_is_imported, skip_pydantic_plugin_scan  # importlib, os only


def main() -> None:
    if sys.argv[1:] == ["--version"]:  # answered without importing the CLI (typer, numpy: 0.3 s)
        sys.stdout.write(f"proxops {__version__}\n")
        sys.exit(0)
    code = 130
    skip_pydantic_plugin_scan()
    try:
        if "mc" in sys.argv[1:] or "references" in sys.argv[1:]:  # a campaign's workers start before the CLI
            # is imported (0.13-0.25 s; `cortex references` also before its system module, 0.35-0.5 s)
            # Kept local: only a campaign needs the pool's start (multiprocessing, the scenario catalog)
            from proxops.exec.prestart import prestart_from_argv

            prestart_from_argv(sys.argv[1:])
        defer_when_numpy_is_imported()  # before scipy (through numba) reads all of numpy
        # Kept local: `--version` answers without it, and a Ctrl-C while it imports (typer, click) is caught
        from proxops.cli import run_app

        code = run_app()
    except KeyboardInterrupt:  # while importing the CLI
        sys.stderr.write("interrupted\n")
    try:
        backends = sys.modules.get("proxops.exec.backends")
        if backends is not None:  # stop kept worker processes now (terminated after a failure)
            backends.shutdown_pools(force=code != 0)
    except KeyboardInterrupt:
        code = 130
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the work is done or given up: exit quietly
    exit_without_teardown(code)


def exit_without_teardown(code: int) -> None:
    """Run the atexit handlers, flush stdout/stderr and end the process without the interpreter's
    teardown of every module: with numba's compiled kernels loaded that teardown alone took 0.3-0.9 s
    (measured) after the output was complete. Files are closed where they are written (nothing
    relies on the teardown to flush them)."""
    import atexit
    import os

    try:
        atexit._run_exitfuncs()
    except BaseException:  # a failing handler must not change the exit code
        pass
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (BrokenPipeError, OSError, ValueError):
            pass
    os._exit(code)


if __name__ == "__main__":
    main()
