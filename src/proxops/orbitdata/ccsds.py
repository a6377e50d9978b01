"""CCSDS Orbit Data Messages in KVN (CCSDS 502.0-B-2, ODM 2.0): OPM read, OEM write and read.

* :func:`read_opm` -- the state vector of an Orbit Parameter Message (keys of ODM 2.0 tables
  3-1 and 3-3; a missing key is one line naming it; Keplerian, covariance and manoeuvre
  blocks are ignored). Accepted: CENTER_NAME = EARTH; REF_FRAME = EME2000, GCRF or ICRF (taken
  as the truth's inertial frame, whose axes are J2000 mean equator and equinox: the GCRF-EME2000
  frame bias of 0.023 arcsec, ~0.8 m at 7000 km, is neglected) or TEME (rotated by
  :func:`proxops.environment.earth.teme_to_eci_matrix`); TIME_SYSTEM = UTC, TAI, TT or GPS.
* :func:`write_oem` -- one Orbit Ephemeris Message per object (ODM 2.0 sec. 5: an OEM holds
  one object; segments split it in time), epochs in UTC to the nanosecond, positions in km
  to 1 um and velocities in km/s to 1 nm/s, with the frame, time system and interpolation in
  the metadata.
* :func:`read_oem` -- this module's own reader (round trip); tests also parse the files with
  the independent ``oem`` package.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

from proxops.environment.epochs import parse_epoch, tai_minus_utc
from proxops.errors import ProxopsInputError

OEM_VERSION = "2.0"
INERTIAL_FRAMES = ("EME2000", "GCRF", "ICRF")
TRUTH_FRAME = "EME2000"  # the truth's inertial axes (J2000 mean equator and equinox, IAU-76/FK5)
TIME_OFFSETS_S = {"UTC": None, "TAI": 0.0, "TT": 32.184, "GPS": -19.0}  # (scale - TAI) s; UTC via leap seconds
OPM_REQUIRED = ("CCSDS_OPM_VERS", "CREATION_DATE", "ORIGINATOR", "OBJECT_NAME", "OBJECT_ID", "CENTER_NAME",
                "REF_FRAME", "TIME_SYSTEM", "EPOCH", "X", "Y", "Z", "X_DOT", "Y_DOT", "Z_DOT")
_STATE_KEYS = (("X", "km"), ("Y", "km"), ("Z", "km"), ("X_DOT", "km/s"), ("Y_DOT", "km/s"), ("Z_DOT", "km/s"))
_KEY_VALUE = re.compile(r"^\s*([A-Z0-9_]+)\s*=\s*(.*?)\s*$")
_UNIT = re.compile(r"^(.*?)\s*\[([^\]]*)\]$")
_CCSDS_TIME = re.compile(r"^(\d{4})-(\d{2})-(\d{2})T(\d{2}):(\d{2}):(\d{2})(?:\.(\d+))?Z?$")


# ---------------------------------------------------------------------------- time
def _utc_datetime_ns(iso_utc: str) -> tuple[datetime, int]:
    """(whole-second UTC datetime, nanoseconds) of an ISO 8601 UTC string (parse_epoch forms)."""
    epoch = parse_epoch(iso_utc)
    text = epoch.iso.replace(" ", "T").removesuffix("Z").removesuffix("UTC").removesuffix("+00:00").removesuffix("+0000")
    date, _, clock = text.partition("T")
    parts = clock.split(":")
    sec_text = parts[2] if len(parts) > 2 else "0"
    whole, _, frac = sec_text.partition(".")
    y, mo, d = (int(x) for x in date.split("-"))
    base = datetime(y, mo, d, int(parts[0]), int(parts[1]), tzinfo=timezone.utc) + timedelta(seconds=int(whole))
    return base, int((frac + "000000000")[:9]) if frac else 0


def utc_epochs(epoch_utc: str, t_s: np.ndarray) -> list[str]:
    """CCSDS ASCII UTC epochs (``YYYY-MM-DDThh:mm:ss.fffffffff``) of ``t_s`` s after ``epoch_utc``
    (elapsed SI seconds; a leap second inside the span is not inserted)."""
    base, ns0 = _utc_datetime_ns(epoch_utc)
    out = []
    for t in np.asarray(t_s, dtype=float):
        total = ns0 + int(round(float(t) * 1e9))
        sec, ns = divmod(total, 1_000_000_000)
        out.append((base + timedelta(seconds=sec)).strftime("%Y-%m-%dT%H:%M:%S") + f".{ns:09d}")
    return out


def seconds_between(epoch_utc: str, ccsds_time: str) -> float:
    """Elapsed s from ``epoch_utc`` to a CCSDS UTC epoch string (nanosecond arithmetic)."""
    b0, n0 = _utc_datetime_ns(epoch_utc)
    b1, n1 = _utc_datetime_ns(ccsds_time)
    return (b1 - b0).total_seconds() + (n1 - n0) * 1e-9


def _to_utc_iso(text: str, time_system: str, where: str) -> str:
    """A CCSDS epoch in ``time_system`` as an ISO UTC string (microseconds) for parse_epoch."""
    m = _CCSDS_TIME.match(text.strip())
    if m is None:
        raise ProxopsInputError(f"{where}: EPOCH = {text!r}: must be a CCSDS time YYYY-MM-DDThh:mm:ss[.fff]")
    y, mo, d, h, mi, s = (int(m.group(i)) for i in range(1, 7))
    frac = m.group(7) or ""
    try:
        when = datetime(y, mo, d, h, mi, min(s, 59), tzinfo=timezone.utc) + timedelta(
            microseconds=round(float("0." + frac) * 1e6) if frac else 0)
    except ValueError:
        raise ProxopsInputError(f"{where}: EPOCH = {text!r}: not a calendar date and time") from None
    offset = TIME_OFFSETS_S[time_system]
    if offset is not None:  # scale -> TAI -> UTC (TAI - UTC of the date)
        when -= timedelta(seconds=offset)
        when -= timedelta(seconds=tai_minus_utc(when.year, when.month, when.day) if when.year >= 1972 else 10)
    return when.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


# ---------------------------------------------------------------------------- KVN
def _kvn_pairs(text: str, where: str) -> list[tuple[int, str, str]]:
    """(line number, KEY, value) of the ``KEY = value`` lines (COMMENT and blank lines skipped)."""
    out = []
    for k, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("COMMENT"):
            continue
        m = _KEY_VALUE.match(s)
        if m is None:
            continue  # block delimiters (COVARIANCE_START...) and data lines
        out.append((k, m.group(1), m.group(2)))
    return out


def _number(key: str, value: str, unit: str, where: str, line: int) -> float:
    m = _UNIT.match(value)
    number, given_unit = (m.group(1), m.group(2).strip()) if m else (value, None)
    if given_unit is not None and given_unit.lower() != unit:
        raise ProxopsInputError(f"{where} line {line}: {key} = {value}: unit must be [{unit}]")
    try:
        x = float(number)
    except ValueError:
        raise ProxopsInputError(f"{where} line {line}: {key} = {value!r}: must be a number in {unit}") from None
    if not math.isfinite(x):
        raise ProxopsInputError(f"{where} line {line}: {key} = {value!r}: must be finite")
    return x


@dataclass(frozen=True)
class OpmState:
    """State vector of an OPM: ``epoch_utc`` (ISO, us), ``state_eci`` (6,) m, m/s in the truth's
    inertial frame, the file's ``ref_frame``, ``time_system`` and ``object_name``."""

    epoch_utc: str
    state_eci: np.ndarray
    ref_frame: str
    time_system: str
    object_name: str


