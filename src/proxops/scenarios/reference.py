"""The scenario key reference, generated from the pydantic schema (``proxops keys``).

Every section and key of a system's ``Scenario`` model with its type, unit (from the key's
suffix: :func:`proxops.scenarios.loader.unit_of`, the function that names units in error
messages), default, allowed range (from the Field constraints: gt/ge/lt/le, Literal choices,
list lengths, string patterns) and the one-line meaning of its ``Field(description=...)``.
The ``[dispersions]`` entries are documented from :class:`DispersionSpec` the same way.

``docs/scenario-keys.md`` is ``proxops keys --all --markdown``; a test keeps it equal.
"""

from __future__ import annotations

import ast
import importlib.util
import inspect
import types
import typing
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

import annotated_types as at
from pydantic import BaseModel
from pydantic.fields import FieldInfo

from proxops.scenarios.dispersion_spec import DispersionSpec
from proxops.scenarios.loader import list_builtin, unit_of
from proxops.scenarios.registry import SYSTEM_MODULES, scenario_model


@dataclass
class KeyDoc:
    """One scenario key."""

    key: str  # dotted path as written in TOML / --set, e.g. "sim.duration_s"
    name: str  # last part, e.g. "duration_s"
    type: str  # "number", "integer", "boolean", "string", "list of 3 numbers", ...
    unit: str  # from the suffix ('' when the key has none)
    default: Any  # the default value (None: "none", the documented fallback in `meaning`)
    required: bool
    allowed: str  # "> 0", ">= 1, <= 50", "one of: j2, two-body, cw", "" when anything of the type goes
    meaning: str


@dataclass
class SectionDoc:
    """One TOML table (``""`` is the top level) and its keys."""

    section: str  # dotted path, "" for the top level, "runs[]" for an array of tables
    toml: str  # how it is written: "[sim]", "[[runs]]", "(top level)"
    meaning: str  # the section field's description
    doc: str  # the section class docstring (first paragraph)
    required: bool
    keys: list[KeyDoc] = field(default_factory=list)


# --------------------------------------------------------------------------- introspection
def system_names() -> list[str]:
    """Registered systems, sorted."""
    return sorted(SYSTEM_MODULES)


def system_summary(name: str) -> str:
    """First sentence of the system module's docstring, read without importing it."""
    spec = importlib.util.find_spec(SYSTEM_MODULES[name])
    text = ast.get_docstring(ast.parse(open(spec.origin, encoding="utf-8").read())) or ""
    para = " ".join(text.split("\n\n")[0].split())
    if para.startswith("System ``") and ": " in para:
        para = para.split(": ", 1)[1]
    return para[0].upper() + para[1:] if para else ""


def list_systems() -> list[dict]:
    """``[{name, description, scenarios}]`` of the registered systems and their built-ins."""
    builtins = list_builtin()
    return [{"name": n, "description": system_summary(n),
             "scenarios": [b["name"] for b in builtins if b["system"] == n]} for n in system_names()]


def reference(system: str) -> list[SectionDoc]:
    """Sections and keys of ``system``'s scenario (raises ProxopsInputError for an unknown system)."""
    model = scenario_model(system)
    sections: list[SectionDoc] = []
    _walk(model, "", "(top level)", "keys every scenario file has", True, sections)
    return sections


def dispersion_reference() -> SectionDoc:
    """The keys of one ``[dispersions]`` entry."""
    sec = SectionDoc(section="dispersions", toml='[dispersions] "section.key" = {...}',
                     meaning="Monte Carlo spread or parameter grid of any numeric (or choice/grid: any) scenario key",
                     doc=_doc(DispersionSpec), required=False)
    for name, info in DispersionSpec.model_fields.items():
        sec.keys.append(_key_doc(name, name, info, unit=""))
    return sec


