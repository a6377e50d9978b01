"""``proxops scenarios`` and ``proxops validate``: the built-in scenarios, a scenario's checks.

Imported by :mod:`proxops.cli` only when one of these commands runs (its lazy command table).
"""

from __future__ import annotations

import json
import sys
from typing import Annotated

import typer

from proxops.analysis.runs import check_scenario
from proxops.cli_common import emit
from proxops.scenarios.loader import list_builtin, load_scenario


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


def validate(
    scenario: Annotated[str, typer.Argument(help="Scenario file or built-in name.")],
    set_: Annotated[list[str], typer.Option("--set", help="Override a key: --set sim.duration_s=600.")] = [],
    as_json: Annotated[bool, typer.Option("--json")] = False,
):
    """Validate a scenario file (exit 0 if valid, 2 with a one-line error otherwise)."""
    loaded = load_scenario(scenario, set_)
    check_scenario(loaded)
    sc = loaded.scenario
    emit({"valid": True, "name": sc.name, "system": sc.system, "source": loaded.source}, as_json,
         f"{loaded.source}: valid ({sc.system} scenario '{sc.name}')")
