"""Validated scenario sections shared by every system.

Each system subclasses :class:`ScenarioBase` and adds its own sections. Keys end in
their unit (``_m``, ``_s``, ``_mps``, ``_mps2``, ``_deg``, ``_deg_s``, ``_km``, ``_kg``,
``_N``); the loader uses the suffix to name the unit in error messages. Unknown keys
and NaN/inf values are rejected.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from proxops.core.constants import R_EARTH


class Section(BaseModel):
    """Base of every scenario section: unknown keys and NaN/inf are errors."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_assignment=True)


Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]
NonNegative = Annotated[float, Field(ge=0.0)]
Positive = Annotated[float, Field(gt=0.0)]
Probability = Annotated[float, Field(ge=0.0, le=1.0)]


class SimSection(Section):
    """Closed-loop run length and sample time."""

    duration_s: Positive
    dt_s: Positive | None = None  # sample time when the controller does not fix it
    seed: int = 0
    check_substeps: Annotated[int, Field(ge=1, le=1000)] = 1


class OrbitSection(Section):
    """Target orbit: give exactly one of ``sma_km`` or ``altitude_km`` (circular altitude
    above the equatorial radius 6378.137 km)."""

    sma_km: Positive | None = None
    altitude_km: float | None = None
    ecc: Annotated[float, Field(ge=0.0, lt=1.0)] = 0.0
    inc_deg: Annotated[float, Field(ge=0.0, le=180.0)] = 0.0
    raan_deg: float = 0.0
    argp_deg: float = 0.0
    nu_deg: float = 0.0
    epoch_utc: str = "2026-01-01T00:00:00"

    @field_validator("epoch_utc")
    @classmethod
    def _valid_epoch(cls, v):
        from proxops.environment.epochs import parse_epoch
        from proxops.errors import ProxopsInputError

        try:
            parse_epoch(v)
        except ProxopsInputError as exc:
            raise ValueError(str(exc).split(": ", 1)[-1]) from None
        return v

    @model_validator(mode="after")
    def _one_size_and_above_ground(self):
        if (self.sma_km is None) == (self.altitude_km is None):
            raise ValueError("give exactly one of orbit.sma_km or orbit.altitude_km")
        perigee_km = self.sma_m * (1.0 - self.ecc) / 1e3
        if perigee_km <= R_EARTH / 1e3:
            raise ValueError(
                f"orbit perigee radius {perigee_km:.1f} km is inside the Earth (radius {R_EARTH / 1e3:.1f} km): "
                "raise sma_km/altitude_km or lower ecc"
            )
        return self

    @property
    def sma_m(self) -> float:
        return self.sma_km * 1e3 if self.sma_km is not None else R_EARTH + self.altitude_km * 1e3


class NavigationSection(Section):
    """Navigation errors: white Gaussian, per axis, 1-sigma."""

    position_sigma_m: NonNegative = 0.0
    velocity_sigma_mps: NonNegative = 0.0


class ActuatorSection(Section):
    """Thruster limits and execution errors (units follow the command: m/s^2 for
    acceleration, m/s for impulses)."""

    max_per_axis: Positive | None = None
    max_norm: Positive | None = None
    min_impulse: NonNegative = 0.0
    magnitude_sigma: NonNegative = 0.0
    pointing_sigma_deg: NonNegative = 0.0
    missed_probability: Probability = 0.0


class SpacecraftSection(Section):
    """Drag and solar-pressure properties of one spacecraft (cannonball model)."""

    mass_kg: Annotated[float, Field(gt=0.0)] = 500.0
    area_m2: Annotated[float, Field(ge=0.0)] = 2.0
    cd: Annotated[float, Field(gt=0.0, le=5.0)] = 2.2
    cr: Annotated[float, Field(ge=0.0, le=2.0)] = 1.3


class TruthSection(Section):
    """Truth model for translational systems: ``cw`` (linear), ``two-body``, ``j2`` (the
    fastest nonlinear path) or ``full`` (composed force models: EGM96 harmonics to
    ``gravity_degree`` x ``gravity_order``, NRLMSISE-00 drag, Sun and Moon, SRP)."""

    model: Literal["j2", "two-body", "cw", "full"] = "j2"
    integrator: Literal["fast", "reference"] = "fast"
    gravity_degree: int = 20
    gravity_order: int | None = None  # default: gravity_degree
    drag: bool = True
    third_body: bool = True  # Sun and Moon
    srp: bool = False
    shadow: Literal["conical", "cylindrical"] = "conical"
    f107: Annotated[float, Field(ge=50.0, le=400.0)] = 150.0  # sfu, previous day
    f107a: Annotated[float, Field(ge=50.0, le=400.0)] = 150.0  # sfu, 81-day mean
    ap: Annotated[float, Field(ge=0.0, le=400.0)] = 15.0  # daily Ap
    target: SpacecraftSection = SpacecraftSection()
    chaser: SpacecraftSection = SpacecraftSection()

    @field_validator("gravity_degree")
    @classmethod
    def _degree(cls, v):
        from proxops.environment.harmonics import SHIPPED_DEGREE

        if not 2 <= v <= SHIPPED_DEGREE:
            raise ValueError(f"must be in [2, {SHIPPED_DEGREE}] (the shipped EGM96 truncation)")
        return v

    @model_validator(mode="after")
    def _order_within_degree(self):
        if self.gravity_order is not None and not 0 <= self.gravity_order <= self.gravity_degree:
            raise ValueError(
                f"gravity_order = {self.gravity_order}: must be in [0, gravity_degree = {self.gravity_degree}]"
            )
        return self


class InitialSection(Section):
    """Initial relative state of the chaser (Hill/RTN unless ``frame = "lvlh-srf"``)."""

    position_m: Vector3
    velocity_mps: Vector3 = [0.0, 0.0, 0.0]
    frame: Literal["hill", "lvlh-srf"] = "hill"

    @field_validator("position_m", "velocity_mps")
    @classmethod
    def _finite(cls, v):
        if not all(math.isfinite(c) for c in v):
            raise ValueError("all three components must be finite numbers")
        return v


class ScenarioBase(Section):
    """Keys every scenario file has. ``system`` selects the system that builds it."""

    name: str
    description: str = ""
    system: str
    sim: SimSection
    navigation: NavigationSection = NavigationSection()
    actuator: ActuatorSection = ActuatorSection()
    dispersions: dict[str, Any] = {}  # validated by proxops.analysis.campaign

    @model_validator(mode="after")
    def _dispersions_address_existing_keys(self):
        """Each [dispersions] entry must name a key of this scenario (proxops.analysis.dispersions)."""
        if self.dispersions:
            from proxops.analysis.dispersions import parse_dispersions

            parse_dispersions(self)
        return self
