"""Builders shared by the translational systems: plant, navigation and actuator from
the common scenario sections (one place, so every system reads them the same way). The full
truth's force models (:mod:`proxops.systems.full_truth`) and the Hill-state EKF
(:mod:`proxops.systems.ekf_setup`) are imported only by the scenarios that use them: their
kernels and ephemerides would add ~0.2 s to every run's start."""

from __future__ import annotations

import numpy as np

from proxops.actuators import IdealActuator, thruster_from_values
from proxops.constraints.passive_safety import certify_free_drift
from proxops.core.layout import HILL_LAYOUT
from proxops.frames.elements import OrbitalElements
from proxops.frames.lvlh import lvlh_to_hill
from proxops.navigation import GaussianNavigation, PerfectNavigation
from proxops.propagation.truth import CWPlant, RelativeTruth
from proxops.scenarios.schema import ActuatorSection, InitialSection, NavigationSection, OrbitSection, TruthSection


def initial_hill_state(initial: InitialSection) -> np.ndarray:
    """Initial relative state in Hill/RTN from the scenario's [initial] section."""
    x0 = np.array(list(initial.position_m) + list(initial.velocity_mps), dtype=float)
    if initial.frame == "lvlh-srf":
        x0 = lvlh_to_hill(x0)
    return x0


def target_elements(orbit: OrbitSection):
    """Osculating target elements from the scenario's [orbit] section."""

    return OrbitalElements.from_deg(orbit.sma_m, orbit.ecc, orbit.inc_deg, orbit.raan_deg, orbit.argp_deg, orbit.nu_deg)


def translational_plant(orbit: OrbitSection, truth: TruthSection, x0_hill: np.ndarray):
    """Truth plant for a chaser starting at ``x0_hill`` relative to the target on ``orbit``."""
    elements = target_elements(orbit)
    if truth.model == "cw":
        return CWPlant.from_orbit(elements, x0_hill)
    if truth.model == "full":
        from proxops.systems.full_truth import full_truth_plant  # its force models and numba kernels: full only

        return full_truth_plant(orbit, truth, x0_hill)
    return RelativeTruth(elements, x0_hill, j2=truth.model == "j2", integrator=truth.integrator)


def navigation_model(nav: NavigationSection, per_state_sigma=None, orbit: OrbitSection | None = None,
                     control_dt_s: float | None = None, system: str = "this system", actuator=None):
    """The navigation of a [navigation] section (the one place it is built): ``model = "noise"``:
    perfect when both sigmas are 0, else Gaussian; ``per_state_sigma(position_sigma_m,
    velocity_sigma_mps)`` maps the two sigmas onto a state layout other than [r; v] (e.g. the
    planar CubeSat's). ``model = "ekf"``: :class:`proxops.navigation.ekf.RelativeEKF` on the Hill
    state, which needs the target ``orbit`` (mean motion) and the controller period
    ``control_dt_s`` (systems whose controller sees another state pass neither: an error)."""
    if nav.model == "ekf":
        from proxops.systems.ekf_setup import ekf_navigation  # the filter (and its eclipse model): ekf only

        return ekf_navigation(nav, orbit, control_dt_s, system, actuator=actuator)
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


def passive_safety_certificate(plant, state, koz, period_s: float, window_orbits: float,
                               samples_per_orbit: int = 720) -> dict:
    """The passive-safety certificate (:func:`proxops.constraints.passive_safety.certify_free_drift`)
    of the thrust-free TRUTH from ``state`` (the plant's full state: what ``plant.free_drift`` takes)
    over ``window_orbits`` orbits of ``period_s`` s, sampled ``samples_per_orbit`` times per orbit.
    One block for every system with an abort or a free-drift phase (srf, cortex)."""
    times = np.linspace(0.0, window_orbits * period_s, int(round(window_orbits * samples_per_orbit)) + 1)
    drift = plant.free_drift(np.asarray(state, dtype=float), times)
    return {**certify_free_drift(times, drift, koz, period_s, window_orbits),
            "truth": type(plant).__name__, "samples_per_orbit": int(samples_per_orbit)}
