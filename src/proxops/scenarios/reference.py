"""The scenario key reference, generated from the pydantic schema (the data ``proxops keys`` prints).

Every section and key of a system's ``Scenario`` model with its type, unit (from the key's
suffix: :func:`proxops.scenarios.loader.unit_of`, the function that names units in error
messages), default, allowed range (from the Field constraints: gt/ge/lt/le, Literal choices,
list lengths, string patterns) and the one-line meaning of its ``Field(description=...)``.
The ``[dispersions]`` entries are documented from :class:`DispersionSpec` the same way.

:func:`listing` is all of it as JSON data; ``src/proxops/scenarios/keys.json`` is that data, written
by ``python -m proxops.scenarios.reference > src/proxops/scenarios/keys.json`` (a test keeps it equal
to the live schema), so that ``proxops keys`` (:mod:`proxops.scenarios.key_listing`) answers without
importing pydantic or any schema. ``docs/scenario-keys.md`` is ``proxops keys --all --markdown``.
"""

from __future__ import annotations

import ast
import importlib.util
import inspect
import json
import sys
import types
import typing
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

import annotated_types as at
from pydantic import BaseModel
from pydantic.fields import FieldInfo

from proxops.scenarios.dispersion_spec import DispersionSpec
from proxops.scenarios.loader import unit_of
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


# --------------------------------------------------------------------------- data
def listing() -> dict:
    """Every built-in system's description and sections, and the ``[dispersions]`` entry keys, as
    JSON data (``keys.json``; :mod:`proxops.scenarios.key_listing` formats it)."""
    return {"systems": {n: {"description": system_summary(n), "sections": [asdict(s) for s in reference(n)]}
                        for n in system_names()},
            "dispersions": asdict(dispersion_reference())}


def listing_json() -> str:
    """The text of ``keys.json``."""
    return json.dumps(listing(), indent=1, ensure_ascii=False) + "\n"


if __name__ == "__main__":
    sys.stdout.write(listing_json())
