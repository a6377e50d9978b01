"""Schema of one ``[dispersions]`` entry (the kinds are explained in
:mod:`proxops.scenarios.dispersions`, which parses, checks and samples them).

It lives in the scenarios layer so that the scenario schema, ``--set`` overrides and the key
reference (:mod:`proxops.scenarios.reference`) describe dispersions without importing analysis.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from proxops.errors import ProxopsInputError

SPEC_KEYS = {"percent", "min_abs", "distribution", "sigma", "half_width", "low", "high", "choice", "grid", "linspace",
             "clip", "group"}
NumberOrVector = float | list[float]


class DispersionSpec(BaseModel):
    """One ``[dispersions]`` entry: ``"section.key" = {percent = 10, min_abs = 1.0}``. Give exactly one
    kind (percent, sigma, half_width, low+high, choice, grid, linspace); values are in the addressed
    key's unit; a list gives one value per component of a vector key."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    percent: float | None = Field(
        None, ge=0.0, description="random: offset of scale max(percent/100 |nominal|, min_abs), uniform in "
        "[-scale, +scale] (or normal with that 1-sigma)")
    min_abs: NumberOrVector | None = Field(
        None, description="with percent: smallest offset scale, per component (>= 0, key's unit)")
    distribution: Literal["uniform", "normal"] | None = Field(
        None, description="with percent: shape of the offset (default uniform)")
    sigma: NumberOrVector | None = Field(None, description="random: nominal + sigma N(0, 1) (>= 0, key's unit)")
    half_width: NumberOrVector | None = Field(None, description="random: nominal + U(-half_width, +half_width) (>= 0)")
    low: NumberOrVector | None = Field(None, description="random: U(low, high), replacing the nominal (needs high)")
    high: NumberOrVector | None = Field(None, description="upper end of U(low, high) (>= low)")
    choice: list[Any] | None = Field(None, min_length=1, description="random: one of these values, equally likely")
    grid: list[Any] | None = Field(
        None, min_length=1, description="grid axis: these values (whole vectors for a vector key); run i uses "
        "grid point i mod n_grid")
    linspace: list[float] | None = Field(
        None, min_length=3, max_length=3, description="grid axis: [start, stop, n] evenly spaced values (n whole >= 1)")
    clip: list[float] | None = Field(
        None, min_length=2, max_length=2, description="after a random continuous draw: clip to [lo, hi] (lo <= hi)")
    group: str | None = Field(
        None, min_length=1, description="grid keys of one group vary together (one axis, equal lengths)")

    @model_validator(mode="after")
    def _one_kind(self):
        kinds = [k for k in ("percent", "sigma", "half_width", "low", "choice", "grid", "linspace") if getattr(self, k) is not None]
        if self.high is not None and self.low is None:
            kinds.append("high")
        if len(kinds) != 1:
            raise ValueError(
                "give exactly one of percent, sigma, half_width, low+high, choice, grid, linspace "
                f"(got {', '.join(kinds) or 'none'})"
            )
        kind = kinds[0]
        if kind in ("low", "high") and (self.low is None or self.high is None):
            raise ValueError("low and high go together: U(low, high)")
        if self.min_abs is not None and kind != "percent":
            raise ValueError("min_abs only goes with percent")
        if self.distribution is not None and kind != "percent":
            raise ValueError("distribution only goes with percent (sigma is normal, half_width/low+high uniform)")
        for name in ("min_abs", "sigma", "half_width"):
            val = getattr(self, name)
            if val is not None and any(v < 0 for v in np.atleast_1d(val)):
                raise ValueError(f"{name} must be >= 0")
        if self.linspace is not None:
            n = self.linspace[2]
            if n < 1 or n != int(n):
                raise ValueError(f"linspace = [start, stop, n] needs a whole n >= 1 (got {n})")
        if self.clip is not None and self.clip[0] > self.clip[1]:
            raise ValueError("clip = [lo, hi] needs lo <= hi")
        if self.clip is not None and kind in ("grid", "linspace", "choice"):
            raise ValueError("clip only goes with random continuous kinds")
        if self.group is not None and kind not in ("grid", "linspace"):
            raise ValueError("group only goes with grid or linspace (keys of a group vary together)")
        return self

    @property
    def kind(self) -> str:
        for k in ("percent", "sigma", "half_width", "low", "choice", "grid", "linspace"):
            if getattr(self, k) is not None:
                return k
        raise AssertionError("validated spec has a kind")

    @property
    def is_grid(self) -> bool:
        return self.kind in ("grid", "linspace")


def flatten_table(table: dict, prefix: str = "") -> dict[str, dict]:
    """Nested or dotted ``[dispersions]`` table -> ``{dotted key: spec table}``."""
    out: dict[str, dict] = {}
    for key, val in table.items():
        full = f"{prefix}.{key}" if prefix else str(key)
        if not isinstance(val, dict):
            raise ProxopsInputError(
                f"dispersions.{full} = {val!r}: expected a table such as {{percent = 10, min_abs = 1.0}} "
                f"or {{grid = [1.0, 2.0]}}; allowed keys: {', '.join(sorted(SPEC_KEYS))}"
            )
        is_spec = val and set(val) <= SPEC_KEYS and not any(isinstance(v, dict) for v in val.values())
        if is_spec:
            out[full] = val
        elif not val:
            raise ProxopsInputError(f"dispersions.{full}: empty table; give e.g. {{percent = 10}}")
        else:
            out.update(flatten_table(val, full))
    return out
