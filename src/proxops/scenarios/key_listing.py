"""``proxops keys``: the scenario key reference, formatted from ``keys.json`` without the schema.

``keys.json`` (beside this module) is :func:`proxops.scenarios.reference.listing`, the reference
generated from the pydantic schema, written by ``python -m proxops.scenarios.reference >
src/proxops/scenarios/keys.json``; tests/test_keys.py keeps it equal to the live schema. Reading it
needs json only, so ``proxops keys`` imports neither pydantic nor numpy nor any system (0.3 s less).
The built-in scenarios of each system come from the files themselves (:mod:`proxops.scenarios.catalog`).
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

from proxops.scenarios.catalog import list_builtin

LISTING = Path(__file__).with_name("keys.json")


@cache
def listing() -> dict:
    """The checked-in reference data (see the module docstring)."""
    return json.loads(LISTING.read_text(encoding="utf-8"))


def system_names() -> list[str]:
    """Built-in systems, sorted."""
    return list(listing()["systems"])


def system_summary(name: str) -> str:
    """First sentence of the system module's docstring."""
    return listing()["systems"][name]["description"]


def list_systems() -> list[dict]:
    """``[{name, description, scenarios}]`` of the built-in systems and their built-in scenarios."""
    builtins = list_builtin()
    return [{"name": n, "description": system_summary(n),
             "scenarios": [b["name"] for b in builtins if b["system"] == n]} for n in system_names()]


def sections(system: str) -> list[dict]:
    return listing()["systems"][system]["sections"]


def as_dict(system: str) -> dict:
    """JSON form of one system's reference (``proxops keys SYSTEM --json``)."""
    return {"system": system, "description": system_summary(system), "sections": sections(system),
            "dispersions": listing()["dispersions"]}


def default_text(k: dict) -> str:
    if k["required"]:
        return "required"
    return _value_text(k["default"])


def _num(v) -> str:
    return format(v, ".10g") if isinstance(v, float) else str(v)


def _value_text(v) -> str:
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, float):
        return _num(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value_text(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{}" if not v else "{...}"
    return str(v)


def to_text(system: str) -> str:
    """Terminal form: one block per section, aligned columns."""
    lines = [f"system {system}: {system_summary(system)}", ""]
    for sec in [*sections(system), listing()["dispersions"]]:
        head = sec["toml"] + ("  (required)" if sec["required"] and sec["section"] else "")
        lines.append(f"{head}  {sec['meaning']}".rstrip())
        if sec["doc"]:
            lines.append(f"  {sec['doc']}")
        rows = [(k["name"], k["type"], k["unit"] or "-", default_text(k), k["allowed"] or "-", k["meaning"])
                for k in sec["keys"]]
        head_row = ("key", "type", "unit", "default", "allowed", "meaning")
        widths = [max(len(r[i]) for r in [*rows, head_row]) for i in range(5)]
        for r in [head_row, *rows]:
            lines.append("  " + "  ".join(f"{c:<{w}}" for c, w in zip(r[:5], widths)) + "  " + r[5])
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def _cell(text: str) -> str:
    return text.replace("|", "\\|") if text else ""


def _md_section(sec: dict, key_column: str = "key") -> list[str]:
    lines = []
    if sec["doc"]:
        lines += [sec["doc"], ""]
    lines += [f"| {key_column} | type | unit | default | allowed | meaning |", "| --- | --- | --- | --- | --- | --- |"]
    for k in sec["keys"]:
        lines.append(f"| `{k['key']}` | {k['type']} | {_cell(k['unit'])} | {_cell(default_text(k))} | "
                     f"{_cell(k['allowed'])} | {_cell(k['meaning'])} |")
    return lines + [""]


def to_markdown(system: str, level: int = 2) -> str:
    """Markdown form of one system's reference (tables per section)."""
    h = "#" * level
    lines = [f"{h} System `{system}`", "", system_summary(system), ""]
    scen = [i["scenarios"] for i in list_systems() if i["name"] == system][0]
    if scen:
        lines += ["Built-in scenarios: " + ", ".join(f"`{s}`" for s in scen) + ".", ""]
    for sec in sections(system):
        title = "top level" if not sec["section"] else f"`{sec['toml']}`"
        req = " (required)" if sec["required"] and sec["section"] else ""
        lines += [f"{h}# {title}{req}: {sec['meaning']}" if sec["meaning"] else f"{h}# {title}{req}", ""]
        lines += _md_section(sec)
    return "\n".join(lines)


def dispersions_markdown(level: int = 2) -> str:
    h = "#" * level
    lines = [f"{h} `[dispersions]` entries (every system)", "",
             "Each entry addresses a scenario key by its dotted path (a vector component as `key[i]`) and gives "
             "exactly one kind; values are in the addressed key's unit, and a list gives one value per component:",
             "", "```toml", "[dispersions]",
             '"initial.position_m" = {percent = 10, min_abs = 1.0}        # random, every run',
             '"navigation.position_sigma_m" = {sigma = 0.02, clip = [0.0, 1.0]}',
             '"actuator.missed_probability" = {grid = [0.05, 0.10]}         # grid axis',
             '"initial.position_m[1]" = {linspace = [-300.0, -20.0, 15]}    # grid axis on one component',
             "```", "",
             "`--set` reaches them too: `--set 'dispersions.initial.position_m.percent=5'` changes one field, "
             "`--set 'dispersions.\"initial.position_m\"={sigma = 2.0}'` replaces or adds a whole entry, "
             "`--set 'dispersions.\"initial.position_m\"={}'` removes it and `--set 'dispersions={}'` removes "
             "them all.", ""]
    return "\n".join(lines + _md_section(listing()["dispersions"], "entry key"))


def all_markdown() -> str:
    """The whole reference: docs/scenario-keys.md."""
    lines = ["# Scenario keys", "",
             "Generated by `proxops keys --all --markdown > docs/scenario-keys.md` from the scenario schema "
             "(a test keeps this file equal to the generated output). `proxops keys SYSTEM` prints one system, "
             "`--json` as one object.", "",
             "A scenario is a TOML file; `system` selects what builds it. Units come from the key suffix "
             "(`_m`, `_s`, `_mps`, `_mps2`, `_deg`, `_deg_s`, `_km`, `_kg`, `_N`; `_per_s` is 1/s); keys without "
             "a unit suffix are dimensionless or say their unit in the meaning. `none` as a default means the "
             "fallback the meaning describes. Unknown keys, NaN and inf are errors. Any key can be overridden "
             "from the command line: `--set section.key=value` (TOML syntax for the value).", "",
             "Systems: " + ", ".join(f"[`{n}`](#system-{n})" for n in system_names())
             + "; [`[dispersions]`](#dispersions-entries-every-system).", ""]
    for name in system_names():
        lines.append(to_markdown(name))
    lines.append(dispersions_markdown())
    return "\n".join(lines).rstrip() + "\n"
