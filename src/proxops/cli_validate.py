"""``proxops validate``: a scenario's checks (the schema, then the system's build and dispersions).

Imported by :mod:`proxops.cli` only when this command runs (its lazy command table).
"""

from __future__ import annotations

from typing import Annotated

import typer

from proxops.cli_common import emit
from proxops.scenarios.loader import check_scenario, load_scenario


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
