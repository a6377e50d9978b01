"""Target orbits from two-line element sets (TLE), propagated with the ``sgp4`` package.

A TLE is a set of SGP4 mean elements at its epoch; its state at the epoch is SGP4's output at
``tsince = 0`` in TEME, here rotated into the truth's inertial frame with
:func:`proxops.environment.earth.teme_to_eci_matrix` and returned as an osculating Cartesian
state (m, m/s). SGP4 itself is the ``sgp4`` package's (Vallado's reference code, WGS-72
constants as the element sets are fitted with); nothing of it is written here.

Checked before SGP4 sees a line (the C++ parser accepts malformed lines and returns NaN): the
column layout of each line (NORAD two-line format), its modulo-10 checksum (digits, '-' counts
1), the same catalogue number on both lines, an epoch in 1972-01-01 .. 2099-12-31 (the range of
:mod:`proxops.environment.epochs`; two-digit years 57-99 are 1957-1999, 00-56 2000-2056) and
SGP4's error code at the epoch (e.g. 6: decayed). Every problem is one line naming the line.

Shipped fixture: ``data/iss-2008-264.tle``, a published ISS element set (2008-09-20, the
NORAD format's standard worked example).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from functools import lru_cache
from pathlib import Path

import numpy as np

from proxops.environment.earth import teme_to_eci_matrix
from proxops.environment.epochs import MAX_YEAR, MIN_YEAR, parse_epoch
from proxops.errors import ProxopsInputError

DATA_DIR = Path(__file__).parent / "data"
ISS_TLE = DATA_DIR / "iss-2008-264.tle"

_LINE1 = re.compile(
    r"^1 (?P<satnum>[0-9A-Z][0-9]{4})[UCS ] .{8} (?P<yy>[0-9]{2})(?P<day>[ 0-9]{3}\.[0-9]{8}) "
    r"[ +-]\.[0-9]{8} [ +-][0-9]{5}[+-][0-9] [ +-][0-9]{5}[+-][0-9] [ 0-9] [ 0-9]{4}[0-9]$"
)
_LINE2 = re.compile(
    r"^2 (?P<satnum>[0-9A-Z][0-9]{4}) [ 0-9]{3}\.[ 0-9]{4} [ 0-9]{3}\.[ 0-9]{4} [0-9]{7} [ 0-9]{3}\.[ 0-9]{4} "
    r"[ 0-9]{3}\.[ 0-9]{4} [ 0-9]{2}\.[0-9]{8}[ 0-9]{5}[0-9]$"
)
FORMAT_HINT = {1: "1 NNNNNC NNNNNAAA NNNNN.NNNNNNNN +.NNNNNNNN +NNNNN-N +NNNNN-N N NNNNN",
               2: "2 NNNNN NNN.NNNN NNN.NNNN NNNNNNN NNN.NNNN NNN.NNNN NN.NNNNNNNNNNNNNN"}


class TleError(ValueError):
    """A TLE problem, one line naming the TLE line (a ValueError, so the schema reports it)."""


@dataclass(frozen=True)
class TleOrbit:
    """The state of a TLE at its epoch: ``epoch_utc`` (ISO 8601, microseconds, the epoch of
    the element set rounded to 1 us), ``state_eci`` (6,) m, m/s in the truth's inertial frame,
    ``state_teme`` (6,) SGP4's TEME output, ``satnum``, ``name`` (title line or '')."""

    epoch_utc: str
    state_eci: np.ndarray
    state_teme: np.ndarray
    satnum: str
    name: str


def checksum(line: str) -> int:
    """Modulo-10 checksum of the first 68 columns (digits count their value, '-' counts 1)."""
    return sum(int(c) if c.isdigit() else (1 if c == "-" else 0) for c in line[:68]) % 10


def split_lines(lines) -> tuple[str, str, str]:
    """``(name, line1, line2)`` of 2 lines or 3 (title line first); blank lines are ignored."""
    if isinstance(lines, str) or not all(isinstance(x, str) for x in lines):
        raise TleError("must be a list of 2 strings (TLE lines 1 and 2), or 3 with the title line first")
    rows = [x.rstrip("\r\n") for x in lines if x.strip()]
    if len(rows) == 3:
        return rows[0].strip(), rows[1].rstrip(), rows[2].rstrip()
    if len(rows) == 2:
        return "", rows[0].rstrip(), rows[1].rstrip()
    raise TleError(f"has {len(rows)} non-blank lines: give TLE lines 1 and 2 (and optionally a title line first)")


