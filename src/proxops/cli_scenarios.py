"""``proxops scenarios``: the built-in scenarios.

Imported by :mod:`proxops.cli` only when this command runs (its lazy command table). Reads the
built-in files with :mod:`proxops.scenarios.catalog` (tomllib): no pydantic, no numpy.
"""

from __future__ import annotations

import json
import sys
from typing import Annotated

import typer

from proxops.scenarios.catalog import list_builtin


def scenarios(as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False):
    """List the built-in scenarios."""
    items = list_builtin()
    rows = [{"name": i["name"], "description": i["description"], "system": i["system"]} for i in items]
    width = max((len(r["name"]) for r in rows), default=4)
    text = "\n".join(f"{r['name']:<{width}}  {r['description']}" for r in rows)
    if as_json:
        sys.stdout.write(json.dumps(rows) + "\n")
    else:
        typer.echo(text)
