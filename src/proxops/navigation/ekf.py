"""Relative-navigation EKF on the Hill state with simulated sensors.

State ``x = [x, y, z, vx, vy, vz]`` (Hill/RTN, m, m/s): x radial out, y along-track, z normal.

Process model: the exact Clohessy-Wiltshire transition ``Phi(dt)`` (:func:`proxops.core.cw.cw_stm`)
with the controller's commanded acceleration through the exact ZOH input matrix, or its impulse
added to the velocity at the start of the step; or, with a ``predictor``
(:class:`proxops.propagation.relative_predictor.HillPredictor`, scenario ``process_model = "j2"``), the
mean by the nonlinear two-body + J2 relative motion (the covariance still by the CW Phi). Process
noise: white acceleration of power spectral density ``q`` (m^2/s^3) on each axis entering through
B = [0; I] (what the process model leaves out); its discrete covariance
``Q_d = int_0^dt Phi(s) B q B^T Phi(s)^T ds`` is computed exactly (Van Loan's matrix exponential),
cached per step length. Thruster execution errors: at each command the actuator's error covariance
(``command_covariance``, from its error model) is added -- at the burn to the velocity block for an
impulse, through B_zoh for a held acceleration.

Consistency (:mod:`proxops.navigation.consistency`): every tick records the NEES of the
estimate against the true Hill state the tick is given, every measurement its NIS
(:meth:`RelativeEKF.consistency_record`, stored by the engine), and an innovation-whiteness monitor
flags windows whose innovations are correlated (event ``nav-overconfident``): a covariance too small
for the errors it should cover, which the NIS alone misses when the measurement noise dominates S.

Sensors (the chaser sees the target along rho = -r, axes parallel to Hill):

* ``range-bearing``: ``[|rho|, az, el]``, az = atan2(rho_y, rho_x), el = asin(rho_z / |rho|). The
  azimuth is singular on the z axis (rho_x = rho_y = 0: d az / d rho ~ 1 / sqrt(rho_x^2 + rho_y^2)).
  Within ``POLE_SIN`` of it (sqrt(rho_x^2 + rho_y^2) < 0.02 |rho| for the predicted line of sight, 1.15 deg
  from the orbit normal) the update uses the measured unit line of sight u(az, el) = [cos el cos az,
  cos el sin az, sin el] instead of the angles (defined everywhere, also at el = +-90 deg): the innovation
  is [range - |rho_hat|, t1 . u, t2 . u] with t1, t2 orthonormal and perpendicular to the predicted line
  of sight, H = -[u_hat; t1 / |rho_hat|; t2 / |rho_hat|] and R = diag(sigma_r^2, sigma_ang^2, sigma_ang^2).
  The isotropic tangent-plane noise is that of a physical angle sensor; the simulated one draws its noise
  in azimuth and elevation, and an azimuth error moves the line of sight by cos(el) sigma_az only: mapped
  exactly (J diag J^T) that component would be nearly noise-free (exactly at el = +-90 deg), P would lose
  rank, so R is conservative by up to 1 / cos(el) in that one direction inside the 1.15 deg zone;
* ``pose``: relative position ``r`` (3 components).

Noise 1-sigma may grow with range: sigma(rho) = sigma * (f + (1 - f) rho / rho_ref) -- the
form of Wijayatunga et al. §5.1.2 (there for 3-sigma with f = 0.02, rho_ref = r_AS);
without ``rho_ref`` it is constant. Angles keep a constant sigma. Measurements are dropped
outside the field of view (full cone angle about the boresight), with a random outage
probability, or while the target is in the Earth's shadow (eclipse dropout). Each update
tick draws the same numbers (one uniform, then one normal per measurement component) whatever
happens, so a run's stream never shifts.

Update: EKF with Joseph form; a measurement whose normalised innovation squared (NIS) exceeds
the chi-square quantile at ``gate_probability`` is rejected and recorded as an engine event
(``nav-rejected``).

Re-initialisation after filter collapse (``reinit_after_rejections = k > 0``): a filter whose
covariance no longer covers its error rejects every measurement and never recovers on its own
(the gate protects the wrong estimate). The filter is declared collapsed when the mean NIS of
its last k measurements (accepted or rejected) exceeds the chi-square bound of that mean,
chi2.ppf(gate_probability, m k) / k -- k consecutive rejections always trip it, and so does an
NIS persistently above its expected value m without single rejections. The next measurement
then re-initialises it: position from the inverse measurement model (pose: z; range-bearing:
r = -|rho| [cos el cos az, cos el sin az, sin el]) with that measurement's covariance J R J^T,
the velocity estimate kept with a 1-sigma of ``reinit_velocity_sigma_mps`` per axis (inflated:
the position-only measurements that follow observe it), no cross-covariance; an engine event
``nav-reinit``. State layout: the filter estimates the position and velocity blocks of the
plant's :class:`proxops.core.layout.StateLayout` (``layout``; default the 6-state Hill layout).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from proxops.core.cw import cw_input_matrix_zoh, cw_stm, cw_matrices
from proxops.core.layout import StateLayout
from proxops.core.small_linalg import gated_kalman_update, mahalanobis_squared, symmetrised, whitened
from proxops.errors import input_error
from proxops.navigation.consistency import WhitenessMonitor

SENSORS = ("range-bearing", "pose")
POLE_SIN = 0.02  # range-bearing: sqrt(rho_x^2 + rho_y^2) / |rho| below this -> unit line-of-sight update
NIS_CAP = 1e12  # NIS values above this count as this in the collapse window (inf/NaN included)


def cw_process_noise(n: float, dt: float, q: float) -> np.ndarray:
    """Exact discrete process noise of white acceleration (PSD ``q`` m^2/s^3 per axis) over ``dt``
    under CW dynamics: Van Loan, expm([[-A, q B B^T], [0, A^T]] dt) -> Q_d = F22^T F12."""
    from scipy.linalg import expm

    a, b = cw_matrices(n)
    m = np.zeros((12, 12))
    m[:6, :6] = -a
    m[:6, 6:] = q * (b @ b.T)
    m[6:, 6:] = a.T
    f = expm(m * dt)
    qd = f[6:, 6:].T @ f[:6, 6:]
    return 0.5 * (qd + qd.T)


def range_bearing(rho: np.ndarray) -> np.ndarray:
    """[range m, azimuth rad, elevation rad] of the line of sight ``rho`` (m)."""
    r = math.sqrt(float(rho @ rho))
    return np.array([r, math.atan2(rho[1], rho[0]), math.asin(max(-1.0, min(1.0, rho[2] / r)))])


def range_bearing_jacobian(rho: np.ndarray) -> np.ndarray:
    """d[range, az, el]/d rho (3x3)."""
    x, y, z = rho
    rh2 = x * x + y * y
    rh = math.sqrt(rh2)
    r2 = rh2 + z * z
    r = math.sqrt(r2)
    return np.array([
        [x / r, y / r, z / r],
        [-y / rh2, x / rh2, 0.0],
        [-x * z / (r2 * rh), -y * z / (r2 * rh), rh / r2],
    ])


@dataclass
class SensorModel:
    """Simulated relative sensor (see the module docstring). Angles in rad, lengths in m."""

    kind: str = "range-bearing"
    range_sigma_m: float = 0.1  # range (range-bearing) or per-axis position (pose) 1-sigma at rho_ref
    angle_sigma_rad: float = 1e-3
    sigma_reference_range_m: float | None = None  # None: constant sigma
    sigma_floor_fraction: float = 0.02
    fov_rad: float = math.pi  # full cone angle, (0, pi]
    boresight: np.ndarray | None = None  # unit vector (Hill axes); None: the initial line of sight
    outage_probability: float = 0.0
    illuminated: object = None  # callable t -> bool (eclipse dropout), None: always lit

    def __post_init__(self):
        if self.kind not in SENSORS:
            raise input_error("navigation.sensor", self.kind, f"must be one of {', '.join(SENSORS)}")
        for name, v in (("range_sigma_m", self.range_sigma_m), ("angle_sigma_deg", self.angle_sigma_rad)):
            if not (math.isfinite(v) and v >= 0.0):
                raise input_error(f"navigation.{name}", v, "must be >= 0", name.rsplit("_", 1)[-1])
        if not (0.0 < self.fov_rad <= math.pi + 1e-12):
            raise input_error("navigation.fov_deg", math.degrees(self.fov_rad), "must be in (0, 180]", "deg")
        if not (0.0 <= self.outage_probability <= 1.0):
            raise input_error("navigation.outage_probability", self.outage_probability, "must be in [0, 1]")
        self.m = 3

    def sigma(self, rng_m: float) -> np.ndarray:
        """1-sigma of each measurement component at range ``rng_m``."""
        s = self.range_sigma_m
        if self.sigma_reference_range_m:
            f = self.sigma_floor_fraction
            s = s * (f + (1.0 - f) * rng_m / self.sigma_reference_range_m)
        if self.kind == "pose":
            return np.array([s, s, s])
        return np.array([s, self.angle_sigma_rad, self.angle_sigma_rad])

    def h(self, x: np.ndarray) -> np.ndarray:
        """Noise-free measurement of the Hill state ``x``."""
        if self.kind == "pose":
            return np.array(x[:3], dtype=float)
        return range_bearing(-np.asarray(x[:3], dtype=float))

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """dh/dx (3x6)."""
        H = np.zeros((3, 6))
        if self.kind == "pose":
            H[0, 0] = H[1, 1] = H[2, 2] = 1.0
        else:
            H[:, :3] = range_bearing_jacobian(-x[:3])
            H[:, :3] *= -1.0
        return H

    def h_and_jacobian(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(h(x), dh/dx) in one pass (the update's hot path; same formulas as h and jacobian)."""
        H = np.zeros((3, 6))
        if self.kind == "pose":
            H[0, 0] = H[1, 1] = H[2, 2] = 1.0
            return x[:3].copy(), H
        x0, x1, x2 = -float(x[0]), -float(x[1]), -float(x[2])  # rho = -r
        rh2 = x0 * x0 + x1 * x1
        rh = math.sqrt(rh2)
        r2 = rh2 + x2 * x2
        r = math.sqrt(r2)
        H[0, :3] = (-x0 / r, -x1 / r, -x2 / r)
        H[1, :3] = (x1 / rh2, -x0 / rh2, 0.0)
        H[2, :3] = (x0 * x2 / (r2 * rh), x1 * x2 / (r2 * rh), -rh / r2)
        return np.array([r, math.atan2(x1, x0), math.asin(max(-1.0, min(1.0, x2 / r)))]), H

    def near_pole(self, x: np.ndarray) -> bool:
        """Range-bearing and the line of sight of ``x`` within POLE_SIN of the z axis (module docstring)."""
        if self.kind != "range-bearing":
            return False
        x0, x1, x2 = float(x[0]), float(x[1]), float(x[2])
        rh2 = x0 * x0 + x1 * x1
        return rh2 < POLE_SIN * POLE_SIN * (rh2 + x2 * x2)

    def tangent_innovation(self, z: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(innovation (3,), H (3x6), R (3x3)) of a range-bearing measurement ``z`` in the unit
        line-of-sight form (module docstring), valid at every line of sight (used near the z axis)."""
        rho = -np.asarray(x[:3], dtype=float)
        r_hat = float(np.linalg.norm(rho))
        u_hat = rho / r_hat
        ex = np.array([1.0, 0.0, 0.0]) if abs(u_hat[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        t1 = ex - (ex @ u_hat) * u_hat
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(u_hat, t1)
        rng, az, el = (float(v) for v in z)
        ca, sa, ce, se = math.cos(az), math.sin(az), math.cos(el), math.sin(el)
        u = np.array([ce * ca, ce * sa, se])
        nu = np.array([rng - r_hat, t1 @ u, t2 @ u])
        H = np.zeros((3, 6))
        H[0, :3], H[1, :3], H[2, :3] = -u_hat, -t1 / r_hat, -t2 / r_hat
        s_r, s_a, s_e = self.sigma(r_hat)
        R = np.zeros((3, 3))
        R[0, 0] = s_r * s_r
        R[1, 1] = R[2, 2] = max(s_a, s_e) ** 2
        return nu, H, R

    def residual(self, z: np.ndarray, zhat: np.ndarray) -> np.ndarray:
        """z - zhat with the azimuth wrapped to (-pi, pi]."""
        d = z - zhat
        if self.kind == "range-bearing":
            d[1] = (d[1] + math.pi) % (2.0 * math.pi) - math.pi
        return d

    def position_from(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inverse measurement model: (relative position r of the chaser (m), its 3x3 covariance) of one
        measurement ``z``: pose, r = z and R; range-bearing, r = -rho(z) and J R J^T with J = dr/dz
        (first order), the sigmas taken at the measured range."""
        if self.kind == "pose":
            r = np.array(z, dtype=float)
            return r, np.diag(self.sigma(float(np.linalg.norm(r))) ** 2)
        rng, az, el = (float(v) for v in z)
        ca, sa, ce, se = math.cos(az), math.sin(az), math.cos(el), math.sin(el)
        rho = rng * np.array([ce * ca, ce * sa, se])
        j = -np.array([[ce * ca, -rng * ce * sa, -rng * se * ca],
                       [ce * sa, rng * ce * ca, -rng * se * sa],
                       [se, 0.0, rng * ce]])
        return -rho, j @ np.diag(self.sigma(abs(rng)) ** 2) @ j.T

    def visible(self, t: float, x_true: np.ndarray) -> bool:
        """In the field of view and illuminated."""
        rho = -np.asarray(x_true[:3], dtype=float)
        r = math.sqrt(float(rho @ rho))
        if r == 0.0:
            return False
        if self.fov_rad < math.pi and self.boresight is not None:
            if float(rho @ self.boresight) / r < math.cos(0.5 * self.fov_rad):
                return False
        return self.illuminated is None or bool(self.illuminated(t))

    def draw(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
        """One measurement of the truth, or None (outage, out of view, eclipse). Always draws one
        uniform then ``m`` normals."""
        u = rng.random()
        e = rng.standard_normal(self.m)
        if self.boresight is None:  # first call: point the sensor along the initial line of sight
            rho = -np.asarray(x_true[:3], dtype=float)
            nr = np.linalg.norm(rho)
            self.boresight = rho / nr if nr > 0 else np.array([1.0, 0.0, 0.0])
        if u < self.outage_probability or not self.visible(t, x_true):
            return None
        z = self.h(x_true)
        return z + self.sigma(float(np.linalg.norm(x_true[:3]))) * e


@dataclass
class RelativeEKF:
    """EKF navigation (:class:`proxops.contracts.Navigation`) on the Hill state.

    ``n``: mean motion (rad/s); ``q_m2_s3``: white-acceleration PSD per axis; ``p0``: initial
    covariance (6x6, SI, positive definite): the initial estimate is the truth plus one draw from
    N(0, p0) with the navigation stream. ``gate_probability``: chi-square gate confidence.
    ``command_sigma_fraction``: the commanded control is executed with an isotropic 1-sigma error
    of this fraction of its norm per axis (impulse: added to the velocity covariance at the burn;
    acceleration: through the ZOH input matrix), so thruster errors do not look like outliers.
    The engine gives the commanded control through :meth:`command` and drains :attr:`events`.
    ``reinit_after_rejections`` (k, 0 = off) and ``reinit_velocity_sigma_mps``: re-initialisation
    after a collapse (module docstring). ``layout``: the plant's state layout; the filter estimates
    its position and velocity blocks (other blocks, if any, are passed through from the truth).
    """

    n: float
    sensor: SensorModel
    p0: np.ndarray
    q_m2_s3: float = 1e-10
    gate_probability: float = 0.9999
    command_sigma_fraction: float = 0.0  # 1-sigma execution error of a command, fraction of |u| per axis
    reinit_after_rejections: int = 0  # k: collapse when the mean NIS of the last k measurements is out of bound
    reinit_velocity_sigma_mps: float = 0.1  # 1-sigma velocity per axis after a re-initialisation
    layout: StateLayout | None = None
    predictor: object = None  # predict(t0, x, u, kind, dt) -> x (mean process model); None: CW
    command_covariance: object = None  # u -> 3x3 execution-error covariance of the actuator; None: none
    whiteness_window: int = 100  # accepted measurements per window of the innovation-whiteness test
    whiteness_lags: int = 20
    whiteness_probability: float = 0.9999  # one-sided; false alarm 1 - this per window
    period_s: float | None = field(default=None, kw_only=True)

    def __post_init__(self):
        from scipy.stats import chi2

        self.p0 = np.asarray(self.p0, dtype=float)
        if self.p0.shape != (6, 6) or not np.allclose(self.p0, self.p0.T, atol=0.0, rtol=1e-12):
            raise input_error("navigation.initial_covariance", "given", "must be a symmetric 6x6 matrix", "SI")
        try:
            self._l0 = np.linalg.cholesky(self.p0)
        except np.linalg.LinAlgError:
            raise input_error("navigation.initial_covariance", f"eigenvalues {np.linalg.eigvalsh(self.p0).min():.3g}..",
                              "must be positive definite (all eigenvalues > 0)", "SI") from None
        if self.q_m2_s3 < 0:
            raise input_error("navigation.process_noise_m2_s3", self.q_m2_s3, "must be >= 0", "m^2/s^3")
        if not 0.0 < self.gate_probability < 1.0:
            raise input_error("navigation.gate_probability", self.gate_probability, "must be in (0, 1)")
        self.gate = float(chi2.ppf(self.gate_probability, self.sensor.m))
        k = self.reinit_after_rejections
        if not (isinstance(k, (int, np.integer)) and k >= 0):
            raise input_error("navigation.reinit_after_rejections", k, "must be an integer >= 0 (0: no re-initialisation)")
        if not (math.isfinite(self.reinit_velocity_sigma_mps) and self.reinit_velocity_sigma_mps > 0):
            raise input_error("navigation.reinit_velocity_sigma_mps", self.reinit_velocity_sigma_mps, "must be > 0", "m/s")
        self.collapse_bound = float(chi2.ppf(self.gate_probability, self.sensor.m * k)) / k if k else math.inf
        self._slices = _hill_slices(self.layout)
        self._cache: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self.events: list[tuple[str, str]] = []
        self.x = np.zeros(6)
        self.P = self.p0.copy()
        self.t: float | None = None
        self._u = np.zeros(3)
        self._kind = "acceleration"
        self._impulse_t: float | None = None
        self.nis: list[float] = []
        self.nis_t: list[float] = []
        self.nees: list[float] = []
        self.nees_t: list[float] = []
        self.rejected = 0
        self.updates = 0
        self.reinits = 0
        self._window: deque[float] = deque(maxlen=max(1, k))
        self._window_sum = 0.0
        self._collapse_sum = self.collapse_bound * k if k else math.inf
        self._collapsed: str | None = None
        self.monitor = WhitenessMonitor(self.whiteness_window, self.whiteness_lags, self.whiteness_probability)
        self.overconfident_windows = 0

    def reset(self, t: float, x_est: np.ndarray, P: np.ndarray | None = None) -> None:
        """Start from the estimate ``x_est`` with covariance ``P`` (default p0) at ``t``."""
        self.x = np.array(x_est, dtype=float)
        self.P = self.p0.copy() if P is None else np.array(P, dtype=float)
        self.t = t
        self._u, self._kind, self._impulse_t = np.zeros(3), "acceleration", None
        self.nis, self.rejected, self.updates, self.reinits = [], 0, 0, 0
        self.nis_t, self.nees, self.nees_t = [], [], []
        self._window.clear()
        self._window_sum = 0.0
        self._collapsed = None
        self.events.clear()
        self.monitor.reset()
        self.overconfident_windows = 0

    def matrices(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Phi, B_zoh, Q_d) of a step of ``dt`` s (cached)."""
        key = round(dt, 9)
        out = self._cache.get(key)
        if out is None:
            out = (cw_stm(self.n, dt), cw_input_matrix_zoh(self.n, dt), cw_process_noise(self.n, dt, self.q_m2_s3))
            self._cache[key] = out
        return out

    def command(self, t: float, u: np.ndarray, kind: str) -> None:
        """The controller's command at ``t`` (held acceleration m/s^2, or impulse m/s at ``t``)."""
        self._u = np.asarray(u, dtype=float)[:3]
        self._kind = kind
        self._impulse_t = t if kind == "impulse" else None

    def propagate(self, t: float) -> None:
        """Predict the estimate and covariance to ``t`` with the commanded control.

        Mean: the ``predictor`` (nonlinear two-body + J2, :class:`proxops.propagation.relative_predictor.HillPredictor`)
        or, without one, the exact CW transition. Covariance: P <- Phi P Phi^T + Q_d (CW Phi; the J2 and
        nonlinear corrections to Phi are O(J2 (R_E/r)^2, rho/r) relative and enter P at that order only)
        plus the execution error of the command (:meth:`execution_covariance`)."""
        dt = t - self.t
        if dt <= 0.0:
            return
        phi, bd, qd = self.matrices(dt)
        x = self.x
        impulse = self._kind == "impulse" and self._impulse_t is not None and abs(self._impulse_t - self.t) < 1e-9
        if self._kind == "impulse":
            self._impulse_t = None
            u = self._u if impulse else np.zeros(3)
            if impulse and self._u.any():  # (a zero impulse has no execution error)
                cu = self.execution_covariance(self._u)
                if cu is not None:  # execution error of the impulse (m/s), at the burn
                    self.P = self.P.copy()
                    self.P[3:, 3:] += cu
            if self.predictor is not None:
                self.x = self.predictor.predict(self.t, x, u, "impulse", dt)
            else:
                if impulse:
                    x = x.copy()
                    x[3:6] += self._u
                self.x = phi @ x
            self.P = phi @ self.P @ phi.T + qd
            self.t = t
            return
        if self.predictor is not None:
            self.x = self.predictor.predict(self.t, x, self._u, "acceleration", dt)
        else:
            self.x = phi @ x + bd @ self._u
        self.P = phi @ self.P @ phi.T + qd
        if self._u.any():  # ZOH acceleration execution error through B_zoh
            cu = self.execution_covariance(self._u)
            if cu is not None:
                self.P = self.P + bd @ cu @ bd.T
        self.t = t

    def execution_covariance(self, u: np.ndarray) -> np.ndarray | None:
        """3x3 covariance of the executed minus the commanded control ``u`` (command unit): the
        actuator's error model (``command_covariance``, e.g.
        :meth:`proxops.actuators.ThrusterModel.execution_covariance`) plus the isotropic
        ``command_sigma_fraction`` |u| per axis; None when both are absent."""
        out = None
        if self.command_covariance is not None:
            out = np.asarray(self.command_covariance(u), dtype=float)
        if self.command_sigma_fraction > 0.0:
            iso = np.eye(3) * (self.command_sigma_fraction * float(np.linalg.norm(u))) ** 2
            out = iso if out is None else out + iso
        return out

    def update(self, t: float, z: np.ndarray) -> bool:
        """Measurement update with ``z``; False (and an event) when the chi-square gate rejects it.

        Joseph form expanded, (I-KH)P(I-KH)^T + KRK^T = P - K HP - (K HP)^T + K S K^T, with the
        3x3 innovation covariance S inverted in closed form (adjugate). A collapsed filter (module
        docstring) is re-initialised from ``z`` instead (True, event ``nav-reinit``)."""
        if self._collapsed is not None:
            self.reinitialise(t, z)
            return True
        x, P, sensor = self.x, self.P, self.sensor
        if sensor.near_pole(x):  # azimuth singular: unit line-of-sight form
            nu, H, R = sensor.tangent_innovation(z, x)
        else:
            zhat, H = sensor.h_and_jacobian(x)
            r = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
            R = np.eye(3) * sensor.sigma(r) ** 2
            nu = sensor.residual(z, zhat)
        nu = np.ascontiguousarray(nu, dtype=float)
        dx, P_new, S, nis, accepted = gated_kalman_update(np.ascontiguousarray(P), H, np.ascontiguousarray(R, dtype=float),
                                                          nu, self.gate)
        self.nis.append(nis)
        self.nis_t.append(t)
        if self.reinit_after_rejections:
            self._check_collapse(nis)
        if not accepted:
            self.rejected += 1
            self.events.append(("nav-rejected", f"{sensor.kind} measurement rejected: NIS {nis:.3g} > "
                                f"{self.gate:.3g} (chi-square {self.gate_probability:g}, {sensor.m} dof)"))
            return False
        z = self.monitor.add(whitened(S, nu))  # whitened innovation
        if self.monitor.flagged(z):
            self.overconfident_windows += 1
            self.events.append(("nav-overconfident", f"innovations not white: z = {z:.3g} > {self.monitor.bound:.3g} "
                                f"over the last {self.monitor.window} measurements (lags 1-{self.monitor.lags}, "
                                f"one-sided {self.monitor.probability:g}): the covariance is too small"))
        self.x, self.P = x + dx, symmetrised(P_new)
        self.updates += 1
        return True

    def consistency_record(self) -> tuple[dict, dict]:
        """(series, meta) for the run's record: ``{"nav_nees": (t, NEES), "nav_nis": (t, NIS)}`` (s, -)
        at every filter tick / measurement (NEES after the tick's update, from the true Hill state the
        tick was given; NIS of every measurement, gated or not), and the dimensions and whiteness
        statistics (:mod:`proxops.navigation.consistency`)."""
        series = {"nav_nees": (np.array(self.nees_t), np.array(self.nees)),
                  "nav_nis": (np.array(self.nis_t), np.array(self.nis))}
        meta = {"nav_nees_dim": 6, "nav_nis_dim": self.sensor.m, "nav_whiteness_z": self.monitor.z_all(),
                "nav_whiteness_bound": self.monitor.bound, "nav_whiteness_window": self.monitor.window,
                "nav_overconfident_windows": self.overconfident_windows}
        return series, meta

    def _check_collapse(self, nis: float) -> None:
        """Collapse test on the NIS window: mean of the last k NIS above chi2.ppf(p, m k) / k (a running
        sum; each NIS capped at 1e12, far above any bound, so that inf/NaN cannot poison the sum)."""
        w = self._window
        v = nis if nis < NIS_CAP else NIS_CAP  # NaN -> cap
        full = len(w) == w.maxlen
        if full:
            self._window_sum -= w[0]
        w.append(v)
        self._window_sum += v
        if (full or len(w) == w.maxlen) and self._window_sum > self._collapse_sum:
            k = len(w)
            self._collapsed = (f"mean NIS {sum(w) / k:.3g} of the last {k} measurements > {self.collapse_bound:.3g} "
                               f"(chi-square {self.gate_probability:g}, {self.sensor.m * k} dof / {k})")

    def reinitialise(self, t: float, z: np.ndarray) -> None:
        """Restart from the measurement ``z`` (position and its covariance from the inverse measurement
        model), keeping the velocity estimate with the inflated sigma ``reinit_velocity_sigma_mps``."""
        r, p_rr = self.sensor.position_from(z)
        x = self.x.copy()
        x[:3] = r
        P = np.zeros((6, 6))
        P[:3, :3] = p_rr
        P[3:, 3:] = np.eye(3) * self.reinit_velocity_sigma_mps ** 2
        self.x, self.P, self.t = x, P, t
        self.reinits += 1
        self.events.append(("nav-reinit", f"filter collapse ({self._collapsed}): re-initialised from the "
                            f"{self.sensor.kind} measurement at t = {t:.6g} s, velocity sigma "
                            f"{self.reinit_velocity_sigma_mps:g} m/s"))
        self._collapsed = None
        self._window.clear()
        self._window_sum = 0.0

    def measure(self, t: float, x_true: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Navigation tick: (first call: initialise from truth + N(0, p0)), propagate, sense, update.
        Reads and returns the plant's state (its layout); the Hill blocks are the filter's estimate."""
        x_full = np.asarray(x_true, dtype=float)
        x_hill = x_full if self._slices is None else np.concatenate([x_full[self._slices[0]], x_full[self._slices[1]]])
        if self.t is None or t < self.t:
            self.reset(t, x_hill[:6] + self._l0 @ rng.standard_normal(6))
        else:
            self.propagate(t)
        z = self.sensor.draw(t, x_hill, rng)
        if z is not None:
            self.update(t, z)
        e = x_hill[:6] - self.x
        self.nees.append(mahalanobis_squared(np.ascontiguousarray(self.P), e))
        self.nees_t.append(t)
        if self._slices is None:
            return self.x.copy()
        out = x_full.copy()
        out[self._slices[0]], out[self._slices[1]] = self.x[:3], self.x[3:]
        return out


def _hill_slices(layout: StateLayout | None) -> tuple[slice, slice] | None:
    """(position, velocity) slices of the plant state the filter estimates; None for the plain
    6-state Hill layout [r; v] (the fast path)."""
    if layout is None:
        return None
    pos, vel = layout.first("position"), layout.first("velocity")
    if pos is None or vel is None or pos.size != 3 or vel.size != 3:
        raise input_error("navigation.model", "ekf", "needs a plant state with a 3-component position and a "
                          "3-component velocity block (the Hill relative state); allowed here: noise")
    if layout.n_x == 6 and (pos.start, vel.start) == (0, 3):
        return None
    return pos.slice, vel.slice
