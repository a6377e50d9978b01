"""Validated scenario sections shared by every system.

Each system subclasses :class:`ScenarioBase` and adds its own sections. Keys end in
their unit (``_m``, ``_s``, ``_mps``, ``_mps2``, ``_deg``, ``_deg_s``, ``_km``, ``_kg``,
``_N``); the loader uses the suffix to name the unit in error messages. Unknown keys
and NaN/inf values are rejected.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, create_model, field_validator, model_validator

from proxops.actuators import THRUSTER_PARAMETERS
from proxops.core.constants import EGM96_SHIPPED_DEGREE, KARMAN_LINE_KM, R_EARTH
from proxops.errors import ProxopsInputError
from proxops.frames.elements import eci_to_elements
from proxops.environment.epochs import parse_epoch
from proxops.scenarios.dispersions import parse_dispersions


class Section(BaseModel):
    """Base of every scenario section: unknown keys and NaN/inf are errors."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_assignment=True, strict=True)


Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]
NonNegative = Annotated[float, Field(ge=0.0)]
Positive = Annotated[float, Field(gt=0.0)]
Probability = Annotated[float, Field(ge=0.0, le=1.0)]


class SimSection(Section):
    """Closed-loop run length and sample time."""

    duration_s: Positive = Field(description="simulated time of one closed-loop run (srf: at least the whole approach)")
    dt_s: Positive | None = Field(None, description="engine sample time when the controller does not fix it "
                                  "(none: the system's default, e.g. srf t_orb/720, los 1 s)")
    seed: Annotated[int, Field(ge=0, le=2**63 - 1)] = Field(
        0, description="random seed of the run (navigation noise, actuator errors); mc: the campaign seed")
    check_substeps: Annotated[int, Field(ge=1, le=1000)] = Field(
        1, description="constraint checks per sample (pieces of the zero-order hold) to catch violations between samples")

    @model_validator(mode="after")
    def _sample_time_fits(self):
        if self.dt_s is not None and self.dt_s > self.duration_s:
            raise ValueError(f"sim.dt_s = {self.dt_s:g} s is longer than sim.duration_s = {self.duration_s:g} s: "
                             "the run would have no step; give dt_s <= duration_s")
        return self


MIN_PERIGEE_ALTITUDE_KM = KARMAN_LINE_KM  # lower, drag ends an orbit within a revolution


