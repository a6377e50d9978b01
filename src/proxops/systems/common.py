"""Builders shared by the translational systems: plant, navigation and actuator from
the common scenario sections (one place, so every system reads them the same way)."""

from __future__ import annotations

import numpy as np

from proxops.actuators import IdealActuator, thruster_from_values
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


def navigation_model(nav: NavigationSection, per_state_sigma=None):
    """The navigation of a [navigation] section (the one place it is built): perfect when both
    sigmas are 0, else Gaussian. ``per_state_sigma(position_sigma_m, velocity_sigma_mps)`` maps
    the two sigmas onto a state layout other than [r; v] (e.g. the planar CubeSat's)."""
    if nav.position_sigma_m == 0.0 and nav.velocity_sigma_mps == 0.0:
        return PerfectNavigation()
    if per_state_sigma is not None:
        return GaussianNavigation(sigma=per_state_sigma(nav.position_sigma_m, nav.velocity_sigma_mps))
    return GaussianNavigation(nav.position_sigma_m, nav.velocity_sigma_mps, layout=HILL_LAYOUT)  # noise per block


def actuator_model(act: ActuatorSection):
    """Ideal for the default section, else the thruster model of its values (one declaration:
    proxops.actuators.THRUSTER_PARAMETERS)."""
    if act == ActuatorSection():
        return IdealActuator()
    return thruster_from_values(act.model_dump())
