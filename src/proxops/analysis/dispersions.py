"""Kept for existing imports: the dispersion parser lives in :mod:`proxops.scenarios.dispersions`
(scenario validation uses it, so it belongs to the scenarios layer)."""

from proxops.scenarios.dispersions import (  # noqa: F401
    Dispersion,
    DispersionPlan,
    apply_values,
    nominal_value,
    parse_dispersions,
    parse_path,
    set_path,
)
