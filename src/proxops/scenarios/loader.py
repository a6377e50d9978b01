"""Load, override and validate scenario files; find built-in scenarios by name.

Every problem becomes one :class:`ProxopsInputError` line naming the key, the value,
its unit (from the key's suffix) and what is allowed.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ValidationError

from proxops.errors import ProxopsInputError
from proxops.scenarios.catalog import read_toml, resolve
from proxops.scenarios.dispersion_spec import SPEC_KEYS, flatten_table
from proxops.scenarios.dispersions import parse_dispersions
from proxops.scenarios.registry import check_without_build, get_system, scenario_model

UNIT_SUFFIXES = (  # longest first: "_deg_s2" before "_deg_s" before "_s"
    ("_m_per_orbit", "m/orbit"),  # a drift per orbital period (passive_safety.drift_median_m_per_orbit)
    ("_deg_s2", "deg/s^2"),
    ("_rad_s2", "rad/s^2"),
    ("_deg_s", "deg/s"),
    ("_rad_s", "rad/s"),
    ("_kgm2", "kg m^2"),
    ("_Nms", "N m s"),
    ("_Nm", "N m"),
    ("_Ns", "N s"),
    ("_mps2", "m/s^2"),
    ("_mps", "m/s"),
    ("_ms", "ms"),
    ("_deg", "deg"),
    ("_rad", "rad"),
    ("_km", "km"),
    ("_kg", "kg"),
    ("_m2", "m^2"),
    ("_m", "m"),
    ("_s", "s"),
    ("_N", "N"),
)


def unit_of(key: str) -> str:
    """Unit named by a key's suffix ('' when it has none); ``_per_<unit>`` divides by it
    (``alpha_per_s`` -> 1/s, ``q_terminal_per_m2`` -> 1/m^2, ``damping_Ns_per_m`` -> N s/m)."""
    for suffix, unit in UNIT_SUFFIXES:
        if key.endswith(suffix):
            head = key[: -len(suffix)]
            if head.endswith("_per"):
                return f"{unit_of(head[: -len('_per')]) or '1'}/{unit}"
            return unit
    return ""


def unit_of_metric(key: str) -> str:
    """Unit of a key or a dotted metric name (``solve_time_ms.median`` -> ``ms``): the last dotted
    part that carries a unit suffix ('' if none)."""
    for part in reversed(str(key).split(".")):
        unit = unit_of(part.split("[")[0])
        if unit:
            return unit
    return ""


@dataclass
class LoadedScenario:
    """A validated scenario and where it came from; ``system``: the system that runs it."""

    scenario: Any  # the system's pydantic Scenario model
    source: str

    @property
    def system(self):
        """The system object (its module, with the engine, is imported on first use: validation
        needs only the schema)."""
        return get_system(self.scenario.system)


def load_scenario(name_or_path: str, overrides: list[str] | tuple[str, ...] = ()) -> LoadedScenario:
    """Read a file or built-in, apply ``key.path=value`` overrides, validate with its system."""
    path = resolve(name_or_path)
    data = read_toml(path)
    return validate_scenario(data, overrides, source=str(path))


def validate_scenario(data: dict, overrides=(), source: str = "<dict>") -> LoadedScenario:
    system_name = data.get("system")
    if not isinstance(system_name, str):
        raise ProxopsInputError(f"{source}: missing top-level key 'system' (the system that runs this scenario)")
    model = scenario_model(system_name)
    for item in overrides:
        apply_override(data, item, model)
    try:
        scenario = model.model_validate(data)
    except ValidationError as exc:
        raise ProxopsInputError(f"{source}: {format_validation_error(exc, data)}") from None
    return LoadedScenario(scenario=scenario, source=source)


def check_scenario(loaded: LoadedScenario) -> None:
    """Every check a run makes before its first step: the schema (done when loading), the
    system's build (geometry, feasibility of the hop ladder, KOZ vs start...) and the
    dispersions table. Raises ProxopsInputError with one line; ``validate`` and ``mc`` call it. The
    schema's build-free check (:func:`proxops.scenarios.registry.check_without_build`: no numba, no
    solver) when it covers the scenario, else the system's (default: build). Here, not beside
    ``execute`` in :mod:`proxops.analysis.runs`, so ``validate`` imports no result type (numpy arrays)."""
    if not check_without_build(loaded.scenario):
        loaded.system.check(loaded.scenario)  # default: build; planners without a closed loop check without building
    parse_dispersions(loaded.scenario, loaded.scenario.dispersions)


def parse_value(text: str) -> Any:
    """A ``--set`` value as TOML (numbers, booleans, arrays, quoted strings), else a bare string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_override(data: dict, item: str, model: type[BaseModel]) -> None:
    """Apply one ``a.b.c=value`` override; the key must be a field of the scenario model
    (or, inside a free-form table such as ``dispersions``, already be in the file)."""
    if "=" not in item:
        raise ProxopsInputError(f"--set {item!r}: expected key=value, e.g. --set sim.duration_s=600")
    key, _, text = item.partition("=")
    parts = _split_key(key.strip())
    if len(parts) > 1 and parts[0] == "dispersions":
        _override_dispersion(data, key.strip(), parts[1:], parse_value(text.strip()))
        return
    node, node_model = data, model
    for depth, part in enumerate(parts):
        fields = _fields_of(node_model)
        known = part in fields if fields is not None else part in node
        if not known:
            allowed = sorted(fields) if fields is not None else sorted(node)
            where = ".".join(parts[:depth]) or "the top level"
            raise ProxopsInputError(f"--set {key}: no key {part!r} in {where}; allowed: {', '.join(allowed) or '(none)'}")
        if depth == len(parts) - 1:
            node[part] = parse_value(text.strip())
            for other in getattr(node_model, "keys_replaced_by", lambda _key: ())(part):  # e.g. orbit.tle
                node.pop(other, None)
            return
        node = node.setdefault(part, {})
        if not isinstance(node, dict):
            raise ProxopsInputError(f"--set {key}: {'.'.join(parts[: depth + 1])} is a value, not a table")
        node_model = fields.get(part) if fields is not None else None


