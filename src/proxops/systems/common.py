"""Builders shared by the translational systems: plant, navigation and actuator from
the common scenario sections (one place, so every system reads them the same way). The full
truth (:mod:`proxops.systems.full_truth`), the Hill-state EKF and its eclipse model are imported
only where a scenario uses them: their kernels and ephemerides would add 0.1-0.5 s (measured under
load) to the start of every run."""

from __future__ import annotations

import math

import numpy as np

from proxops.constraints.passive_safety import certify_free_drift
from proxops.core.cw import mean_motion
from proxops.core.layout import HILL_LAYOUT
from proxops.environment.epochs import parse_epoch
from proxops.errors import input_error
from proxops.navigation import GaussianNavigation, PerfectNavigation
from proxops.propagation.truth import CWPlant, RelativeTruth
from proxops.scenarios.schema import NavigationSection, OrbitSection, TruthSection
from proxops.systems.schema._build_free import target_elements


def translational_plant(orbit: OrbitSection, truth: TruthSection, x0_hill: np.ndarray):
    """Truth plant for a chaser starting at ``x0_hill`` relative to the target on ``orbit``."""
    elements = target_elements(orbit)
    if truth.model == "cw":
        return CWPlant.from_orbit(elements, x0_hill)
    if truth.model == "full":
        from proxops.systems.full_truth import full_truth_plant  # its force models and numba kernels: full only

        return full_truth_plant(elements, orbit, truth, x0_hill)
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
        return ekf_navigation(nav, orbit, control_dt_s, system, actuator=actuator)
    if nav.position_sigma_m == 0.0 and nav.velocity_sigma_mps == 0.0:
        return PerfectNavigation()
    if per_state_sigma is not None:
        return GaussianNavigation(sigma=per_state_sigma(nav.position_sigma_m, nav.velocity_sigma_mps))
    return GaussianNavigation(nav.position_sigma_m, nav.velocity_sigma_mps, layout=HILL_LAYOUT)  # noise per block


def ekf_navigation(nav: NavigationSection, orbit: OrbitSection | None, control_dt_s: float | None,
                   system: str = "this system", layout=None, actuator=None):
    """:class:`proxops.navigation.ekf.RelativeEKF` of a ``model = "ekf"`` [navigation] section;
    ``layout``: the plant's state layout (the filter estimates its position and velocity blocks;
    None: the 6-state Hill layout); ``actuator``: the run's actuator, whose execution-error model
    (``execution_covariance``, or that of its ``errors`` stage) the filter adds to its covariance
    at each command. ``process_model = "j2"``: the mean is predicted by
    :class:`proxops.propagation.relative_predictor.HillPredictor` on the target orbit."""
    from proxops.navigation.ekf import RelativeEKF, SensorModel  # ekf scenarios only (see the module doc)

    if orbit is None or control_dt_s is None:
        raise input_error("navigation.model", "ekf", f"{system} does not run on the Hill-state filter: allowed: noise")
    period = nav.update_period_s
    if period is not None:
        ratio = control_dt_s / period
        if period > control_dt_s * (1 + 1e-9) or abs(ratio - round(ratio)) > 1e-6:
            raise input_error("navigation.update_period_s", period,
                              f"must divide the control period {control_dt_s:g} s (control period / update period "
                              f"an integer; got {ratio:.6g})", "s")
    if nav.initial_covariance is not None:
        p0 = np.asarray(nav.initial_covariance, dtype=float)
        if p0.shape != (6, 6):
            raise input_error("navigation.initial_covariance", f"{p0.shape}", "must be 6 rows of 6 numbers", "SI")
    else:
        p0 = np.diag([nav.initial_position_sigma_m ** 2] * 3 + [nav.initial_velocity_sigma_mps ** 2] * 3)
    boresight = None
    if nav.boresight_hill is not None:
        b = np.asarray(nav.boresight_hill, dtype=float)
        if not np.linalg.norm(b) > 0:
            raise input_error("navigation.boresight_hill", nav.boresight_hill, "must be a non-zero vector")
        boresight = b / np.linalg.norm(b)
    illuminated = target_illumination(orbit) if nav.eclipse_dropout else None
    sensor = SensorModel(kind=nav.sensor, range_sigma_m=nav.range_sigma_m,
                         angle_sigma_rad=math.radians(nav.angle_sigma_deg),
                         sigma_reference_range_m=nav.sigma_reference_range_m,
                         sigma_floor_fraction=nav.sigma_floor_fraction, fov_rad=math.radians(nav.fov_deg),
                         boresight=boresight, outage_probability=nav.outage_probability, illuminated=illuminated)
    predictor = None
    if nav.process_model == "j2":
        from proxops.propagation.relative_predictor import HillPredictor

        predictor = HillPredictor(target_elements(orbit), j2=True)
    command_covariance = getattr(actuator, "execution_covariance", None)
    if command_covariance is None:
        command_covariance = getattr(getattr(actuator, "errors", None), "execution_covariance", None)
    if not nav.actuator_error_model:
        command_covariance = None
    return RelativeEKF(mean_motion(orbit.sma_m), sensor, p0, q_m2_s3=nav.process_noise_m2_s3,
                       predictor=predictor, command_covariance=command_covariance,
                       gate_probability=nav.gate_probability, command_sigma_fraction=nav.command_sigma_fraction,
                       reinit_after_rejections=nav.reinit_after_rejections,
                       reinit_velocity_sigma_mps=nav.reinit_velocity_sigma_mps, layout=layout, period_s=period)


class target_illumination:  # noqa: N801 (a picklable callable)
    """``t -> bool``: the target (Keplerian orbit from [orbit]) is lit by the Sun (conical shadow)."""

    def __init__(self, orbit: OrbitSection):
        self.orbit = orbit
        self._cache: dict[float, bool] = {}

    def __call__(self, t: float) -> bool:
        lit = self._cache.get(t)
        if lit is None:
            from proxops.environment.eclipse import illumination, kepler_positions  # eclipse_dropout only
            from proxops.environment.ephemeris import sun_position_eci

            ts = np.array([t])
            r = kepler_positions(target_elements(self.orbit), ts)
            sun = sun_position_eci(parse_epoch(self.orbit.epoch_utc), ts)
            lit = self._cache[t] = bool(illumination(r, np.atleast_2d(sun))[0] > 0.5)
        return lit


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