def _check_line(k: int, line: str, pattern: re.Pattern) -> re.Match:
    if len(line) != 69:
        raise TleError(f"line {k} has {len(line)} characters, a TLE line has 69")
    m = pattern.match(line)
    if m is None:
        raise TleError(f"line {k} does not follow the TLE column layout {FORMAT_HINT[k]!r}")
    if int(line[68]) != checksum(line):
        raise TleError(f"line {k} checksum: the last digit is {line[68]} but the line tallies to {checksum(line)} "
                       "(a damaged or edited line)")
    return m


def tle_epoch_iso(yy: int, day_of_year: float) -> str:
    """ISO 8601 UTC (microseconds) of a TLE epoch: two-digit year (57-99: 19xx) and day of year
    (1.0 = January 1, 0 h)."""
    year = 1900 + yy if yy >= 57 else 2000 + yy
    if not MIN_YEAR <= year <= MAX_YEAR:
        raise TleError(f"line 1 epoch year {year} is outside the supported range {MIN_YEAR}-01-01 .. "
                       f"{MAX_YEAR}-12-31 (leap-second table and ephemeris)")
    days_in_year = 366 if (year % 4 == 0 and (year % 100 != 0 or year % 400 == 0)) else 365
    if not 1.0 <= day_of_year < days_in_year + 1:
        raise TleError(f"line 1 epoch day {day_of_year} is not a day of {year} (1.0 to {days_in_year + 1} exclusive)")
    us = round((day_of_year - 1.0) * 86400e6)
    when = datetime(year, 1, 1, tzinfo=timezone.utc) + timedelta(microseconds=us)
    return when.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


@lru_cache(maxsize=64)
def _tle_orbit(name: str, line1: str, line2: str) -> TleOrbit:
    m1 = _check_line(1, line1, _LINE1)
    m2 = _check_line(2, line2, _LINE2)
    if m1["satnum"] != m2["satnum"]:
        raise TleError(f"line 2 catalogue number {m2['satnum']!r} differs from line 1's {m1['satnum']!r}")
    iso = tle_epoch_iso(int(m1["yy"]), float(m1["day"]))
    epoch = parse_epoch(iso)
    from sgp4.api import SGP4_ERRORS, WGS72, Satrec  # third-party, loaded only for a TLE

    sat = Satrec.twoline2rv(line1, line2, WGS72)
    err, r_km, v_kms = sat.sgp4(epoch.jd_utc_day, epoch.jd_utc_frac)
    if err != 0 or not all(math.isfinite(c) for c in (*r_km, *v_kms)):
        raise TleError(f"SGP4 rejects the element set at its epoch {iso} (error {err}: "
                       f"{SGP4_ERRORS.get(err, 'non-finite state')})")
    teme = np.array([*r_km, *v_kms], dtype=float) * 1e3
    rot = teme_to_eci_matrix(epoch)
    eci = np.concatenate([rot @ teme[:3], rot @ teme[3:]])
    return TleOrbit(iso, eci, teme, m1["satnum"], name)


def tle_orbit(lines) -> TleOrbit:
    """:class:`TleOrbit` of a TLE given as 2 lines (or 3, title first). Raises :class:`TleError`."""
    name, line1, line2 = split_lines(lines)
    try:
        return _tle_orbit(name, line1, line2)
    except ProxopsInputError as exc:  # epoch checks of proxops.environment.epochs
        raise TleError(str(exc)) from None


def read_tle_file(path: str | Path) -> list[str]:
    """The lines of a TLE file (2 or 3 lines; the first element set if it holds several)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="ascii")
    except FileNotFoundError:
        raise TleError("no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TleError(f"cannot be read as an ASCII TLE file ({type(exc).__name__})") from None
    rows = [x.rstrip() for x in text.splitlines() if x.strip()]
    if len(rows) >= 3 and not rows[0].startswith("1 ") and rows[1].startswith("1 "):
        return rows[:3]
    return rows[:2] if len(rows) >= 2 and rows[0].startswith("1 ") else rows