class OrbitSection(Section):
    """Target orbit: give exactly one of ``sma_km`` or ``altitude_km`` (circular altitude
    above the equatorial radius 6378.137 km; the perigee at least 100 km above it), or one source that sets the elements and the
    epoch: ``tle`` (two lines, or three with the title first), ``tle_file`` or ``opm_file``
    (CCSDS OPM, KVN). A source's state at its epoch (SGP4 output for a TLE, rotated from TEME)
    becomes the osculating elements of the truth's inertial frame
    (proxops.orbitdata); element keys given beside a source must equal what it sets
    (``--set orbit.tle=[...]`` replaces the file's element keys). File paths are relative to
    the working directory."""

    SOURCE_KEYS: ClassVar[tuple[str, ...]] = ("tle", "tle_file", "opm_file")
    DERIVED_KEYS: ClassVar[tuple[str, ...]] = ("sma_km", "altitude_km", "ecc", "inc_deg", "raan_deg", "argp_deg",
                                               "nu_deg", "epoch_utc")

    sma_km: Positive | None = Field(None, description="target semi-major axis (give this or altitude_km; perigee "
                                    "altitude >= 100 km)")
    altitude_km: float | None = Field(None, description="circular altitude above 6378.137 km, >= 100 km (give this "
                                      "or sma_km)")
    ecc: Annotated[float, Field(ge=0.0, lt=1.0)] = Field(0.0, description="target eccentricity")
    inc_deg: Annotated[float, Field(ge=0.0, le=180.0)] = Field(0.0, description="target inclination")
    raan_deg: float = Field(0.0, description="right ascension of the ascending node")
    argp_deg: float = Field(0.0, description="argument of perigee")
    nu_deg: float = Field(0.0, description="true anomaly at t = 0")
    epoch_utc: str = Field("2026-01-01T00:00:00", description="UTC epoch of t = 0, ISO 8601 (for environment models)")
    tle: list[str] | None = Field(None, description="target two-line element set [line 1, line 2] (or title "
                                  "first): sets the elements and epoch_utc (SGP4 at the TLE epoch, TEME -> inertial)")
    tle_file: str | None = Field(None, description="file holding the target TLE (2 or 3 lines), instead of tle")
    opm_file: str | None = Field(None, description="CCSDS OPM (KVN) of the target: its state vector and epoch set the "
                                 "orbit (REF_FRAME EME2000/GCRF/ICRF/TEME, CENTER_NAME EARTH)")

    @classmethod
    def keys_replaced_by(cls, key: str) -> tuple[str, ...]:
        """Keys that ``--set orbit.<key>`` removes from the section: a source replaces the
        file's elements, epoch and other source (proxops.scenarios.loader.apply_override)."""
        if key in cls.SOURCE_KEYS:
            return cls.DERIVED_KEYS + tuple(k for k in cls.SOURCE_KEYS if k != key)
        return ()

    @field_validator("tle")
    @classmethod
    def _valid_tle(cls, v):
        if v is not None:
            from proxops.orbitdata.tle import tle_orbit

            tle_orbit(v)  # TleError is a ValueError: reported as orbit.tle = [...]: line k ...
        return v

    @field_validator("tle_file", "opm_file")
    @classmethod
    def _valid_file(cls, v, info):
        if v is not None:
            _source_state(info.field_name, v)
        return v

    @model_validator(mode="before")
    @classmethod
    def _elements_from_source(cls, data):
        """A TLE/OPM source sets sma_km, ecc, the angles and epoch_utc (see the class doc)."""
        if not isinstance(data, dict):
            return data
        given = [k for k in cls.SOURCE_KEYS if data.get(k) is not None]
        if not given:
            return data
        if len(given) > 1:
            raise ValueError(f"give one orbit source, not {' and '.join('orbit.' + k for k in given)}")
        source = given[0]
        try:
            derived = _source_elements(source, data[source])
        except ValueError:
            return data  # the source's field validator reports it with its key
        for key in cls.DERIVED_KEYS:
            mine = data.get(key)
            if mine is not None and not _same_value(key, mine, derived.get(key)):
                set_by = f"{derived[key]!r}" if key in derived else "sma_km instead"
                raise ValueError(f"orbit.{key} = {mine!r} is given with orbit.{source}, which sets it ({set_by}): "
                                 f"remove orbit.{key}")
        return {**data, **derived}

    @field_validator("epoch_utc")
    @classmethod
    def _valid_epoch(cls, v):
        try:
            parse_epoch(v)
        except ProxopsInputError as exc:
            allowed = str(exc).split(": ", 1)[-1]
            raise ValueError(("must be " + allowed) if allowed.startswith("ISO") else allowed) from None
        return v

    @model_validator(mode="after")
    def _one_size_and_above_ground(self):
        if (self.sma_km is None) == (self.altitude_km is None):
            raise ValueError("give exactly one of orbit.sma_km or orbit.altitude_km")
        perigee_km = self.sma_m * (1.0 - self.ecc) / 1e3
        if perigee_km < R_EARTH / 1e3 + MIN_PERIGEE_ALTITUDE_KM:
            where = "inside the Earth" if perigee_km <= R_EARTH / 1e3 else "in the lower atmosphere"
            raise ValueError(
                f"perigee altitude {perigee_km - R_EARTH / 1e3:.1f} km is {where} (Earth radius "
                f"{R_EARTH / 1e3:.3f} km); allowed a perigee altitude >= {MIN_PERIGEE_ALTITUDE_KM:g} km: raise "
                "sma_km/altitude_km or lower ecc"
            )
        return self

    @property
    def sma_m(self) -> float:
        return self.sma_km * 1e3 if self.sma_km is not None else R_EARTH + self.altitude_km * 1e3


