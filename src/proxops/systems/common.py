"""Builders shared by the translational systems: plant, navigation and actuator from
the common scenario sections (one place, so every system reads them the same way)."""

from __future__ import annotations

import numpy as np

from proxops.actuators import IdealActuator, ThrusterModel
from proxops.core.layout import HILL_LAYOUT
from proxops.navigation import GaussianNavigation, PerfectNavigation
from proxops.scenarios.schema import ActuatorSection, InitialSection, NavigationSection, OrbitSection, TruthSection


def initial_hill_state(initial: InitialSection) -> np.ndarray:
    """Initial relative state in Hill/RTN from the scenario's [initial] section."""
    x0 = np.array(list(initial.position_m) + list(initial.velocity_mps), dtype=float)
    if initial.frame == "lvlh-srf":
        from proxops.frames.lvlh import lvlh_to_hill

        x0 = lvlh_to_hill(x0)
    return x0


def target_elements(orbit: OrbitSection):
    """Osculating target elements from the scenario's [orbit] section."""
    from proxops.frames.elements import OrbitalElements

    return OrbitalElements.from_deg(orbit.sma_m, orbit.ecc, orbit.inc_deg, orbit.raan_deg, orbit.argp_deg, orbit.nu_deg)


def translational_plant(orbit: OrbitSection, truth: TruthSection, x0_hill: np.ndarray):
    """Truth plant for a chaser starting at ``x0_hill`` relative to the target on ``orbit``."""
    from proxops.propagation.truth import CWPlant, RelativeTruth

    elements = target_elements(orbit)
    if truth.model == "cw":
        return CWPlant.from_orbit(elements, x0_hill)
    if truth.model == "full":
        from proxops.propagation.composed import ComposedTruth

        return ComposedTruth(elements, x0_hill, force_models(orbit, truth), integrator=truth.integrator)
    return RelativeTruth(elements, x0_hill, j2=truth.model == "j2", integrator=truth.integrator)


def force_models(orbit: OrbitSection, truth: TruthSection):
    """:class:`proxops.propagation.composed.ForceModels` of a ``model = "full"`` [truth] section."""
    from proxops.environment.forces import Spacecraft, SpaceWeather
    from proxops.propagation.composed import ForceModels

    order = truth.gravity_degree if truth.gravity_order is None else truth.gravity_order
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
        weather=SpaceWeather(truth.f107, truth.f107a, truth.ap),
    )


def navigation_model(nav: NavigationSection):
    if nav.position_sigma_m == 0.0 and nav.velocity_sigma_mps == 0.0:
        return PerfectNavigation()
    return GaussianNavigation(nav.position_sigma_m, nav.velocity_sigma_mps, layout=HILL_LAYOUT)  # noise per block


def actuator_model(act: ActuatorSection):
    if act == ActuatorSection():
        return IdealActuator()
    return ThrusterModel(
        max_per_axis=act.max_per_axis,
        max_norm=act.max_norm,
        min_impulse=act.min_impulse,
        magnitude_sigma=act.magnitude_sigma,
        pointing_sigma_rad=np.radians(act.pointing_sigma_deg),
        missed_probability=act.missed_probability,
    )