def _walk(model: type[BaseModel], path: str, toml: str, meaning: str, required: bool, out: list[SectionDoc]) -> None:
    sec = SectionDoc(section=path, toml=toml, meaning=meaning, doc=_doc(model), required=required)
    out.append(sec)
    for name, info in model.model_fields.items():
        full = f"{path}.{name}" if path else name
        nested, many = _nested_model(info.annotation)
        if name == "dispersions" and not path:
            sec.keys.append(_key_doc(full, name, info, unit=""))
            sec.keys[-1].type = "table"
            sec.keys[-1].allowed = "entries as in [dispersions] below"
            continue
        if nested is not None:
            sub = f"{full}[]" if many else full
            _walk(nested, sub, f"[[{full}]]" if many else f"[{full}]", info.description or "", info.is_required(), out)
            continue
        sec.keys.append(_key_doc(full, name, info, unit=unit_of(name)))


def _nested_model(ann) -> tuple[type[BaseModel] | None, bool]:
    """(model, is_list) if ``ann`` is a section model, an optional one or a list of them."""
    for arg in _union_args(ann):
        if isinstance(arg, type) and issubclass(arg, BaseModel):
            return arg, False
        if typing.get_origin(arg) is list:
            (item,) = typing.get_args(arg) or (None,)
            item = _strip_annotated(item)[0]
            if isinstance(item, type) and issubclass(item, BaseModel):
                return item, True
    return None, False


def _union_args(ann) -> list:
    ann = _strip_annotated(ann)[0]
    if typing.get_origin(ann) in (typing.Union, types.UnionType):
        return list(typing.get_args(ann))
    return [ann]


def _strip_annotated(ann) -> tuple[Any, list]:
    """(bare type, constraint objects) of a possibly ``Annotated`` type."""
    meta: list = []
    while typing.get_origin(ann) is typing.Annotated:
        args = typing.get_args(ann)
        ann = args[0]
        for m in args[1:]:
            meta += m.metadata if isinstance(m, FieldInfo) else [m]
    return ann, meta


def _key_doc(full: str, name: str, info: FieldInfo, unit: str) -> KeyDoc:
    required = info.is_required()
    default = None if required else info.get_default(call_default_factory=True)
    type_text, allowed = _type_and_range(info.annotation, list(info.metadata))
    return KeyDoc(key=full, name=name, type=type_text, unit=unit, default=_plain(default), required=required,
                  allowed=allowed, meaning=" ".join((info.description or "").split()))


def _type_and_range(ann, meta: list) -> tuple[str, str]:
    """Readable type and allowed range of an annotation plus its field-level constraints."""
    ann, outer = _strip_annotated(ann)
    meta = outer + meta
    args = [a for a in _union_args(ann) if a is not type(None)]
    if len(args) > 1:
        texts = [_type_and_range(a, [])[0] for a in args]
        return " or ".join(texts), _range_text(meta)
    bare, inner = _strip_annotated(args[0] if args else ann)
    meta = inner + meta
    if typing.get_origin(bare) is Literal:
        return "string", "one of: " + ", ".join(str(v) for v in typing.get_args(bare))
    if typing.get_origin(bare) is list:
        (item,) = typing.get_args(bare) or (Any,)
        item_type, item_range = _type_and_range(item, [])
        lo = next((m.min_length for m in meta if isinstance(m, at.MinLen)), None)
        hi = next((m.max_length for m in meta if isinstance(m, at.MaxLen)), None)
        plural = item_type if item_type.endswith("s") or item_type == "any" else item_type + "s"
        if lo is not None and lo == hi:
            text = f"list of {lo} {plural}"
        elif lo is not None:
            text = f"list of {plural} (at least {lo}{f', at most {hi}' if hi is not None else ''})"
        else:
            text = f"list of {plural}"
        return text, (f"each {item_range}" if item_range else "")
    if typing.get_origin(bare) is dict:
        return "table", _range_text(meta)
    names = {float: "number", int: "integer", bool: "boolean", str: "string"}
    return names.get(bare, "any" if bare is Any else getattr(bare, "__name__", str(bare))), _range_text(meta)


