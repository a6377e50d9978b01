"""Pieces of a system's build that need no numba, no plant and no solver (numpy at most), shared by
the system builders (:mod:`proxops.systems`) and by the schema modules' build-free
checks (:func:`proxops.scenarios.registry.register_check`, run by ``proxops validate``): one
definition, so both raise the same one-line errors."""

from __future__ import annotations

import numpy as np

from proxops.actuators import IdealActuator, thruster_from_values
from proxops.core.constants import R_EARTH
from proxops.frames.elements import OrbitalElements, check_perigee_above_surface
from proxops.frames.lvlh import lvlh_to_hill
from proxops.scenarios.schema import ActuatorSection, InitialSection, OrbitSection, TruthSection


def initial_hill_state(initial: InitialSection) -> np.ndarray:
    """Initial relative state in Hill/RTN from the scenario's [initial] section."""
    x0 = np.array(list(initial.position_m) + list(initial.velocity_mps), dtype=float)
    if initial.frame == "lvlh-srf":
        x0 = lvlh_to_hill(x0)
    return x0


def target_elements(orbit: OrbitSection) -> OrbitalElements:
    """Osculating target elements from the scenario's [orbit] section."""
    return OrbitalElements.from_deg(orbit.sma_m, orbit.ecc, orbit.inc_deg, orbit.raan_deg, orbit.argp_deg, orbit.nu_deg)


def actuator_model(act: ActuatorSection):
    """Ideal for the default section, else the thruster model of its values (one declaration:
    proxops.actuators.THRUSTER_PARAMETERS)."""
    if act == ActuatorSection():
        return IdealActuator()
    return thruster_from_values(act.model_dump())


def plant_checked(orbit: OrbitSection, truth: TruthSection) -> bool:
    """The checks of :func:`proxops.systems.common.translational_plant` without building the plant:
    the target elements, and for the nonlinear truths (:class:`proxops.propagation.truth.RelativeTruth`)
    the perigee above the surface (its integrator name is the schema's: ``multistep`` only with
    ``full``). False for ``truth.model = "full"``: its force models and data check themselves (build)."""
    if truth.model == "full":
        return False
    elements = target_elements(orbit)
    if truth.model != "cw":
        check_perigee_above_surface(elements, R_EARTH, "target orbit")
    return True
