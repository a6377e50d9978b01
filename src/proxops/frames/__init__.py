"""Frames: ECI <-> Hill/RTN (exact, with the rotating-frame velocity term), Hill <-> srf
V-bar/R-bar LVLH, classical orbital elements. See each module for conventions."""

from proxops.frames.elements import (
    OrbitalElements,
    check_perigee_above_surface,
    circular_orbit,
    eci_to_elements,
    elements_to_eci,
    mean_to_true_anomaly,
    orbital_period,
    true_to_mean_anomaly,
)
from proxops.frames.hill import (
    eci_offset_to_hill,
    eci_to_hill,
    eci_vector_to_hill,
    hill_dcm,
    hill_frame_rate,
    hill_to_eci,
    hill_to_eci_offset,
    hill_vector_to_eci,
)
from proxops.frames.lvlh import (
    HILL_TO_LVLH,
    HILL_TO_LVLH_STATE,
    LVLH_TO_HILL,
    hill_to_lvlh,
    hill_vector_to_lvlh,
    lvlh_to_hill,
    lvlh_vector_to_hill,
)

__all__ = [
    "OrbitalElements",
    "check_perigee_above_surface",
    "circular_orbit",
    "eci_to_elements",
    "elements_to_eci",
    "mean_to_true_anomaly",
    "orbital_period",
    "true_to_mean_anomaly",
    "eci_offset_to_hill",
    "eci_to_hill",
    "eci_vector_to_hill",
    "hill_dcm",
    "hill_frame_rate",
    "hill_to_eci",
    "hill_to_eci_offset",
    "hill_vector_to_eci",
    "HILL_TO_LVLH",
    "HILL_TO_LVLH_STATE",
    "LVLH_TO_HILL",
    "hill_to_lvlh",
    "hill_vector_to_lvlh",
    "lvlh_to_hill",
    "lvlh_vector_to_hill",
]