def parse_opm(text: str, where: str = "OPM") -> OpmState:
    """:class:`OpmState` of OPM KVN text (see module doc); errors name ``where`` and the key."""
    pairs = _kvn_pairs(text, where)
    if not pairs or pairs[0][1] != "CCSDS_OPM_VERS":
        raise ProxopsInputError(f"{where}: not a KVN OPM: the first keyword must be CCSDS_OPM_VERS")
    values: dict[str, tuple[int, str]] = {}
    for line, key, value in pairs:
        values.setdefault(key, (line, value))
    missing = [k for k in OPM_REQUIRED if k not in values]
    if missing:
        raise ProxopsInputError(f"{where}: missing key{'s' if len(missing) > 1 else ''} {', '.join(missing)} "
                                f"(an OPM needs {', '.join(OPM_REQUIRED)})")
    center = values["CENTER_NAME"][1].upper()
    if center != "EARTH":
        raise ProxopsInputError(f"{where} line {values['CENTER_NAME'][0]}: CENTER_NAME = {center}: must be EARTH")
    frame = values["REF_FRAME"][1].upper()
    if frame not in (*INERTIAL_FRAMES, "TEME"):
        raise ProxopsInputError(f"{where} line {values['REF_FRAME'][0]}: REF_FRAME = {frame}: allowed "
                                f"{', '.join(INERTIAL_FRAMES)}, TEME")
    scale = values["TIME_SYSTEM"][1].upper()
    if scale not in TIME_OFFSETS_S:
        raise ProxopsInputError(f"{where} line {values['TIME_SYSTEM'][0]}: TIME_SYSTEM = {scale}: allowed "
                                f"{', '.join(TIME_OFFSETS_S)}")
    line, epoch_text = values["EPOCH"]
    iso = _to_utc_iso(epoch_text, scale, f"{where} line {line}")
    try:
        parse_epoch(iso, f"{where} line {line}: EPOCH")
    except ProxopsInputError as exc:
        raise ProxopsInputError(str(exc)) from None
    state = np.array([_number(k, values[k][1], u, where, values[k][0]) for k, u in _STATE_KEYS]) * 1e3
    if frame == "TEME":
        # TEME only, kept local: the scenario schema reads OPM files while validating, which must not
        # import numba (environment.earth's kernels)
        from proxops.environment.earth import teme_to_eci_matrix

        rot = teme_to_eci_matrix(iso)
        state = np.concatenate([rot @ state[:3], rot @ state[3:]])
    return OpmState(iso, state, frame, scale, values["OBJECT_NAME"][1])


