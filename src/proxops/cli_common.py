"""Helpers every ``proxops`` command shares: one-line input errors and JSON output."""

from __future__ import annotations

import functools
import json
import sys
from pathlib import Path

import typer

from proxops.errors import ProxopsInputError

STATE = {"debug": False}  # set by the top-level --debug option


def friendly_errors(func):
    """Turn input errors into one line on stderr and exit code 2 (traceback with --debug)."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except ProxopsInputError as exc:
            if STATE["debug"]:
                raise
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(2)

    return wrapper


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
