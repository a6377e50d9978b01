"""The full truth of a ``model = "full"`` [truth] section: its force models
(:class:`proxops.propagation.composed.ForceModels`: EGM96 harmonics, NRLMSISE-00 drag, Sun and Moon,
SRP, space weather, Earth orientation) and the composed plant."""

from __future__ import annotations

import numpy as np

from proxops.environment.forces import Spacecraft, SpaceWeather
from proxops.environment.spaceweather import eop_at, weather_history
from proxops.propagation.composed import ComposedTruth, ForceModels
from proxops.frames.elements import OrbitalElements
from proxops.scenarios.schema import OrbitSection, TruthSection


def full_truth_plant(elements: OrbitalElements, orbit: OrbitSection, truth: TruthSection,
                     x0_hill: np.ndarray) -> ComposedTruth:
    """Truth plant (composed force models) for a chaser starting at ``x0_hill`` relative to the target
    on osculating ``elements`` (those of ``orbit``)."""
    return ComposedTruth(elements, x0_hill, force_models(orbit, truth), integrator=truth.integrator)


def force_models(orbit: OrbitSection, truth: TruthSection):
    """:class:`proxops.propagation.composed.ForceModels` of a ``model = "full"`` [truth] section."""
    order = truth.gravity_degree if truth.gravity_order is None else truth.gravity_order
    weather = SpaceWeather(truth.f107, truth.f107a, truth.ap)
    if truth.space_weather == "cssi" and truth.drag:
        weather = weather_history(orbit.epoch_utc)
    return ForceModels(
        epoch=orbit.epoch_utc,
        gravity="harmonics",
        degree=truth.gravity_degree,
        order=order,
        drag=truth.drag,
        sun=truth.third_body,
        moon=truth.third_body,
        srp=truth.srp,
        shadow=truth.shadow,
        target=Spacecraft(**truth.target.model_dump(), name="truth.target"),
        chaser=Spacecraft(**truth.chaser.model_dump(), name="truth.chaser"),
        weather=weather,
        **_earth_orientation(orbit, truth),
    )


def _earth_orientation(orbit: OrbitSection, truth: TruthSection) -> dict:
    """UT1 - UTC (s) and the pole coordinates (arcsec) of the epoch for ``truth.earth_orientation
    = "iers"``, else zeros."""
    if truth.earth_orientation != "iers":
        return {"ut1_utc_s": 0.0, "polar_motion_arcsec": (0.0, 0.0)}
    eop = eop_at(orbit.epoch_utc, "truth.earth_orientation")
    return {"ut1_utc_s": eop["ut1_utc_s"], "polar_motion_arcsec": (eop["x_arcsec"], eop["y_arcsec"])}
