"""Helpers every ``proxops`` command shares: one top-level error policy and JSON output.

The error policy lives in one place, :class:`ProxopsGroup` (the click group behind the
``proxops`` typer app), so no command needs its own try/except:

- bad input (:class:`~proxops.errors.ProxopsInputError`, a wrong option type or value, an
  unknown option, a path that cannot be written): one line ``error: ...`` on stderr, exit 2;
- Ctrl-C (or SIGTERM) at any moment: one line ``interrupted...`` on stderr, exit 130;
- a failure that is not the user's (any other exception): one line ``error: internal ...``
  naming ``--debug``, exit 1. ``--debug`` shows the traceback instead.

Exit codes: 0 ok, 1 internal error or a campaign that could not go on, 2 bad input,
3 a campaign that finished but every run failed, 130 interrupted.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from typer import _click as click  # typer vendors its own click: its exceptions are these
import typer
from typer.core import TyperGroup

from proxops.errors import ProxopsInputError

STATE = {"debug": False}  # set by the top-level --debug option

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_ALL_FAILED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130


class Interrupted(KeyboardInterrupt):
    """Ctrl-C with a message for the user (e.g. how many campaign runs were saved)."""


class _CarriedInterrupt(Exception):
    """Carries a KeyboardInterrupt past typer's handler (which would exit 130 in silence)."""

    def __init__(self, interrupt: KeyboardInterrupt):
        super().__init__(str(interrupt))
        self.interrupt = interrupt


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


class ProxopsGroup(TyperGroup):
    """Typer's group with the proxops error policy (see the module docstring)."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        def call():
            rv = super(ProxopsGroup, self).main(args, prog_name, complete_var, standalone_mode=False, **extra)
            if isinstance(rv, int) and not isinstance(rv, bool) and rv == EXIT_INTERRUPTED:
                # typer turns a Ctrl-C outside ``invoke`` (parsing the command line, closing the context)
                # into a silent exit code 130: 5 of 10 Ctrl-Cs 3-5 s into `proxops mc` printed nothing
                raise KeyboardInterrupt
            return rv

        code = guarded(call)
        if standalone_mode:
            sys.exit(code)
        return code

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:
            raise _CarriedInterrupt(exc) from None


def guarded(call) -> int:
    """Run ``call()`` under the error policy; returns the exit code."""
    try:
        rv = call()
        return rv if isinstance(rv, int) and not isinstance(rv, bool) else EXIT_OK
    except typer.Exit as exc:
        return exc.exit_code
    except _CarriedInterrupt as exc:
        message = str(exc.interrupt) if isinstance(exc.interrupt, Interrupted) else ""
        typer.echo(_one_line(message) or "interrupted", err=True)
        return EXIT_INTERRUPTED
    except Interrupted as exc:
        typer.echo(_one_line(str(exc)) or "interrupted", err=True)
        return EXIT_INTERRUPTED
    except (KeyboardInterrupt, typer.Abort):
        typer.echo("interrupted", err=True)
        return EXIT_INTERRUPTED
    except click.exceptions.NoArgsIsHelpError as exc:
        exc.show()
        return EXIT_INPUT
    except click.exceptions.UsageError as exc:
        if STATE["debug"]:
            raise
        where = f" (see `{exc.ctx.command_path} --help`)" if exc.ctx is not None else ""
        typer.echo(f"error: {_one_line(exc.format_message())}{where}", err=True)
        return EXIT_INPUT
    except ProxopsInputError as exc:
        if STATE["debug"]:
            raise
        typer.echo(f"error: {_one_line(str(exc))}", err=True)
        return EXIT_INPUT
    except OSError as exc:  # a path the user gave that cannot be read or written
        if STATE["debug"]:
            raise
        if getattr(exc, "filename", None) is None:
            return _internal(exc)
        typer.echo(f"error: {exc.filename}: {exc.strerror or type(exc).__name__}", err=True)
        return EXIT_INPUT
    except Exception as exc:  # not the user's fault: say so in one line
        if STATE["debug"]:
            raise
        return _internal(exc)


def _internal(exc: BaseException) -> int:
    typer.echo(f"error: internal error {type(exc).__name__}: {_one_line(str(exc))[:300]} "
               "(run again with `proxops --debug ...` for the traceback, and please report it)", err=True)
    return EXIT_INTERNAL


def friendly_errors(func):
    """Kept for commands written against the earlier API: the policy is in :class:`ProxopsGroup`."""
    return func


def check_out_dir(path, option: str = "--out") -> Path:
    """An output folder the user named: created if missing; one-line error if it cannot be."""
    import tempfile

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ProxopsInputError(f"{option} {path}: exists and is a file; give a folder (it is created if missing)")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ProxopsInputError(f"{option} {path}: cannot create the folder ({exc.strerror or exc})") from None
    try:  # a real write: permissions, read-only file systems and quotas all show here
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise ProxopsInputError(f"{option} {path}: cannot write there ({exc.strerror or exc}); "
                                "choose another folder") from None
    return path


def json_default(obj):
    """JSON encoding of numpy scalars/arrays and paths."""
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    return str(obj)


def emit(obj: dict, as_json: bool, text: str) -> None:
    """Print ``obj`` as exactly one JSON object on stdout, or ``text`` for people."""
    if as_json:
        sys.stdout.write(json.dumps(obj, default=json_default) + "\n")
    else:
        typer.echo(text)
