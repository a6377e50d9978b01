"""Dispersions of a scenario's ``[dispersions]`` table: parse, check, sample.

Each entry addresses a scenario key by its dotted path (a list component with ``[i]``)
and says how that value varies from run to run. Both TOML spellings work::

    [dispersions]
    "initial.position_m" = {percent = 10, min_abs = 1.0}      # quoted dotted key
    initial.velocity_mps = {percent = 10, min_abs = 0.1}       # nested tables
    "navigation.position_sigma_m" = {sigma = 0.02, clip = [0.0, 1.0]}
    "actuator.missed_probability" = {grid = [0.05, 0.10]}       # parameter grid axis
    "initial.position_m[1]" = {linspace = [-300.0, -20.0, 15]}  # grid axis on one component

Random kinds (a fresh draw per run; vector keys draw each component):

- ``percent = p`` (+ ``min_abs``, ``distribution = "uniform"|"normal"``): offset of scale
  ``max(p/100 * |nominal_i|, min_abs_i)``, uniform in ``[-scale, +scale]`` (default) or a
  normal with that 1-sigma. Silva et al. 2026 §5: "varied by 10 % ... a minimum offset
  of 1 m for position and 0.1 m/s for velocity" -> ``{percent = 10, min_abs = 1.0}``. The
  paper does not say uniform or normal; uniform in ±10 % is the default here.
- ``sigma = s``: nominal + s N(0, 1) (absolute, same unit as the key).
- ``half_width = h``: nominal + U(-h, h).
- ``low = a, high = b``: U(a, b), replacing the nominal.
- ``choice = [v1, v2, ...]``: one of the values, equally likely.
- optional ``clip = [lo, hi]`` after any random draw (e.g. keep a probability in [0, 1]).

Grid kinds (deterministic; every grid key is one axis of a Cartesian product,
declaration order, last axis fastest; run ``i`` uses grid point ``i % n_grid``):

- ``grid = [v1, v2, ...]`` (scalars, or whole vectors for a vector key)
- ``linspace = [start, stop, n]``
- optional ``group = "name"``: grid keys of the same group vary together (one axis, equal
  lengths), e.g. the low/high error levels of Wijayatunga et al. Table 3.

Execution errors (navigation noise, thrust magnitude/pointing errors and missed thrusts,
Wijayatunga et al. Alg. 3 / Table 3) are the scenario's ``[navigation]`` and
``[actuator]`` keys; each run's own seed draws their realisation, and those keys can
themselves be dispersed or gridded here.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import BaseModel, ValidationError

from proxops.errors import ProxopsInputError
from proxops.scenarios.dispersion_spec import SPEC_KEYS, DispersionSpec, NumberOrVector, flatten_table  # noqa: F401

@dataclass
class Dispersion:
    """A parsed entry: where it points, its nominal value and how it varies."""

    key: str  # dotted path as written, e.g. "initial.position_m" or "initial.position_m[1]"
    path: tuple  # parsed tokens: str field names and int list indices
    spec: DispersionSpec
    nominal: Any  # value in the validated scenario (scalar or list)
    grid_values: list | None = None  # the axis values for grid kinds

    def columns(self) -> list[str]:
        """Row column names for this key (one per scalar component)."""
        if isinstance(self.nominal, list):
            return [f"{self.key}[{i}]" for i in range(len(self.nominal))]
        return [self.key]

    def split(self, value) -> dict[str, Any]:
        """``{column: scalar}`` of a value of this key."""
        if isinstance(self.nominal, list):
            return {f"{self.key}[{i}]": _scalar(v) for i, v in enumerate(value)}
        return {self.key: _scalar(value)}


@dataclass
class DispersionPlan:
    """All dispersions of a scenario: random ones and grid axes (each axis one key, or the
    keys of one ``group`` varying together)."""

    random: list[Dispersion]
    grid: list[list[Dispersion]]

    @property
    def n_grid(self) -> int:
        return math.prod(len(axis[0].grid_values) for axis in self.grid) if self.grid else 1

    def columns(self) -> list[str]:
        return [c for axis in self.grid for d in axis for c in d.columns()] + [c for d in self.random for c in d.columns()]

    def grid_columns(self) -> list[list[str]]:
        """Column names of each grid axis."""
        return [[c for d in axis for c in d.columns()] for axis in self.grid]

    def grid_point(self, index: int) -> dict[str, Any]:
        """``{column: value}`` of grid point ``index`` (Cartesian product, last axis fastest)."""
        out: dict[str, Any] = {}
        sizes = [len(axis[0].grid_values) for axis in self.grid]
        for axis, i in zip(self.grid, _unravel(index, sizes)):
            for d in axis:
                out.update(d.split(d.grid_values[i]))
        return out

    def sample(self, rng: np.random.Generator) -> dict[str, Any]:
        """``{column: value}`` of one random draw of every random dispersion (declaration order)."""
        out: dict[str, Any] = {}
        for d in self.random:
            out.update(d.split(_draw(d, rng)))
        return out

    def values(self, run_id: int, rng: np.random.Generator) -> tuple[int, dict[str, Any]]:
        """Grid index and dispersed values of run ``run_id``."""
        g = run_id % self.n_grid
        vals = self.grid_point(g) if self.grid else {}
        vals.update(self.sample(rng))
        return g, vals


# --------------------------------------------------------------------------- parsing
_TOKEN = re.compile(r"^([A-Za-z_][A-Za-z0-9_\-]*)((?:\[\d+\])*)$")


def parse_path(key: str) -> tuple:
    """``"a.b[2].c"`` -> ``("a", "b", 2, "c")``."""
    tokens: list = []
    for part in key.split("."):
        m = _TOKEN.match(part.strip())
        if not m:
            raise ProxopsInputError(
                f"dispersions: key {key!r} is not a dotted scenario path (e.g. initial.position_m or initial.position_m[0])"
            )
        tokens.append(m.group(1))
        tokens += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    return tuple(tokens)


def nominal_value(scenario: BaseModel, path: tuple, key: str):
    """Value at ``path`` in a validated scenario; clear error if the key does not exist."""
    node: Any = scenario
    for depth, tok in enumerate(path):
        where = _where(path[:depth])
        if isinstance(tok, int):
            if not isinstance(node, (list, tuple)):
                raise ProxopsInputError(f"dispersions: key {key!r}: {where} is not a list, it has no component [{tok}]")
            if tok >= len(node):
                raise ProxopsInputError(
                    f"dispersions: key {key!r}: {where} has {len(node)} components, index [{tok}] is out of range"
                )
            node = node[tok]
        elif isinstance(node, BaseModel):
            fields = type(node).model_fields
            if tok not in fields:
                raise ProxopsInputError(
                    f"dispersions: key {key!r} does not exist in the {scenario.system!r} scenario: no {tok!r} in {where}; "
                    f"allowed: {', '.join(fields)}"
                )
            node = getattr(node, tok)
        elif isinstance(node, dict):
            if tok not in node:
                raise ProxopsInputError(
                    f"dispersions: key {key!r} does not exist: no {tok!r} in {where}; allowed: {', '.join(map(str, node)) or '(none)'}"
                )
            node = node[tok]
        elif node is None:
            raise ProxopsInputError(f"dispersions: key {key!r}: [{where}] is not set in this scenario; "
                                    f"write its values in the file before dispersing them")
        else:
            raise ProxopsInputError(f"dispersions: key {key!r}: {where} is a value, not a table")
    if isinstance(node, BaseModel) or isinstance(node, dict):
        raise ProxopsInputError(f"dispersions: key {key!r} is a whole table; address one of its values")
    if isinstance(node, tuple):
        node = list(node)
    if path and path[0] == "dispersions":
        raise ProxopsInputError("dispersions: a dispersion cannot address the dispersions table itself")
    return node


def parse_dispersions(scenario: BaseModel, table: dict | None = None) -> DispersionPlan:
    """Check every ``[dispersions]`` entry against the validated ``scenario`` and return the plan.

    Raises :class:`ProxopsInputError` naming the key for a missing key, a bad spec, a
    vector/scalar mismatch or a non-numeric nominal value for a continuous kind."""
    table = scenario.dispersions if table is None else table
    random: list[Dispersion] = []
    grid: list[list[Dispersion]] = []
    groups: dict[str, list[Dispersion]] = {}
    seen: set[str] = set()
    for key, raw in flatten_table(table or {}).items():
        path = parse_path(key)
        nominal = nominal_value(scenario, path, key)
        try:
            spec = DispersionSpec.model_validate(raw)
        except ValidationError as exc:
            err = exc.errors()[0]
            loc = ".".join(str(p) for p in err["loc"])
            msg = err["msg"].removeprefix("Value error, ")
            raise ProxopsInputError(f"dispersions.{key}{'.' + loc if loc else ''}: {msg}") from None
        d = Dispersion(key=key, path=path, spec=spec, nominal=nominal)
        _check_shapes(d)
        overlap = seen.intersection(d.columns()) or _overlaps(d, seen)
        if overlap:
            raise ProxopsInputError(f"dispersions: key {key!r} overlaps another entry ({', '.join(sorted(overlap))})")
        seen.update(d.columns())
        if spec.is_grid:
            d.grid_values = _grid_values(d)
            if spec.group is None:
                grid.append([d])
            elif spec.group in groups:
                first = groups[spec.group][0]
                if len(first.grid_values) != len(d.grid_values):
                    raise ProxopsInputError(
                        f"dispersions.{key}: group {spec.group!r} needs equal lengths, but {first.key} has "
                        f"{len(first.grid_values)} values and {key} has {len(d.grid_values)}"
                    )
                groups[spec.group].append(d)
            else:
                groups[spec.group] = [d]
                grid.append(groups[spec.group])
        else:
            random.append(d)
    return DispersionPlan(random=random, grid=grid)


def _overlaps(d: Dispersion, seen: set[str]) -> set[str]:
    """A whole-vector key and one of its components both dispersed."""
    mine = set(d.columns())
    out = set()
    for col in seen:
        for c in mine:
            if col.startswith(c + "[") or c.startswith(col + "["):
                out.add(col)
    return out


def _check_shapes(d: Dispersion) -> None:
    spec, nom, key = d.spec, d.nominal, d.key
    vector = isinstance(nom, list)
    kind = spec.kind
    if kind in ("percent", "sigma", "half_width", "low"):
        comps = nom if vector else [nom]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in comps):
            raise ProxopsInputError(
                f"dispersions.{key}: {kind} needs a numeric value, but {key} = {nom!r}; use choice or grid"
            )
        if not vector and isinstance(nom, int):
            raise ProxopsInputError(
                f"dispersions.{key}: {key} = {nom!r} is a whole number; a continuous {kind} dispersion would make it "
                "fractional: use choice = [...] or grid = [...]"
            )
        n = len(nom) if vector else 1
        for name in ("min_abs", "sigma", "half_width", "low", "high"):
            val = getattr(spec, name)
            if isinstance(val, list) and len(val) != n:
                raise ProxopsInputError(
                    f"dispersions.{key}.{name}: {len(val)} components given but {key} has {n}"
                    if vector else f"dispersions.{key}.{name}: {key} is a scalar, give one number"
                )
        if kind == "low" and np.any(np.asarray(spec.low) > np.asarray(spec.high)):
            raise ProxopsInputError(f"dispersions.{key}: low = {spec.low} must be <= high = {spec.high}")
    if kind in ("grid", "choice"):
        values = spec.grid if kind == "grid" else spec.choice
        for v in values:
            if vector and not (isinstance(v, list) and len(v) == len(nom)):
                raise ProxopsInputError(
                    f"dispersions.{key}.{kind}: {key} is a {len(nom)}-vector, so each value must be a list of "
                    f"{len(nom)} numbers (got {v!r}); or address one component as {key}[i]"
                )
            if not vector and isinstance(v, (list, dict)):
                raise ProxopsInputError(f"dispersions.{key}.{kind}: {key} is a scalar, got the value {v!r}")
    if kind == "linspace" and vector:
        raise ProxopsInputError(f"dispersions.{key}.linspace: {key} is a vector; address one component as {key}[i]")


def _grid_values(d: Dispersion) -> list:
    if d.spec.kind == "linspace":
        start, stop, n = d.spec.linspace
        return [float(v) for v in np.linspace(start, stop, int(n))]
    return list(d.spec.grid)


# --------------------------------------------------------------------------- sampling
def _draw(d: Dispersion, rng: np.random.Generator):
    spec = d.spec
    vector = isinstance(d.nominal, list)
    nom = np.asarray(d.nominal, dtype=float) if spec.kind != "choice" else None
    shape = nom.shape if nom is not None else ()
    kind = spec.kind
    if kind == "choice":
        return spec.choice[int(rng.integers(len(spec.choice)))]
    if kind == "percent":
        floor = np.broadcast_to(np.asarray(spec.min_abs if spec.min_abs is not None else 0.0, float), shape)
        scale = np.maximum(spec.percent / 100.0 * np.abs(nom), floor)
        if (spec.distribution or "uniform") == "uniform":
            value = nom + scale * rng.uniform(-1.0, 1.0, size=shape)
        else:
            value = nom + scale * rng.standard_normal(size=shape)
    elif kind == "sigma":
        value = nom + np.asarray(spec.sigma, float) * rng.standard_normal(size=shape)
    elif kind == "half_width":
        value = nom + np.asarray(spec.half_width, float) * rng.uniform(-1.0, 1.0, size=shape)
    else:  # low/high
        value = rng.uniform(np.asarray(spec.low, float), np.asarray(spec.high, float), size=shape)
    if spec.clip is not None:
        value = np.clip(value, spec.clip[0], spec.clip[1])
    return [float(v) for v in value] if vector else float(value)


# --------------------------------------------------------------------------- applying
def set_path(data: dict, path: tuple, value, scenario: BaseModel | None = None) -> None:
    """Set ``value`` at ``path`` in raw scenario ``data`` (a TOML dict), filling any part the
    file left at its default from the validated ``scenario``."""
    node: Any = data
    model_node: Any = scenario
    for depth, tok in enumerate(path[:-1]):
        model_node = _child(model_node, tok)
        nxt = path[depth + 1]
        if isinstance(tok, int):
            node = node[tok]
            continue
        if tok not in node or node[tok] is None:
            node[tok] = _dump(model_node) if model_node is not None else ({} if isinstance(nxt, str) else [])
        elif isinstance(node[tok], tuple):
            node[tok] = list(node[tok])
        node = node[tok]
    node[path[-1]] = value


def _child(node, tok):
    if node is None:
        return None
    if isinstance(tok, int):
        return node[tok] if isinstance(node, (list, tuple)) and tok < len(node) else None
    if isinstance(node, BaseModel):
        return getattr(node, tok, None)
    if isinstance(node, dict):
        return node.get(tok)
    return None


def _dump(node):
    if isinstance(node, BaseModel):
        return node.model_dump(mode="python", exclude_none=True)
    if isinstance(node, tuple):
        return list(node)
    if isinstance(node, list):
        return [_dump(v) for v in node]
    return node


def apply_values(data: dict, values: dict[str, Any], scenario: BaseModel | None = None) -> dict:
    """Raw scenario ``data`` with every ``{column: value}`` of a run set in place (returns ``data``)."""
    for column, value in values.items():
        set_path(data, parse_path(column), value, scenario)
    return data


# --------------------------------------------------------------------------- helpers
def _where(path: tuple) -> str:
    if not path:
        return "the scenario's top level"
    out = ""
    for tok in path:
        out += f"[{tok}]" if isinstance(tok, int) else (f".{tok}" if out else tok)
    return out


def _unravel(index: int, sizes: list[int]) -> list[int]:
    out = []
    for size in reversed(sizes):
        out.append(index % size)
        index //= size
    return list(reversed(out))


def _scalar(v):
    if isinstance(v, np.generic):
        return v.item()
    return v


__all__ = [
    "DispersionSpec",
    "Dispersion",
    "DispersionPlan",
    "parse_dispersions",
    "parse_path",
    "flatten_table",
    "apply_values",
    "set_path",
]