def _source_state(key: str, value):
    """(epoch ISO UTC, ECI state (6,) m, m/s) of an orbit source; ValueError naming the problem. The
    readers are imported here, for the scenarios with a source only (the TLE's SGP4 and TEME rotation:
    numba, erfa; the OPM parser: ~5-25 ms that validate and keys would pay for every scenario)."""
    from proxops.orbitdata.tle import read_tle_file, tle_orbit

    try:
        if key == "tle":
            o = tle_orbit(value)
        elif key == "tle_file":
            o = tle_orbit(read_tle_file(value))
        else:
            from proxops.orbitdata.ccsds import read_opm

            o = read_opm(value)
    except ProxopsInputError as exc:
        raise ValueError(str(exc)) from None
    return o.epoch_utc, o.state_eci


def _source_elements(key: str, value) -> dict:
    """[orbit] keys (sma_km, ecc, angles in deg, epoch_utc) set by an orbit source."""

    epoch, state = _source_state(key, value)
    el = eci_to_elements(state)
    return {"sma_km": el.sma / 1e3, "ecc": el.ecc, "inc_deg": math.degrees(el.inc), "raan_deg": math.degrees(el.raan),
            "argp_deg": math.degrees(el.argp), "nu_deg": math.degrees(el.true_anomaly), "epoch_utc": epoch}


def _same_value(key: str, given, derived) -> bool:
    """Whether a key given beside a source equals the value the source sets (a stored scenario)."""
    if derived is None:
        return False
    if key == "epoch_utc":
        return str(given) == str(derived)
    try:
        a, b = float(given), float(derived)
    except (TypeError, ValueError):
        return False
    if key.endswith("_deg") and key != "inc_deg":
        a, b = a % 360.0, b % 360.0
        return min(abs(a - b), 360.0 - abs(a - b)) <= 1e-9
    return abs(a - b) <= 1e-12 * max(1.0, abs(b))


