"""Scenario epochs: validated ISO 8601 UTC strings and the time scales the models need.

Time scales (what each model reads, and what the approximation costs):

* **UTC** -- the scenario epoch as written (``2022-05-01T00:00:00Z``). Leap seconds
  are handled through the TAI-UTC table below (IERS Bulletin C; no leap second has
  been inserted since 2017-01-01, so 37 s applies to every later epoch; a future leap
  second would shift TT by 1 s, i.e. the Sun by 0.04 arcsec and the Moon by 0.5 arcsec).
* **TT** = UTC + (TAI - UTC) + 32.184 s -- the uniform time of the Sun and Moon series
  (:mod:`proxops.environment.ephemeris`). Simulation time ``t_s`` is elapsed SI
  seconds, so TT(t) = TT(epoch) + t exactly. TDB - TT (< 1.7 ms) is neglected.
* **UT1** ~ UTC -- Earth rotation angle for the Earth-fixed gravity field and the
  co-rotating atmosphere. |UT1 - UTC| < 0.9 s by definition of UTC; 0.9 s is a
  6.6e-5 rad (13.5 arcsec) rotation of the field, 420 m at the equator, which moves
  the harmonic acceleration at LEO by < 1e-8 m/s^2 and is common to both spacecraft.
  A leap second inside a run is not applied to UT1 (same 1 s bound).

Supported epochs: 1972-01-01 (start of the leap-second UTC) to 2099-12-31, the
range of the leap-second table and of the analytic ephemeris series.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from datetime import datetime, timezone

from proxops.errors import input_error

ISO_HINT = "ISO 8601 UTC, e.g. 2022-05-01T00:00:00Z"
JD_J2000 = 2451545.0  # TT Julian date of J2000.0
SECONDS_PER_DAY = 86400.0
TT_MINUS_TAI = 32.184  # s
MIN_YEAR = 1972
MAX_YEAR = 2099

# (UTC date from which it applies, TAI - UTC in s), IERS Bulletin C (table through 2017-01-01)
LEAP_SECONDS: tuple[tuple[tuple[int, int, int], int], ...] = (
    ((1972, 1, 1), 10), ((1972, 7, 1), 11), ((1973, 1, 1), 12), ((1974, 1, 1), 13),
    ((1975, 1, 1), 14), ((1976, 1, 1), 15), ((1977, 1, 1), 16), ((1978, 1, 1), 17),
    ((1979, 1, 1), 18), ((1980, 1, 1), 19), ((1981, 7, 1), 20), ((1982, 7, 1), 21),
    ((1983, 7, 1), 22), ((1985, 7, 1), 23), ((1988, 1, 1), 24), ((1990, 1, 1), 25),
    ((1991, 1, 1), 26), ((1992, 7, 1), 27), ((1993, 7, 1), 28), ((1994, 7, 1), 29),
    ((1996, 1, 1), 30), ((1997, 7, 1), 31), ((1999, 1, 1), 32), ((2006, 1, 1), 33),
    ((2009, 1, 1), 34), ((2012, 7, 1), 35), ((2015, 7, 1), 36), ((2017, 1, 1), 37),
)  # fmt: skip

_ISO = re.compile(
    r"^(\d{4})-(\d{2})-(\d{2})[T ](\d{2}):(\d{2})(?::(\d{2})(\.\d+)?)?(Z|\+00:00|\+0000|UTC)?$"
)


def tai_minus_utc(year: int, month: int, day: int) -> int:
    """TAI - UTC (s) on a UTC date (>= 1972-01-01), from :data:`LEAP_SECONDS`."""
    value = LEAP_SECONDS[0][1]
    for date, offset in LEAP_SECONDS:
        if (year, month, day) >= date:
            value = offset
    return value


def julian_day_number(year: int, month: int, day: int) -> int:
    """Julian day number of a Gregorian calendar date (noon-based; Fliegel & Van Flandern 1968)."""
    a = (14 - month) // 12
    y = year + 4800 - a
    m = month + 12 * a - 3
    return day + (153 * m + 2) // 5 + 365 * y + y // 4 - y // 100 + y // 400 - 32045


@dataclass(frozen=True)
class Epoch:
    """A UTC instant with its Julian dates. ``jd_utc`` and ``jd_tt`` are stored split as
    (day at 0h, fraction of day) so that the sum keeps ~10 microsecond resolution."""

    iso: str
    jd_utc_day: float
    jd_utc_frac: float
    tai_utc_s: int

    @property
    def jd_utc(self) -> float:
        """UTC Julian date (days)."""
        return self.jd_utc_day + self.jd_utc_frac

    @property
    def tt_minus_utc_s(self) -> float:
        """TT - UTC (s) at the epoch = (TAI - UTC) + 32.184."""
        return self.tai_utc_s + TT_MINUS_TAI

    @property
    def jd_tt(self) -> float:
        """TT Julian date (days)."""
        return self.jd_utc_day + (self.jd_utc_frac + self.tt_minus_utc_s / SECONDS_PER_DAY)

    def days_tt_since_j2000(self, t_s: float = 0.0) -> float:
        """TT days from J2000.0 at ``t_s`` seconds after the epoch."""
        return (self.jd_utc_day - JD_J2000) + self.jd_utc_frac + (self.tt_minus_utc_s + t_s) / SECONDS_PER_DAY

    def days_ut1_since_j2000(self, t_s: float = 0.0) -> float:
        """UT1 days from 2000-01-01 12:00 UT1 at ``t_s`` s after the epoch (UT1 ~ UTC, see module doc)."""
        return (self.jd_utc_day - JD_J2000) + self.jd_utc_frac + t_s / SECONDS_PER_DAY

    def __str__(self) -> str:
        return self.iso


def parse_epoch(iso_utc: str, field: str = "epoch") -> Epoch:
    """Validated :class:`Epoch` from an ISO 8601 UTC string such as ``2022-05-01T00:00:00Z``
    (``T`` or space separator; seconds and fraction optional; suffix ``Z``/``+00:00``/
    none, read as UTC). Raises ProxopsInputError naming ``field`` otherwise, and for
    epochs outside 1972-01-01 .. 2099-12-31 (leap-second table / ephemeris range)."""
    if isinstance(iso_utc, Epoch):
        return iso_utc
    if not isinstance(iso_utc, str):
        raise input_error(field, iso_utc, ISO_HINT)
    text = iso_utc.strip()
    m = _ISO.match(text)
    if m is None:
        raise input_error(field, iso_utc, ISO_HINT)
    year, month, day, hour, minute = (int(m.group(i)) for i in range(1, 6))
    second = int(m.group(6) or 0)
    frac = float(m.group(7) or 0.0)
    try:
        # validates the calendar date and time fields (second 60 is a leap second, below)
        datetime(year, month, day, hour, minute, min(second, 59), tzinfo=timezone.utc)
    except ValueError:
        raise input_error(field, iso_utc, ISO_HINT) from None
    if second > 60:
        raise input_error(field, iso_utc, ISO_HINT)
    if not MIN_YEAR <= year <= MAX_YEAR:
        raise input_error(
            field,
            iso_utc,
            f"outside the supported range {MIN_YEAR}-01-01 .. {MAX_YEAR}-12-31 (leap-second table and ephemeris)",
        )
    jdn = julian_day_number(year, month, day)
    day_frac = (hour * 3600.0 + minute * 60.0 + second + frac) / SECONDS_PER_DAY
    return Epoch(text, jdn - 0.5, day_frac, tai_minus_utc(year, month, day))


def check_time_range(epoch: Epoch, t_s_max: float, field: str = "duration") -> None:
    """Raise ProxopsInputError if ``epoch + t_s_max`` leaves the supported range."""
    end_days = epoch.days_tt_since_j2000(float(t_s_max))
    jd_end = JD_J2000 + end_days
    jd_max = julian_day_number(MAX_YEAR + 1, 1, 1) - 0.5
    jd_min = julian_day_number(MIN_YEAR, 1, 1) - 0.5
    if not (jd_min <= jd_end < jd_max) or not math.isfinite(jd_end):
        raise input_error(
            field,
            t_s_max,
            f"epoch {epoch.iso} + duration leaves the supported range {MIN_YEAR}..{MAX_YEAR} of the ephemeris",
            "s",
        )
