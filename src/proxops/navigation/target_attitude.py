"""Navigation of the chaser relative to a tumbling target whose attitude and rate are estimated
(system ``los``): an :class:`proxops.navigation.mekf.AttitudeMEKF` fed by the
attitude part of a simulated camera/LIDAR pose (:class:`proxops.navigation.mekf.PoseAttitudeSensor`).

The plant (:class:`proxops.dynamics.tumbling_target.TumblingTargetTruth`) reports the chaser's
state in the *true* target body frame, x_B = [r_B, v_B] (Iskender 2026 eqs.
7-8). The controller sees it in the *estimated* body frame:

    dr = R r_B,  dv = R (v_B + w x r_B)                    (truth, inertial axes)
    r_B^ = R^^T dr,  v_B^ = R^^T dv - w^ x r_B^             (eqs. 7-8 with the estimates)

with R = R_IB(q_true), R^ = R_IB(q^) and w^ the estimated body rate; optional white Gaussian
errors on dr, dv (``position_sigma_m``, ``velocity_sigma_mps``, inertial axes) stand for the
translational part of the pose. The truth attitude comes from ``truth_attitude(t) -> (q_IB, w_B)``
(the plant's own closed form, used only to simulate measurements and score the filter).

Visibility: the pose is measured while the chaser's line of sight in the target body frame, r_B,
lies within half of ``sensor.fov_rad`` of the target's docking axis (the sensor's boresight,
default +y_B: the face whose features the camera tracks), outside random outages.

For the controller (:class:`proxops.control.los_regimes.LosGuidanceController`), whose body-frame
model knows the frame angle theta(t) about the orbit normal from the scenario, :meth:`frame_angle_error`
gives the angle psi about z_B between the estimated and the true body frame: the controller turns
its frame to theta + psi, so its Hill reconstruction R_LB^ r_B^ equals the true Hill position and
the commanded acceleration is rotated with the estimated angle (what a controller computing theta^
from q^ and the known Hill frame does).

Consistency is recorded every tick (:attr:`record`): NEES of attitude + rate (6 dof), attitude and
rate errors, the NIS of every update (3 dof), update and rejection counts. :func:`attitude_summary` turns them
into the ``att_*`` summary keys.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from proxops.dynamics.tumbling_target import cross3
from proxops.core.quaternion import dcm_kernel, multiply_kernel
from proxops.navigation.mekf import AttitudeMEKF, PoseAttitudeSensor, attitude_error
from proxops.navigation import small_rotation


@dataclass
class TargetAttitudeNavigation:
    """Navigation (:class:`proxops.contracts.Navigation`) of the body-frame relative state with the
    target attitude and rate estimated by an MEKF (module docstring).

    ``truth_attitude``: callable t -> (q_IB (4,), w_B (3,) rad/s); ``sensor``: the pose-attitude
    sensor (boresight in target body axes); ``p0``: initial error covariance (6x6, rad^2, rad^2/s^2),
    the initial estimate is the truth plus one draw from N(0, p0) (navigation stream);
    ``inertia``: the filter's principal moments (kg m^2); ``q_accel_psd``: its angular-acceleration PSD
    (rad^2/s^3); ``gate_probability``: chi-square gate.
    """

    truth_attitude: object
    sensor: PoseAttitudeSensor
    p0: np.ndarray
    inertia: np.ndarray
    q_accel_psd: float
    gate_probability: float = 0.9999
    position_sigma_m: float = 0.0
    velocity_sigma_mps: float = 0.0
    period_s: float | None = field(default=None, kw_only=True)

    def __post_init__(self):
        self.p0 = np.asarray(self.p0, dtype=float)
        self._l0 = np.linalg.cholesky(self.p0)
        self.filter: AttitudeMEKF | None = None
        self.t: float | None = None
        self.events: list[tuple[str, str]] = []
        self.record: dict = {"t": [], "nees": [], "att_err_rad": [], "rate_err_rad_s": [], "nis": [], "updates": 0,
                             "rejected": 0, "nees_dof": 6, "nis_dof": 3}
        self._psi = 0.0

    def _start(self, t: float, q: np.ndarray, w: np.ndarray, rng: np.random.Generator) -> None:
        e = self._l0 @ rng.standard_normal(6)
        q_hat = multiply_kernel(q, small_rotation(-e[:3]))  # q_true = q^ (x) exp(e/2)
        self.filter = AttitudeMEKF(q_hat, w - e[3:], self.p0, self.inertia, self.q_accel_psd,
                                   gate_probability=self.gate_probability)
        self.t = t
        for v in self.record.values():
            if isinstance(v, list):
                v.clear()

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Navigation tick: predict to ``t``, sense, update; the body-frame state in the estimated frame."""
        q, w = self.truth_attitude(t)
        q, w = np.asarray(q, dtype=float), np.asarray(w, dtype=float)
        if self.filter is None or self.t is None or t < self.t:
            self._start(t, q, w, rng)
        else:
            self.filter.predict(t - self.t)
            self.t = t
        f = self.filter
        x = np.asarray(x_true, dtype=float)
        q_meas, w_meas = self.sensor.draw(t, q, w, x[:3], rng)
        rec = self.record
        if q_meas is not None:
            rec["nis"].append(f.update_attitude(q_meas, self.sensor.sigma_rad).nis)
        if w_meas is not None:
            rec["nis"].append(f.update_rate(w_meas, self.sensor.rate_sigma_rad_s).nis)
        rec["updates"], rec["rejected"] = f.updates, f.rejected
        if f.events:
            self.events.extend(f.events)
            f.events.clear()
        R = dcm_kernel(q)  # quat_to_dcm (the same bits)
        dr = R @ x[:3]
        dv = R @ (x[3:6] + cross3(w, x[:3]))
        if self.position_sigma_m > 0.0:
            dr = dr + self.position_sigma_m * rng.standard_normal(3)
        if self.velocity_sigma_mps > 0.0:
            dv = dv + self.velocity_sigma_mps * rng.standard_normal(3)
        q_hat, w_hat = f.q, f.omega
        R_hat = dcm_kernel(np.ascontiguousarray(q_hat, dtype=float))
        r_hat = R_hat.T @ dr
        v_hat = R_hat.T @ dv - cross3(w_hat, r_hat)
        D = R.T @ R_hat  # estimated body axes in true body components
        self._psi = math.atan2(D[1, 0], D[0, 0])
        err = attitude_error(q_hat, q)
        rec["t"].append(float(t))
        rec["nees"].append(f.nees(q, w))
        rec["att_err_rad"].append(float(np.linalg.norm(err)))
        rec["rate_err_rad_s"].append(float(np.linalg.norm(w - w_hat)))
        return np.concatenate([r_hat, v_hat])

    def frame_angle_error(self) -> float:
        """psi (rad): angle about z of the estimated body frame from the true one, at the last tick."""
        return self._psi