class NavigationSection(Section):
    """Navigation: ``noise`` (white Gaussian on the true state, per axis, 1-sigma) or ``ekf`` (an
    extended Kalman filter on the Hill state, CW or nonlinear J2 process model, fed by a simulated sensor:
    proxops.navigation.ekf; los: the target's attitude and rate by a multiplicative EKF,
    proxops.navigation.mekf; underactuated: the planar pose, proxops.navigation.planar_ekf). The ``ekf``
    keys are ignored by ``noise`` and vice versa."""

    model: Literal["noise", "ekf"] = Field("noise", description="noise: Gaussian error on the true state; ekf: "
                                           "filter estimate from simulated sensor measurements")
    position_sigma_m: NonNegative = Field(0.0, description="noise: 1-sigma relative-position error per axis (0: perfect)")
    velocity_sigma_mps: NonNegative = Field(0.0, description="noise: 1-sigma relative-velocity error per axis (0: perfect)")
    sensor: Literal["range-bearing", "pose"] = Field(
        "range-bearing", description="ekf: range + azimuth + elevation (lidar/camera-like) or relative position (pose)")
    range_sigma_m: NonNegative = Field(0.1, description="ekf: 1-sigma of the range (range-bearing) or of each "
                                       "position axis (pose), at sigma_reference_range_m when that is set")
    angle_sigma_deg: NonNegative = Field(0.05, description="ekf: 1-sigma of azimuth and elevation (range-bearing)")
    sigma_reference_range_m: Positive | None = Field(
        None, description="ekf: range sigma grows with range: sigma (f + (1 - f) range / this) (cortex §5.1.2 form); "
        "none: constant")
    sigma_floor_fraction: Probability = Field(0.02, description="ekf: f of the range law (cortex §5.1.2: 0.02)")
    update_period_s: Positive | None = Field(None, description="ekf: sensor/filter update period, must divide the "
                                             "control period (none: the control period)")
    fov_deg: Annotated[float, Field(gt=0.0, le=180.0)] = Field(
        180.0, description="ekf: full cone angle of the sensor's field of view about its boresight, (0, 180]")
    boresight_hill: Vector3 | None = Field(None, description="ekf: sensor boresight in Hill axes (none: the line of "
                                           "sight chaser -> target at t = 0)")
    outage_probability: Probability = Field(0.0, description="ekf: probability that a measurement is lost (random outage)")
    eclipse_dropout: bool = Field(False, description="ekf: no measurement while the target is in the Earth's shadow "
                                  "(conical, proxops.environment.eclipse; orbit.epoch_utc)")
    process_model: Literal["cw", "j2"] = Field(
        "cw", description="ekf: mean prediction by the linear CW transition (cw) or by the nonlinear two-body + J2 "
        "relative motion from the known target orbit (j2, proxops.propagation.relative_predictor)")
    process_noise_m2_s3: NonNegative = Field(1e-9, description="ekf: white-acceleration power spectral density per "
                                             "axis (covers the accelerations the process model leaves out)")
    initial_position_sigma_m: Positive = Field(1.0, description="ekf: initial 1-sigma position error per axis (the "
                                               "initial estimate is drawn from it)")
    initial_velocity_sigma_mps: Positive = Field(0.01, description="ekf: initial 1-sigma velocity error per axis")
    initial_covariance: list[list[float]] | None = Field(
        None, description="ekf: full 6x6 initial covariance (SI: m^2, m^2/s, m^2/s^2), positive definite; replaces "
        "the two initial sigmas")
    command_sigma_fraction: NonNegative = Field(
        0.0, description="ekf: extra isotropic 1-sigma execution error of each commanded impulse/acceleration per "
        "axis, as a fraction of its norm, on top of the [actuator] / [errors] execution-error model the filter "
        "adds (magnitude, pointing, direction angles, missed thrusts) unless actuator_error_model is false")
    actuator_error_model: bool = Field(
        True, description="ekf: add the actuator's execution-error covariance at every command (false: the filter "
        "believes every command exactly; to study a filter that does not model its thrusters)")
    gate_probability: Annotated[float, Field(gt=0.0, lt=1.0)] = Field(
        0.9999, description="ekf: chi-square gate confidence; a measurement beyond it is rejected (an event)")
    reinit_after_rejections: Annotated[int, Field(ge=0, le=1000)] = Field(
        0, description="ekf: re-initialise after a filter collapse: when the mean NIS of the last k measurements "
        "exceeds its chi-square bound at gate_probability (k consecutive rejections always do), the next measurement "
        "restarts the filter (an event nav-reinit); 0: never")
    reinit_velocity_sigma_mps: Positive = Field(
        0.1, description="ekf: 1-sigma velocity per axis after a re-initialisation (the position comes from the "
        "measurement)")
    # --- attitude filter: los (the target's attitude and rate), underactuated (planar pose) ---
    attitude_sigma_deg: Positive = Field(
        0.5, description="ekf (los, underactuated): 1-sigma per axis of the attitude of a camera/LIDAR pose measurement")
    attitude_rate_sigma_deg_s: Positive | None = Field(
        None, description="ekf (los): also measure the target's body rate with this 1-sigma per axis (none: no rate "
        "measurement)")
    attitude_fov_deg: Annotated[float, Field(gt=0.0, le=180.0)] = Field(
        180.0, description="ekf (los, underactuated): the pose is measured while the line of sight lies within half "
        "this cone about the sensor axis (los: the target's docking axis +y_B; underactuated: the deputy's body x)")
    attitude_process_noise_rad2_s3: NonNegative = Field(
        1e-8, description="ekf (los, underactuated): white angular-acceleration power spectral density per axis, "
        "rad^2/s^3 (unmodelled torques)")
    initial_attitude_sigma_deg: Positive = Field(
        5.0, description="ekf (los, underactuated): initial 1-sigma attitude error per axis (the initial estimate is "
        "drawn from it)")
    initial_rate_sigma_deg_s: Positive = Field(
        0.2, description="ekf (los, underactuated): initial 1-sigma body-rate error per axis")
    attitude_inertia_kgm2: Annotated[list[Annotated[float, Field(gt=0.0)]], Field(min_length=3, max_length=3)] = Field(
        [1.0, 1.0, 1.0], description="ekf (los): principal moments of inertia of the target in the filter's "
        "torque-free model (only their ratios matter)")


