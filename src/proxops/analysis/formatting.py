"""Numbers for people: every result printed in a summary or report is rounded to the resolution
that means something for its unit, and shown with that unit. Machine outputs (``--json``,
Parquet, CSV, summary.json) keep full precision; only text and Markdown go through here.

The unit comes from the key's suffix (:func:`proxops.scenarios.loader.unit_of`, the function
that names units in error messages), so ``final_range_m`` prints as ``98.361 m`` and
``total_dv_mps`` as ``0.8311 m/s``.
"""

from __future__ import annotations

import math
import numbers

from proxops.scenarios.loader import unit_of_metric

# decimals per unit: positions to 1 mm, speeds and delta-v to 0.1 mm/s, accelerations to
# 1 um/s^2, times to 10 ms (solve times to 1 us), angles to 0.001 deg, rates to 1e-4 deg/s
DECIMALS = {
    "m": 3, "km": 6, "m/s": 4, "m/s^2": 6, "s": 2, "ms": 3, "deg": 3, "deg/s": 4, "deg/s^2": 4,
    "rad": 5, "rad/s": 6, "rad/s^2": 6, "N": 4, "N m": 6, "N m s": 6, "N s": 4, "kg": 3, "kg m^2": 6, "%": 1,
    "m/orbit": 3,
}
SIGNIFICANT = 4  # keys without a unit (ratios, weights, counts as means)


def format_number(value, unit: str = "") -> str:
    """``value`` rounded to the resolution of ``unit`` (fixed decimals, see DECIMALS), or to 4
    significant digits without a unit. Values below the resolution print as ``0`` (a 5.6e-16 m
    range is a zero range to the reader), as does zero itself. Integers, booleans and text are as they are."""
    if value is None:
        return "none"
    if getattr(getattr(value, "dtype", None), "kind", "") == "b":
        value = bool(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if not isinstance(value, float):
        try:
            value = float(value)  # numpy scalars
        except (TypeError, ValueError):
            return str(value)
    if not math.isfinite(value):
        return str(value)
    decimals = DECIMALS.get(unit)
    if value == 0.0 or (decimals is not None and abs(value) < 0.5 * 10.0**-decimals):
        return "0"  # zero, or below the unit's resolution: nothing to read in its digits
    if decimals is not None:
        return f"{value:.{decimals}f}"
    if abs(value) >= 10**SIGNIFICANT:
        return f"{value:.0f}"
    if not unit and abs(value) < 1e-6:  # no unit, no resolution: a bound says all a reader needs (a 5e-12 residual)
        return "< 1e-06" if value > 0 else "> -1e-06"
    return f"{value:.{SIGNIFICANT}g}"


def format_quantity(value, key: str, significant: bool = False) -> str:
    """``value`` of ``key`` with its unit: ``format_quantity(98.36128, "final_range_m")`` -> ``98.361 m``.
    ``significant``: 4 significant digits instead of the unit's resolution (for input settings such
    as a grid's values, which are exact rather than measured)."""
    unit = unit_of_metric(key)
    text = format_number(value, "" if significant else unit)
    numeric = isinstance(value, numbers.Number) and not isinstance(value, bool) and \
        getattr(getattr(value, "dtype", None), "kind", "") != "b"
    return f"{text} {unit}" if unit and numeric and text not in ("nan", "inf", "-inf") else text


def format_percent(fraction: float) -> str:
    """A fraction as a percentage to 0.1 (``0.95`` -> ``95.0 %``)."""
    if fraction is None or not math.isfinite(float(fraction)):
        return "nan"
    return f"{100.0 * float(fraction):.1f} %"
