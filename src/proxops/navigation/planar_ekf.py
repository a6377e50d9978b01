"""Planar pose EKF of the underactuated CubeSat deputy (system ``underactuated``).

State ``s = [x, y, theta, vx, vy, omega]`` (m, rad, m/s, rad/s; :mod:`proxops.dynamics.planar_cubesat`),
the same as the plant's and the NMPC's. Why one 6-state EKF (the translational EKF extended with the
planar angle) rather than the multiplicative attitude filter of :mod:`proxops.navigation.mekf`:

* a rotation about one fixed axis commutes, so the angle is a global minimal parametrisation (mod 2 pi)
  and the multiplicative error reduces to an additive angle with a wrapped residual;
* the angle and the translation are coupled through the thrust direction (cos theta, sin theta) f/m, so
  a joint filter keeps the cross-covariance two separate filters would drop;
* the body rate is driven by the reaction wheel (eq. 4/5: thetadd = (-D wheel_acc - c omega) / I_z),
  not torque-free: the commanded wheel acceleration and thrust enter the prediction through the
  engine's ``command`` hook, as the commanded acceleration does in
  :class:`proxops.navigation.ekf.RelativeEKF`.

Process model: the plant's own right-hand side (:func:`proxops.dynamics.planar_cubesat.rk4_step`,
the held command) in substeps of at most ``max_substep_s``, plus white acceleration of PSD
``q_accel_m2_s3`` on vx, vy and white angular acceleration of PSD ``q_angular_rad2_s3`` on omega;
Phi and Q_d of each substep by Van Loan (:func:`proxops.navigation.mekf.van_loan`) of the Jacobian at
the substep's mean state:

    F = [[0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1],
         [3n^2, 0, -sin(theta) f/m, 0, 2n, 0], [0, 0, cos(theta) f/m, -2n, 0, 0], [0, 0, 0, 0, 0, -c/I_z]]

Measurement: a pose of the deputy relative to the chief's docking port, ``[x, y, theta]`` with
1-sigma ``position_sigma_m`` per axis and ``angle_sigma_rad`` (angle residual wrapped to [-pi, pi)),
lost with ``outage_probability`` or when the chief (line of sight -r) lies outside half of ``fov_rad``
about the deputy's body x axis (its docking axis). Update: expanded Joseph form and chi-square gate,
as RelativeEKF. Each tick draws one uniform then 3 normals (the stream never shifts).

Recorded per tick (:attr:`record`): NEES of the attitude block (theta, omega: 2 dof, ``nees``) and of
the whole state (6 dof, ``pose_nees``), attitude and rate errors, the NIS of every update (3 dof).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from proxops.core.small_linalg import mahalanobis_squared
from proxops.dynamics.planar_cubesat import PlanarCubeSatParams, rk4_step, wrap_angle as wrap
from proxops.errors import input_error
from proxops.navigation.mekf import van_loan


@dataclass
class PlanarPoseEKF:
    """Navigation (:class:`proxops.contracts.Navigation`) of the planar deputy (module docstring)."""

    params: PlanarCubeSatParams
    p0: np.ndarray
    position_sigma_m: float
    angle_sigma_rad: float
    q_accel_m2_s3: float = 1e-9
    q_angular_rad2_s3: float = 1e-8
    fov_rad: float = math.pi
    outage_probability: float = 0.0
    gate_probability: float = 0.9999
    max_substep_s: float = 0.5
    period_s: float | None = field(default=None, kw_only=True)

    def __post_init__(self):
        from scipy.stats import chi2

        self.p0 = np.asarray(self.p0, dtype=float)
        if self.p0.shape != (6, 6):
            raise input_error("navigation.initial_covariance", f"{self.p0.shape}", "must be 6x6", "SI")
        self._l0 = np.linalg.cholesky(self.p0)
        for name, v in (("navigation.range_sigma_m", self.position_sigma_m),
                        ("navigation.attitude_sigma_deg", self.angle_sigma_rad)):
            if not (math.isfinite(v) and v > 0.0):
                raise input_error(name, v, "must be > 0 for the planar pose filter")
        self.gate = float(chi2.ppf(self.gate_probability, 3))
        self.Qc = np.diag([0.0, 0.0, 0.0, self.q_accel_m2_s3, self.q_accel_m2_s3, self.q_angular_rad2_s3])
        self.R = np.diag([self.position_sigma_m ** 2] * 2 + [self.angle_sigma_rad ** 2])
        self.H = np.zeros((3, 6))
        self.H[0, 0] = self.H[1, 1] = self.H[2, 2] = 1.0
        self.events: list[tuple[str, str]] = []
        self.record: dict = {"t": [], "nees": [], "pose_nees": [], "att_err_rad": [], "rate_err_rad_s": [], "nis": [],
                             "updates": 0, "rejected": 0, "nees_dof": 2, "nis_dof": 3, "pose_nees_dof": 6}
        self.x = np.zeros(6)
        self.P = self.p0.copy()
        self.t: float | None = None
        self._u = np.zeros(2)

    def command(self, t: float, u: np.ndarray, kind: str) -> None:
        """The applied command [thrust N, wheel_acc rad/s^2], held until the next one."""
        self._u = np.asarray(u, dtype=float)[:2].copy()

    def jacobian(self, s: np.ndarray) -> np.ndarray:
        """Continuous F = d(ds/dt)/ds at ``s`` under the held command (module docstring)."""
        p = self.params
        n, a = p.mean_motion_rad_s, float(self._u[0]) / p.mass_kg
        F = np.zeros((6, 6))
        F[0, 3] = F[1, 4] = F[2, 5] = 1.0
        F[3, 0], F[3, 2], F[3, 4] = 3.0 * n * n, -math.sin(s[2]) * a, 2.0 * n
        F[4, 2], F[4, 3] = math.cos(s[2]) * a, -2.0 * n
        F[5, 5] = -p.damping_Nms / p.body_inertia_kgm2
        return F

    def propagate(self, t: float) -> None:
        """Predict to ``t`` (the plant's RK4 model under the held command, Van Loan Q_d per substep)."""
        dt = t - self.t
        if dt <= 0.0:
            return
        m = max(1, math.ceil(dt / self.max_substep_s))
        h = dt / m
        for _ in range(m):
            x1 = rk4_step(self.x, self._u, self.params, h)
            phi, qd = van_loan(self.jacobian(0.5 * (self.x + x1)), self.Qc, h)
            P = phi @ self.P @ phi.T + qd
            self.P = 0.5 * (P + P.T)
            self.x = x1
        self.t = t

    def visible(self, s: np.ndarray) -> bool:
        """The chief (line of sight -r) within half the field of view about the body x axis."""
        if self.fov_rad >= math.pi:
            return True
        r = math.hypot(s[0], s[1])
        if r == 0.0:
            return False
        return (-s[0] * math.cos(s[2]) - s[1] * math.sin(s[2])) / r >= math.cos(0.5 * self.fov_rad)

    def update(self, z: np.ndarray) -> bool:
        """Pose update (Joseph form, chi-square gate); False and an event when rejected."""
        P, H = self.P, self.H
        nu = z - self.x[:3]
        nu[2] = wrap(nu[2])
        HP = H @ P
        S = HP @ H.T + self.R
        Sinv = np.linalg.inv(S)
        nis = float(nu @ Sinv @ nu)
        self.record["nis"].append(nis)
        if not nis <= self.gate:
            self.record["rejected"] += 1
            self.events.append(("nav-rejected", f"pose measurement rejected: NIS {nis:.3g} > {self.gate:.3g} "
                                f"(chi-square {self.gate_probability:g}, 3 dof)"))
            return False
        K = HP.T @ Sinv
        self.x = self.x + K @ nu
        KHP = K @ HP
        P = P - KHP - KHP.T + K @ S @ K.T
        self.P = 0.5 * (P + P.T)
        self.record["updates"] += 1
        return True

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Navigation tick: (first call: truth + N(0, p0)), predict, sense, update; the estimate."""
        s = np.asarray(x_true, dtype=float)
        if self.t is None or t < self.t:
            self.x = s + self._l0 @ rng.standard_normal(6)
            self.P, self.t, self._u = self.p0.copy(), t, np.zeros(2)
            for v in self.record.values():
                if isinstance(v, list):
                    v.clear()
            self.record["updates"] = self.record["rejected"] = 0
        else:
            self.propagate(t)
        u = rng.random()
        e = rng.standard_normal(3)
        if u >= self.outage_probability and self.visible(s):
            self.update(s[:3] + np.array([self.position_sigma_m * e[0], self.position_sigma_m * e[1],
                                          self.angle_sigma_rad * e[2]]))
        err = s - self.x
        err[2] = wrap(err[2])
        rec = self.record
        rec["t"].append(float(t))
        rec["pose_nees"].append(mahalanobis_squared(np.ascontiguousarray(self.P), err))
        ea = err[[2, 5]]
        rec["nees"].append(mahalanobis_squared(self.P[np.ix_([2, 5], [2, 5])], ea))
        rec["att_err_rad"].append(abs(float(err[2])))
        rec["rate_err_rad_s"].append(abs(float(err[5])))
        out = self.x.copy()
        out[2] = wrap(out[2])
        return out