def _actuator_fields() -> dict:
    """Fields of [actuator] from the one declaration in proxops.actuators.THRUSTER_PARAMETERS."""
    fields = {}
    for p in THRUSTER_PARAMETERS:
        bounds = {k: getattr(p, k) for k in ("ge", "gt", "le") if getattr(p, k) is not None}
        typ = Annotated[float, Field(**bounds)]
        fields[p.key] = (typ | None if p.default is None else typ, Field(p.default, description=p.description))
    return fields


ActuatorSection = create_model(
    "ActuatorSection", __base__=Section, __module__=__name__,
    __doc__="Thruster limits and execution errors (units follow the command: m/s^2 for\n    acceleration, m/s for "
            "impulses).", **_actuator_fields())


class SpacecraftSection(Section):
    """Drag and solar-pressure properties of one spacecraft (cannonball model)."""

    mass_kg: Annotated[float, Field(gt=0.0)] = Field(500.0, description="spacecraft mass (drag and SRP)")
    area_m2: Annotated[float, Field(ge=0.0)] = Field(2.0, description="cross-section seen by the flow and the Sun "
                                                     "(cannonball)")
    cd: Annotated[float, Field(gt=0.0, le=5.0)] = Field(2.2, description="drag coefficient C_D")
    cr: Annotated[float, Field(ge=0.0, le=2.0)] = Field(1.3, description="radiation-pressure coefficient C_R "
                                                        "(1 absorbing, 2 mirror)")