def _range_text(meta: list) -> str:
    parts = []
    for m in meta:
        if isinstance(m, at.Gt):
            parts.append(f"> {_num(m.gt)}")
        elif isinstance(m, at.Ge):
            parts.append(f">= {_num(m.ge)}")
        elif isinstance(m, at.Lt):
            parts.append(f"< {_num(m.lt)}")
        elif isinstance(m, at.Le):
            parts.append(f"<= {_num(m.le)}")
        elif isinstance(m, at.MinLen):
            parts.append(f"length >= {m.min_length}")
        elif isinstance(m, at.MaxLen):
            parts.append(f"length <= {m.max_length}")
        elif getattr(m, "pattern", None):
            parts.append(f"matches {m.pattern}")
    return ", ".join(parts)


def _doc(model: type) -> str:
    doc = inspect.getdoc(model) or ""
    if model.__doc__ is None or doc == inspect.getdoc(BaseModel):
        return ""
    return " ".join(doc.split("\n\n")[0].split()).replace("``", "`")


def _num(v) -> str:
    return format(v, ".10g") if isinstance(v, float) else str(v)


def _plain(v):
    if isinstance(v, BaseModel):
        return v.model_dump()
    if isinstance(v, tuple):
        return list(v)
    return v


# --------------------------------------------------------------------------- output
def as_dict(system: str) -> dict:
    """JSON form of one system's reference (``proxops keys SYSTEM --json``)."""
    return {"system": system, "description": system_summary(system),
            "sections": [asdict(s) for s in reference(system)], "dispersions": asdict(dispersion_reference())}


def default_text(k: KeyDoc) -> str:
    if k.required:
        return "required"
    return _value_text(k.default)


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
    for sec in [*reference(system), dispersion_reference()]:
        head = sec.toml + ("  (required)" if sec.required and sec.section else "")
        lines.append(f"{head}  {sec.meaning}".rstrip())
        if sec.doc:
            lines.append(f"  {sec.doc}")
        rows = [(k.name, k.type, k.unit or "-", default_text(k), k.allowed or "-", k.meaning) for k in sec.keys]
        head_row = ("key", "type", "unit", "default", "allowed", "meaning")
        widths = [max(len(r[i]) for r in [*rows, head_row]) for i in range(5)]
        for r in [head_row, *rows]:
            lines.append("  " + "  ".join(f"{c:<{w}}" for c, w in zip(r[:5], widths)) + "  " + r[5])
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def _cell(text: str) -> str:
    return text.replace("|", "\\|") if text else ""


def _md_section(sec: SectionDoc, key_column: str = "key") -> list[str]:
    lines = []
    if sec.doc:
        lines += [sec.doc, ""]
    lines += [f"| {key_column} | type | unit | default | allowed | meaning |", "| --- | --- | --- | --- | --- | --- |"]
    for k in sec.keys:
        lines.append(f"| `{k.key}` | {k.type} | {_cell(k.unit)} | {_cell(default_text(k))} | {_cell(k.allowed)} | "
                     f"{_cell(k.meaning)} |")
    return lines + [""]


def to_markdown(system: str, level: int = 2) -> str:
    """Markdown form of one system's reference (tables per section)."""
    h = "#" * level
    lines = [f"{h} System `{system}`", "", system_summary(system), ""]
    scen = [i["scenarios"] for i in list_systems() if i["name"] == system][0]
    if scen:
        lines += ["Built-in scenarios: " + ", ".join(f"`{s}`" for s in scen) + ".", ""]
    for sec in reference(system):
        title = "top level" if not sec.section else f"`{sec.toml}`"
        req = " (required)" if sec.required and sec.section else ""
        lines += [f"{h}# {title}{req}: {sec.meaning}" if sec.meaning else f"{h}# {title}{req}", ""]
        lines += _md_section(sec)
    return "\n".join(lines)


def dispersions_markdown(level: int = 2) -> str:
    h = "#" * level
    sec = dispersion_reference()
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
    return "\n".join(lines + _md_section(sec, "entry key"))


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
