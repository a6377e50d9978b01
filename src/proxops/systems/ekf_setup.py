"""The Hill-state EKF of a ``model = "ekf"`` [navigation] section
(:class:`proxops.navigation.ekf.RelativeEKF`) and its sensor's eclipse model."""

from __future__ import annotations

import math

import numpy as np

from proxops.core.cw import mean_motion
from proxops.environment.eclipse import illumination, kepler_positions
from proxops.environment.ephemeris import sun_position_eci
from proxops.environment.epochs import parse_epoch
from proxops.errors import input_error
from proxops.navigation.ekf import RelativeEKF, SensorModel
from proxops.propagation.relative_predictor import HillPredictor
from proxops.scenarios.schema import NavigationSection, OrbitSection
from proxops.systems.common import target_elements


def ekf_navigation(nav: NavigationSection, orbit: OrbitSection | None, control_dt_s: float | None,
                   system: str = "this system", layout=None, actuator=None):
    """:class:`proxops.navigation.ekf.RelativeEKF` of a ``model = "ekf"`` [navigation] section;
    ``layout``: the plant's state layout (the filter estimates its position and velocity blocks;
    None: the 6-state Hill layout); ``actuator``: the run's actuator, whose execution-error model
    (``execution_covariance``, or that of its ``errors`` stage) the filter adds to its covariance
    at each command. ``process_model = "j2"``: the mean is predicted by
    :class:`proxops.propagation.relative_predictor.HillPredictor` on the target orbit."""
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
            ts = np.array([t])
            r = kepler_positions(target_elements(self.orbit), ts)
            sun = sun_position_eci(parse_epoch(self.orbit.epoch_utc), ts)
            lit = self._cache[t] = bool(illumination(r, np.atleast_2d(sun))[0] > 0.5)
        return lit