class TruthSection(Section):
    """Truth model for translational systems: ``cw`` (linear), ``two-body``, ``j2`` (the
    fastest nonlinear path) or ``full`` (composed force models: EGM96 harmonics to
    ``gravity_degree`` x ``gravity_order``, NRLMSISE-00 drag, Sun and Moon, SRP)."""

    model: Literal["j2", "two-body", "cw", "full"] = Field(
        "j2", description="truth dynamics: two-body + J2 (Encke), two-body, linear CW, or full (composed force models)")
    integrator: Literal["fast", "dop853", "multistep", "reference"] = Field(
        "fast", description="fast: the fastest numba path (full without srp: multistep on spans >= 324 s, else "
        "DOP853); dop853: numba adaptive DOP853; multistep (full without srp): fixed-step Adams-Bashforth-Moulton, "
        "order 6, 18 s, look-ahead harmonics; reference: scipy solve_ivp (slower, for checks)")
    gravity_degree: int = Field(20, description="full: EGM96 spherical-harmonic degree (2 to 120, shipped offline)")
    gravity_order: int | None = Field(None, description="full: harmonic order, 0 to gravity_degree "
                                      "(none: gravity_degree)")
    drag: bool = Field(True, description="full: NRLMSISE-00 drag on both spacecraft (co-rotating atmosphere)")
    third_body: bool = Field(True, description="full: Sun and Moon third-body attraction")
    srp: bool = Field(False, description="full: cannonball solar radiation pressure with the Earth's shadow")
    shadow: Literal["conical", "cylindrical"] = Field("conical", description="full: Earth shadow model for SRP")
    f107: Annotated[float, Field(ge=50.0, le=400.0)] = Field(150.0, description="full: F10.7 solar flux of the "
                                                             "previous day, sfu")
    f107a: Annotated[float, Field(ge=50.0, le=400.0)] = Field(150.0, description="full: 81-day mean F10.7, sfu")
    ap: Annotated[float, Field(ge=0.0, le=400.0)] = Field(15.0, description="full: daily geomagnetic Ap index")
    space_weather: Literal["constant", "cssi"] = Field(
        "constant", description="full: constant (f107, f107a, ap above) or cssi (the shipped CSSI history, per UT "
        "day over the run: observed F10.7 of the day before, its 81-day centred mean, daily Ap and the 3-hour ap; "
        "`proxops data` shows the range)")
    earth_orientation: Literal["model", "iers"] = Field(
        "model", description="full: model (UT1 = UTC, no polar motion) or iers (UT1 - UTC and polar motion of the "
        "epoch from the shipped IERS finals.all); both with IAU 2006/2000A precession-nutation (erfa)")
    target: SpacecraftSection = Field(SpacecraftSection(), description="target spacecraft properties (full)")
    chaser: SpacecraftSection = Field(SpacecraftSection(), description="chaser spacecraft properties (full)")

    @field_validator("gravity_degree")
    @classmethod
    def _degree(cls, v):
        if not 2 <= v <= EGM96_SHIPPED_DEGREE:
            raise ValueError(f"must be in [2, {EGM96_SHIPPED_DEGREE}] (the shipped EGM96 truncation)")
        return v

    @model_validator(mode="after")
    def _multistep_needs_full(self):
        if self.integrator == "multistep" and (self.model != "full" or self.srp):
            raise ValueError(f"integrator = 'multistep' needs model = 'full' without srp (model is '{self.model}', "
                             f"srp = {str(self.srp).lower()}); use 'fast' or 'dop853'")
        return self

    @model_validator(mode="after")
    def _order_within_degree(self):
        if self.gravity_order is not None and not 0 <= self.gravity_order <= self.gravity_degree:
            raise ValueError(
                f"gravity_order = {self.gravity_order}: must be in [0, gravity_degree = {self.gravity_degree}]"
            )
        return self


class InitialSection(Section):
    """Initial relative state of the chaser (Hill/RTN unless ``frame = "lvlh-srf"``)."""

    position_m: Vector3 = Field(description="initial relative position of the chaser, in `frame`")
    velocity_mps: Vector3 = Field([0.0, 0.0, 0.0], description="initial relative velocity of the chaser, in `frame`")
    frame: Literal["hill", "lvlh-srf"] = Field(
        "hill", description="hill: x radial, y along-track, z normal; lvlh-srf: the srf paper's x V-bar, "
        "y -orbit normal, z R-bar")

    @field_validator("position_m", "velocity_mps")
    @classmethod
    def _finite(cls, v):
        if not all(math.isfinite(c) for c in v):
            raise ValueError("all three components must be finite numbers")
        return v


class ScenarioBase(Section):
    """Keys every scenario file has. ``system`` selects the system that builds it."""

    name: str = Field(description="scenario name (shown in summaries, reports and campaign folders)")
    description: str = Field("", description="one line saying what the scenario is")
    system: str = Field(description="the system that builds and runs it (`proxops keys` lists them)")
    sim: SimSection = Field(description="run length, sample time, seed")
    navigation: NavigationSection = Field(NavigationSection(), description="navigation errors (default perfect)")
    actuator: ActuatorSection = Field(ActuatorSection(), description="thruster limits and errors (default ideal)")
    dispersions: dict[str, Any] = Field(
        {}, description="Monte Carlo spread or parameter grid: \"section.key\" = {kind = ...} entries "
        "(validated by proxops.scenarios.dispersions)")

    @model_validator(mode="after")
    def _dispersions_address_existing_keys(self):
        """Each [dispersions] entry must name a key of this scenario (proxops.scenarios.dispersions)."""
        if self.dispersions:
            parse_dispersions(self)
        return self