def _split_key(key: str) -> list[str]:
    """``a."b.c".d`` -> ``["a", "b.c", "d"]`` (TOML-style quoted parts may contain dots)."""
    parts, buf, quote = [], "", None
    for ch in key:
        if quote:
            if ch == quote:
                quote = None
            else:
                buf += ch
        elif ch in "\"'":
            quote = ch
        elif ch == ".":
            parts.append(buf.strip())
            buf = ""
        else:
            buf += ch
    if quote:
        raise ProxopsInputError(f"--set {key}: unclosed quote in the key")
    return parts + [buf.strip()]


def _override_dispersion(data: dict, key: str, parts: list[str], value) -> None:
    """``--set dispersions.<entry>[.<field>]=value`` whatever spelling the file used for the entry
    (quoted dotted key or nested tables): the table is rewritten as ``{"a.b": {spec}}``; a value that
    is a table replaces (or adds) the whole entry, ``{}`` removes it, otherwise ``<field>`` (percent,
    sigma, ...) is set.
    The result is validated with the scenario (the entry must name an existing key)."""
    table = data.get("dispersions") or {}
    if not isinstance(table, dict):
        raise ProxopsInputError(f"--set {key}: dispersions is a value, not a table")
    flat = flatten_table(table)
    if parts[-1] in SPEC_KEYS and len(parts) > 1:
        entry, spec_key = ".".join(parts[:-1]), parts[-1]
        spec = dict(flat.get(entry) or {})
        if entry not in flat:
            raise ProxopsInputError(
                f"--set {key}: no dispersion entry {entry!r} to change; entries: {', '.join(flat) or '(none)'}; "
                f"add one whole: --set 'dispersions.\"{entry}\"={{{spec_key} = ...}}'")
        spec[spec_key] = value
        flat[entry] = spec
    elif value == {}:  # remove one entry
        entry = ".".join(parts)
        if flat.pop(entry, None) is None:
            raise ProxopsInputError(f"--set {key}: no dispersion entry {entry!r} to remove; entries: {', '.join(flat) or '(none)'}")
    else:
        entry = ".".join(parts)
        if not isinstance(value, dict):
            raise ProxopsInputError(
                f"--set {key}: a dispersion entry is a table, e.g. --set 'dispersions.\"{entry}\"={{percent = 10}}'; "
                f"or set one of its keys ({', '.join(sorted(SPEC_KEYS))})")
        flat[entry] = value
    data["dispersions"] = flat


def _fields_of(model) -> dict | None:
    """Field name -> nested model (or None) of a pydantic model class; None if not a model."""
    import typing

    if model is None:
        return None
    if isinstance(model, type) and issubclass(model, BaseModel):
        out = {}
        for name, info in model.model_fields.items():
            ann = info.annotation
            nested = None
            candidates = typing.get_args(ann) or (ann,)
            for c in candidates:
                if isinstance(c, type) and issubclass(c, BaseModel):
                    nested = c
            out[name] = nested
        return out
    return None


def format_validation_error(exc: ValidationError, data: dict) -> str:
    """First pydantic error as ``key = value unit: what is allowed``."""
    err = exc.errors()[0]
    loc = [p for p in err["loc"] if not str(p).startswith("function-")]
    names = [str(p) for p in loc if not isinstance(p, int)]
    key = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in loc).lstrip(".")
    msg = err["msg"]
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    if err["type"] == "extra_forbidden":
        return f"unknown key {key!r}: remove it or check its spelling"
    if err["type"] == "missing":
        return f"missing key {key!r}: it is required"
    value = err.get("input")
    if isinstance(value, dict):  # model-level error
        return f"{key or 'scenario'}: {msg}" if key else msg
    unit = unit_of(names[-1]) if names else ""
    allowed = msg[0].lower() + msg[1:] if msg else "not allowed"
    unit_text = f" {unit}" if unit else ""
    return f"{key} = {value!r}{unit_text}: {allowed}"
