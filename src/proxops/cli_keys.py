"""``proxops keys``: the scenario key reference (every section and key with unit, default,
allowed range and meaning), generated from the schema by :mod:`proxops.scenarios.reference` and read
from its checked-in output by :mod:`proxops.scenarios.key_listing` (json only: no pydantic, no numpy).

Listed in the lazy command table of :mod:`proxops.cli` (input errors -> one line, exit code 2)::

    proxops keys                      # the systems and their built-in scenarios
    proxops keys srf                  # every key of an srf scenario
    proxops keys srf --json           # the same as one JSON object
    proxops keys --all --markdown > docs/scenario-keys.md
"""

from __future__ import annotations

from typing import Annotated, Optional

import typer

from proxops.cli_common import emit
from proxops.errors import ProxopsInputError
from proxops.scenarios import key_listing as ref


def keys(
    system: Annotated[Optional[str], typer.Argument(help="System name (`proxops keys` lists them).")] = None,
    all_: Annotated[bool, typer.Option("--all", help="Every system, then the [dispersions] entries.")] = False,
    markdown: Annotated[bool, typer.Option("--markdown", help="Markdown tables (docs/scenario-keys.md is --all --markdown).")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object on stdout.")] = False,
):
    """Every scenario key of a system: unit, default, allowed range and meaning."""

    if system is not None and all_:
        raise ProxopsInputError(f"keys: give a system ({system!r}) or --all, not both")
    if markdown and as_json:
        raise ProxopsInputError("keys: give --markdown or --json, not both")
    if all_:
        if as_json:
            emit({"systems": [ref.as_dict(n) for n in ref.system_names()]}, True, "")
        elif markdown:
            typer.echo(ref.all_markdown(), nl=False)
        else:
            typer.echo("\n".join(ref.to_text(n) for n in ref.system_names()), nl=False)
        return
    if system is None:
        items = ref.list_systems()
        width = max(len(i["name"]) for i in items)
        text = "\n".join(f"{i['name']:<{width}}  {i['description']}\n{'':<{width}}  built-ins: "
                         f"{', '.join(i['scenarios']) or 'none'}" for i in items)
        emit({"systems": items}, as_json, text + "\n\n`proxops keys SYSTEM` lists the keys of one system.")
        return
    if system not in ref.system_names():
        raise ProxopsInputError(f"keys: no system {system!r}; allowed: {', '.join(ref.system_names())}")
    if as_json:
        emit(ref.as_dict(system), True, "")
    elif markdown:
        typer.echo(ref.to_markdown(system), nl=False)
    else:
        typer.echo(ref.to_text(system), nl=False)
