"""Thruster models between the controller's command and the truth (all effects optional).

Every model follows :class:`proxops.contracts.Actuator`: ``apply(t, u, kind, rng)`` and
``period_s`` (None = once per controller sample)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from proxops.core.constants import G0
from proxops.errors import input_error


@dataclass
class ActuatorBase:
    """Defaults of an actuator model: applied once per controller sample."""

    period_s: float | None = field(default=None, kw_only=True)

    @property
    def zero_passthrough(self) -> bool:
        """True when ``apply`` of a zero command returns zero without drawing random numbers (the
        engine may then skip idle ticks, :mod:`proxops.sim.engine`). Default False (unknown)."""
        return False

    def apply(self, t: float, u: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
        raise NotImplementedError


@dataclass
class IdealActuator(ActuatorBase):
    """Applies the command unchanged."""

    zero_passthrough = True

    def apply(self, t: float, u: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
        return np.array(u, dtype=float)


@dataclass
class ThrusterModel(ActuatorBase):
    """Limits and execution errors of a translational thruster set.

    Units follow the command kind: m/s^2 for ``acceleration``, m/s for ``impulse``.

    - ``max_per_axis``: per-axis saturation (|u_i| <= max_per_axis), ``None`` = none.
    - ``max_norm``: saturation of the 2-norm (direction kept), ``None`` = none.
    - ``min_impulse``: commands whose norm is below this fire nothing (minimum impulse
      bit; same unit as the command).
    - ``magnitude_sigma``: relative 1-sigma magnitude error (e.g. 0.01 = 1 %).
    - ``pointing_sigma_rad``: 1-sigma pointing error (rad), a random small rotation.
    - ``missed_probability``: probability that a command is not executed at all.
    - ``missed_window_s``: when set, the missed-thrust draw is made once per window of this
      length (the first command in it) and cancels every command of the window: Algorithm 3
      cancels all impulses of one guidance interval together (eq. 28).
    - ``elevation_sigma_rad`` / ``azimuth_sigma_rad``: 1-sigma errors of the two direction
      angles of eq. (29) in the Hill frame, beta = asin(dv_z/|dv|) (out of plane) and
      alpha = atan2(dv_x, dv_y) (in plane, from along-track towards radial), re-composed as
      |dv| [cos b sin a, cos b cos a, sin b] (Alg. 3 step 5). The printed
      alpha = atan(v_t / v_n) does not invert step 5; atan2(v_r, v_t) does.
    (Wijayatunga et al. Alg. 3 / Table 3 execution-error model; eq. 28 draws
    M ~ N(0, 1) and compares it with p, which misses with probability Phi(p) ~ 0.5: the
    text's "with probability p" is implemented: U(0, 1) < p.)
    """

    max_per_axis: float | None = None
    max_norm: float | None = None
    min_impulse: float = 0.0
    magnitude_sigma: float = 0.0
    pointing_sigma_rad: float = 0.0
    missed_probability: float = 0.0
    missed_window_s: float | None = None
    elevation_sigma_rad: float = 0.0
    azimuth_sigma_rad: float = 0.0

    def __post_init__(self):
        p = self.missed_probability
        if not (isinstance(p, (int, float)) and 0.0 <= p <= 1.0):
            raise input_error("missed_probability", p, "must be a probability in [0, 1]")
        if self.missed_window_s is not None and not (math.isfinite(self.missed_window_s) and self.missed_window_s > 0):
            raise input_error("missed_window_s", self.missed_window_s, "must be a finite number > 0", "s")
        self._window = None
        self._window_missed = False

    @property
    def zero_passthrough(self) -> bool:
        """A zero command fires nothing and draws nothing unless missed thrusts are drawn per
        window (one draw per window, whatever the command)."""
        return not (self.missed_window_s is not None and self.missed_probability > 0.0)

    def limited(self, u: np.ndarray) -> np.ndarray:
        """The deterministic part of :meth:`apply` (saturations, minimum impulse bit): what the
        vehicle knows it commanded (a navigation filter propagates with it)."""
        u = np.array(u, dtype=float)
        if not u.any():  # nothing commanded (an idle tick): the zeros the steps below would return
            return np.zeros_like(u)
        if self.max_per_axis is not None:
            m = self.max_per_axis
            u = np.minimum(np.maximum(u, -m), m)  # = np.clip, without its dispatch overhead
        norm = math.sqrt(u @ u)  # = np.linalg.norm(u) (sqrt of the same dot product)
        if self.max_norm is not None and norm > self.max_norm:
            u *= self.max_norm / norm
            norm = self.max_norm
        if norm == 0.0 or norm < self.min_impulse:
            return np.zeros_like(u)
        return u

    def execution_covariance(self, u: np.ndarray) -> np.ndarray:
        """3x3 second moment E[d d^T] of the execution error d = applied - limited(u) (command unit),
        to first order in the error sigmas: magnitude s_m^2 u u^T; pointing (rotation vector
        phi ~ N(0, s_p^2 I), d = phi x u) s_p^2 (|u|^2 I - u u^T); eq. (29) angles s_b^2 g_b g_b^T +
        s_a^2 g_a g_a^T with g the derivatives of |u| [cos b sin a, cos b cos a, sin b]; a missed
        thrust (d = -u with probability p) p u u^T. A navigation filter adds it to its covariance
        (the process noise of the actuator)."""
        u = self.limited(np.asarray(u, dtype=float))
        m2 = float(u @ u)
        cov = np.zeros((3, 3))
        if m2 == 0.0 or u.size != 3:
            return cov
        uu = np.outer(u, u)
        cov += (self.magnitude_sigma ** 2 + self.missed_probability) * uu
        if self.pointing_sigma_rad > 0.0:
            cov += self.pointing_sigma_rad ** 2 * (m2 * np.eye(3) - uu)
        if self.elevation_sigma_rad > 0.0 or self.azimuth_sigma_rad > 0.0:
            m = math.sqrt(m2)
            b = math.asin(max(-1.0, min(1.0, float(u[2]) / m)))
            a = math.atan2(float(u[0]), float(u[1]))
            cb, sb, ca, sa = math.cos(b), math.sin(b), math.cos(a), math.sin(a)
            gb = m * np.array([-sb * sa, -sb * ca, cb])
            ga = m * np.array([cb * ca, -cb * sa, 0.0])
            cov += self.elevation_sigma_rad ** 2 * np.outer(gb, gb) + self.azimuth_sigma_rad ** 2 * np.outer(ga, ga)
        return cov

    def apply(self, t: float, u: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
        u = np.array(u, dtype=float)
        if self.missed_window_s is not None and self.missed_probability > 0.0:
            window = math.floor(t / self.missed_window_s + 1e-9)  # one draw per guidance window
            if window != self._window:
                self._window = window
                self._window_missed = bool(rng.random() < self.missed_probability)
            if self._window_missed:
                return np.zeros_like(u)
        if (u.shape == (3,) and self.max_norm is None and self.min_impulse == 0.0
                and self.elevation_sigma_rad == 0.0 and self.azimuth_sigma_rad == 0.0):
            return self._apply_3(u, rng)
        u = self.limited(u)
        if not (u != 0.0).any():
            return u
        if self.missed_window_s is None and self.missed_probability > 0.0 and rng.random() < self.missed_probability:
            return np.zeros_like(u)
        if self.magnitude_sigma > 0.0:
            u *= 1.0 + self.magnitude_sigma * rng.standard_normal()
        if self.pointing_sigma_rad > 0.0 and u.size == 3:
            u = _rotate_small(u, self.pointing_sigma_rad * rng.standard_normal(3))
        if (self.elevation_sigma_rad > 0.0 or self.azimuth_sigma_rad > 0.0) and u.size == 3:
            u = perturb_angles(u, self.elevation_sigma_rad * rng.standard_normal(),
                               self.azimuth_sigma_rad * rng.standard_normal())
        return u


    def _apply_3(self, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """:meth:`apply` of a 3-vector without a norm limit, minimum impulse bit or angle errors,
        on plain floats (the per-step path of a closed loop): the same operations in the same
        order, hence the same numbers and draws. The zero test is the sum of squares (no
        cancellation: zero exactly when ``limited``'s norm is)."""
        ux, uy, uz = u.tolist()
        m = self.max_per_axis
        if m is not None:  # = np.minimum(np.maximum(u, -m), m), NaN kept
            ux, uy, uz = min(max(ux, -m), m), min(max(uy, -m), m), min(max(uz, -m), m)
        if ux * ux + uy * uy + uz * uz == 0.0:
            return np.zeros(3)
        if self.missed_window_s is None and self.missed_probability > 0.0 and rng.random() < self.missed_probability:
            return np.zeros(3)  # (per-window misses were drawn in apply)
        if self.magnitude_sigma > 0.0:
            f = 1.0 + self.magnitude_sigma * rng.standard_normal()
            ux, uy, uz = ux * f, uy * f, uz * f
        if self.pointing_sigma_rad > 0.0:
            ps = self.pointing_sigma_rad
            kx, ky, kz = rng.standard_normal(3).tolist()
            ux, uy, uz = _rotate_small_xyz(ux, uy, uz, ps * kx, ps * ky, ps * kz)
        return np.array([ux, uy, uz])


def perturb_angles(dv: np.ndarray, d_beta: float, d_alpha: float) -> np.ndarray:
    """Eq. (29), Alg. 3 step 5: add d_beta to beta = asin(dv_z/|dv|) and d_alpha to
    alpha = atan2(dv_x, dv_y), keep |dv|; returns |dv| [cos b sin a, cos b cos a, sin b]."""
    m = math.sqrt(float(dv @ dv))
    if m == 0.0:
        return dv
    beta = math.asin(max(-1.0, min(1.0, float(dv[2]) / m))) + d_beta
    alpha = math.atan2(float(dv[0]), float(dv[1])) + d_alpha
    cb = math.cos(beta)
    return np.array([m * cb * math.sin(alpha), m * cb * math.cos(alpha), m * math.sin(beta)])


@dataclass(frozen=True)
class ThrusterParameter:
    """One parameter of :class:`ThrusterModel`, declared once for the model and the scenario's
    ``[actuator]`` section (built from :data:`THRUSTER_PARAMETERS` in proxops.scenarios.schema).

    field: ThrusterModel attribute (SI); key: scenario key (edge unit, e.g. ``_deg``);
    default: scenario default (None: no limit); ge / gt / le: bounds of the scenario value;
    to_model: scenario value -> model value (e.g. math.radians)."""

    field: str
    key: str
    default: float | None
    description: str
    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    to_model: object = None


THRUSTER_PARAMETERS = (
    ThrusterParameter("max_per_axis", "max_per_axis", None, "per-axis saturation |u_i| <= max_per_axis, command "
                      "unit (m/s^2 or m/s); none: no limit", gt=0.0),
    ThrusterParameter("max_norm", "max_norm", None, "saturation of |u| (direction kept), command unit; none: no limit",
                      gt=0.0),
    ThrusterParameter("min_impulse", "min_impulse", 0.0, "commands with |u| below this fire nothing (minimum impulse "
                      "bit), command unit", ge=0.0),
    ThrusterParameter("magnitude_sigma", "magnitude_sigma", 0.0, "relative 1-sigma magnitude error (0.01 = 1 %)", ge=0.0),
    ThrusterParameter("pointing_sigma_rad", "pointing_sigma_deg", 0.0, "1-sigma pointing error (random small rotation)",
                      ge=0.0, to_model=math.radians),
    ThrusterParameter("missed_probability", "missed_probability", 0.0, "probability that a command is not executed "
                      "at all", ge=0.0, le=1.0),
)


def thruster_from_values(values: dict) -> ThrusterModel:
    """A :class:`ThrusterModel` from scenario values keyed as in :data:`THRUSTER_PARAMETERS`."""
    kwargs = {}
    for p in THRUSTER_PARAMETERS:
        v = values.get(p.key, p.default)
        kwargs[p.field] = p.to_model(v) if (p.to_model is not None and v is not None) else v
    return ThrusterModel(**kwargs)


def _rotate_small(v: np.ndarray, rotation_vector: np.ndarray) -> np.ndarray:
    """Rotate the 3-vector ``v`` by the rotation vector (rad) with Rodrigues' formula
    (written on plain floats: this runs once per command in every Monte Carlo run)."""
    kx, ky, kz = rotation_vector.tolist()
    if kx * kx + ky * ky + kz * kz == 0.0:
        return v
    return np.array(_rotate_small_xyz(*v.tolist(), kx, ky, kz))


def _rotate_small_xyz(vx: float, vy: float, vz: float, kx: float, ky: float, kz: float) -> tuple[float, float, float]:
    """:func:`_rotate_small` on floats: (vx, vy, vz) rotated by the rotation vector (kx, ky, kz) (rad)."""
    angle = math.sqrt(kx * kx + ky * ky + kz * kz)
    if angle == 0.0:
        return vx, vy, vz
    kx, ky, kz = kx / angle, ky / angle, kz / angle
    c, s = math.cos(angle), math.sin(angle)
    kdotv = (kx * vx + ky * vy + kz * vz) * (1.0 - c)
    return (vx * c + (ky * vz - kz * vy) * s + kx * kdotv,
            vy * c + (kz * vx - kx * vz) * s + ky * kdotv,
            vz * c + (kx * vy - ky * vx) * s + kz * kdotv)


def propellant_mass_kg(dv_mps: float, wet_mass_kg: float, isp_s: float) -> float:
    """Rocket equation: propellant used for ``dv_mps`` from ``wet_mass_kg`` at ``isp_s``."""
    return wet_mass_kg * (1.0 - np.exp(-dv_mps / (isp_s * G0)))