def read_opm(path: str | Path) -> OpmState:
    """:func:`parse_opm` of a file (errors name the file)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ProxopsInputError(f"{p}: no such OPM file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ProxopsInputError(f"{p}: cannot be read as a KVN OPM ({type(exc).__name__})") from None
    return parse_opm(text, str(p))


# ---------------------------------------------------------------------------- OEM
@dataclass
class OemSegment:
    """One OEM segment: metadata and states (n, 6) in m, m/s at ``epochs`` (CCSDS UTC strings)."""

    object_name: str
    object_id: str
    epochs: list[str]
    states: np.ndarray
    center_name: str = "EARTH"
    ref_frame: str = TRUTH_FRAME
    time_system: str = "UTC"
    interpolation: str = "HERMITE"
    interpolation_degree: int = 5
    comments: list[str] = field(default_factory=list)


def format_oem(segments: list[OemSegment], originator: str = "proxops", comments=(), creation_date: str | None = None) -> str:
    """KVN text of an OEM (ODM 2.0 sec. 5) with the given segments (one object)."""
    if not segments or any(len(s.epochs) != len(s.states) or len(s.epochs) == 0 for s in segments):
        raise ProxopsInputError("OEM: every segment needs as many states as epochs, at least one")
    created = creation_date or datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S")
    lines = [f"CCSDS_OEM_VERS = {OEM_VERSION}"]
    lines += [f"COMMENT {c}" for c in comments]
    lines += [f"CREATION_DATE = {created}", f"ORIGINATOR = {originator}", ""]
    for s in segments:
        lines += ["META_START", *(f"COMMENT {c}" for c in s.comments),
                  f"OBJECT_NAME = {s.object_name}", f"OBJECT_ID = {s.object_id}", f"CENTER_NAME = {s.center_name}",
                  f"REF_FRAME = {s.ref_frame}", f"TIME_SYSTEM = {s.time_system}",
                  f"START_TIME = {s.epochs[0]}", f"STOP_TIME = {s.epochs[-1]}"]
        if s.interpolation:
            lines += [f"INTERPOLATION = {s.interpolation}", f"INTERPOLATION_DEGREE = {int(s.interpolation_degree)}"]
        lines += ["META_STOP", ""]
        km = np.asarray(s.states, dtype=float) / 1e3
        for e, x in zip(s.epochs, km):
            lines.append(f"{e} {x[0]: .9f} {x[1]: .9f} {x[2]: .9f} {x[3]: .12f} {x[4]: .12f} {x[5]: .12f}")
        lines.append("")
    return "\n".join(lines)


def write_oem(path: str | Path, segments: list[OemSegment], originator: str = "proxops", comments=()) -> Path:
    """Write :func:`format_oem` to ``path`` (parent folders made)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(format_oem(segments, originator, comments))
    return p


def read_oem(path: str | Path) -> list[OemSegment]:
    """Segments of a KVN OEM with 6-component state lines (covariance blocks skipped)."""
    p = Path(path)
    lines = p.read_text(encoding="utf-8").splitlines()
    if not lines or not lines[0].strip().startswith("CCSDS_OEM_VERS"):
        raise ProxopsInputError(f"{p}: not a KVN OEM: the first keyword must be CCSDS_OEM_VERS")
    segments: list[OemSegment] = []
    meta: dict | None = None
    rows: list[list[str]] = []
    in_cov = False

    def close():
        if meta is not None:
            segments.append(OemSegment(meta.get("OBJECT_NAME", ""), meta.get("OBJECT_ID", ""), [r[0] for r in rows],
                                       np.array([[float(v) for v in r[1:7]] for r in rows]).reshape(-1, 6) * 1e3,
                                       meta.get("CENTER_NAME", ""), meta.get("REF_FRAME", ""),
                                       meta.get("TIME_SYSTEM", ""), meta.get("INTERPOLATION", ""),
                                       int(meta.get("INTERPOLATION_DEGREE", 0) or 0)))

    reading_meta = False
    for k, raw in enumerate(lines, start=1):
        s = raw.strip()
        if not s or s.startswith("COMMENT"):
            continue
        if s == "META_START":
            close()
            meta, rows, reading_meta, in_cov = {}, [], True, False
        elif s == "META_STOP":
            reading_meta = False
        elif s in ("COVARIANCE_START", "COVARIANCE_STOP"):
            in_cov = s == "COVARIANCE_START"
        elif reading_meta:
            m = _KEY_VALUE.match(s)
            if m:
                meta[m.group(1)] = m.group(2)
        elif meta is not None and not in_cov and "=" not in s:
            parts = s.split()
            if len(parts) not in (7, 10):
                raise ProxopsInputError(f"{p} line {k}: a state line has an epoch and 6 (or 9) numbers")
            rows.append(parts)
    close()
    return segments
