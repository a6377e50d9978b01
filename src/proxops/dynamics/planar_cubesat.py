"""Planar underactuated 6U CubeSat deputy in Hill's frame (Aborizk et al. §2, §4).

State ``s = [x, y, theta, vx, vy, omega]`` (m, m, rad, m/s, m/s, rad/s): in-plane Hill/RTN
position (x radial out, y along-track) and velocity, body angle ``theta`` measured
counter-clockwise about +z from the Hill x axis, and its rate. Control
``u = [f_x, wheel_acc]``: thrust along the body x axis (N, both signs) and the reaction
wheel's angular acceleration relative to the body (rad/s^2).

    xdd     = 3 n^2 x + 2 n yd + cos(theta) f_x / m          (eq. 1, 6-8)
    ydd     = -2 n xd          + sin(theta) f_x / m          (eq. 2, 6-8)
    thetadd = (-D wheel_acc - c omega) / I_z                 (eq. 4 with c = 0, eq. 5)

The right-hand side is written once (:func:`planar_rhs`) and evaluates on numpy arrays
(plant) and on CasADi SX/MX symbols (optimiser), so the two cannot drift apart.

Checks of the printed equations (derivation in the module tests):

- eqs. 1-2 and A of eq. 7 agree with the standard CW equations in the Hill frame
  (x radial): xdd = 3n^2 x + 2n yd, ydd = -2n xd. No sign error.
- eq. 3 prints ``eta^2 z``; it should be ``eta^2 dz`` (notation only, unused: planar).
- eq. 4: angular momentum of body plus wheel about z is conserved without external
  torque, ``I_z thetad + D psid = const`` with I_z the whole satellite's MMoI and psi the
  wheel angle relative to the body, so ``I_z thetadd = -D psidd``. The paper writes the
  wheel term as ``psi_dot_z`` but calls it (and Tables 2/3 bound it as) the wheel's angular
  *acceleration*: it is ``psidd``. It also calls eq. 4 "underdamped"; it is undamped.
- eq. 8 divides by ``m_c``; the mass is the deputy's ``m`` of Table 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxops.errors import ProxopsInputError, input_error
from proxops.core.layout import Block, StateLayout, make_control_layout
from proxops.dynamics.plant import PlantBase

STATE_NAMES = ("x", "y", "theta", "vx", "vy", "omega")
STATE_UNITS = ("m", "m", "rad", "m/s", "m/s", "rad/s")
CONTROL_NAMES = ("thrust", "wheel_acc")
CONTROL_UNITS = ("N", "rad/s^2")
N_STATE = 6
N_CONTROL = 2

DEG = math.pi / 180.0
DAMPING_CASE2_NMS = 1.0e-3  # c of eq. 5 used in §5 (N m s)


@dataclass(frozen=True)
class PlanarCubeSatParams:
    """Deputy parameters, Table 1 defaults (SI).

    ``damping_Nms`` is c of eq. 5 (N m s); 0 gives the undamped eq. 4.
    """

    mass_kg: float = 12.0
    wheel_inertia_kgm2: float = 4.1e-5  # D
    body_inertia_kgm2: float = 5.6e-2  # I_z (whole satellite about z)
    mean_motion_rad_s: float = 1.027e-3  # eta
    damping_Nms: float = 0.0  # c

    def __post_init__(self):
        for name in ("mass_kg", "wheel_inertia_kgm2", "body_inertia_kgm2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise input_error(name, value, "must be a finite number > 0")
        for name in ("mean_motion_rad_s", "damping_Nms"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise input_error(name, value, "must be a finite number >= 0")

    def angular_acceleration(self, omega, wheel_acc):
        """thetadd (rad/s^2) of eq. 5 (eq. 4 when c = 0); numpy or CasADi operands."""
        return (-self.wheel_inertia_kgm2 * wheel_acc - self.damping_Nms * omega) / self.body_inertia_kgm2


def _is_casadi(*values) -> bool:
    return any(type(v).__module__.startswith("casadi") for v in values)


def planar_rhs(s, u, p: PlanarCubeSatParams):
    """ds/dt of eqs. 1, 2, 4/5 for state ``s`` (6) and control ``u`` (2).

    Works on numpy arrays (returns a numpy array) and on CasADi symbols (returns a
    CasADi column)."""
    if _is_casadi(s, u):
        import casadi as ca

        cos, sin, stack = ca.cos, ca.sin, lambda items: ca.vertcat(*items)
    else:
        cos, sin, stack = math.cos, math.sin, lambda items: np.array(items, dtype=float)
    x, theta, vx, vy, omega = s[0], s[2], s[3], s[4], s[5]
    thrust, wheel_acc = u[0], u[1]
    n = p.mean_motion_rad_s
    a_thrust = thrust / p.mass_kg
    return stack(
        [
            vx,
            vy,
            omega,
            3.0 * n * n * x + 2.0 * n * vy + cos(theta) * a_thrust,
            -2.0 * n * vx + sin(theta) * a_thrust,
            p.angular_acceleration(omega, wheel_acc),
        ]
    )


def rk4_step(s, u, p: PlanarCubeSatParams, dt: float, substeps: int = 1):
    """Classical RK4 over ``dt`` s in ``substeps`` pieces with ZOH control (numpy or CasADi)."""
    h = dt / substeps
    for _ in range(substeps):
        k1 = planar_rhs(s, u, p)
        k2 = planar_rhs(s + 0.5 * h * k1, u, p)
        k3 = planar_rhs(s + 0.5 * h * k2, u, p)
        k4 = planar_rhs(s + h * k3, u, p)
        s = s + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return s


def casadi_step_function(p: PlanarCubeSatParams, dt: float, substeps: int = 1):
    """CasADi Function ``F(s, u) -> s_next`` (RK4, ZOH) built from :func:`planar_rhs`."""
    import casadi as ca

    s = ca.SX.sym("s", N_STATE)
    u = ca.SX.sym("u", N_CONTROL)
    return ca.Function("planar_step", [s, u], [rk4_step(s, u, p, dt, substeps)], ["s", "u"], ["s_next"])


@dataclass(frozen=True)
class Interval:
    """Closed interval [lo, hi] in SI units (``hi >= lo`` enforced)."""

    lo: float
    hi: float

    def check(self, name: str, unit: str) -> "Interval":
        if not (math.isfinite(self.lo) and math.isfinite(self.hi)):
            raise input_error(name, [self.lo, self.hi], "bounds must be finite numbers", unit)
        if self.lo > self.hi:
            raise input_error(name, [self.lo, self.hi], "min must be <= max", unit)
        return self


@dataclass(frozen=True)
class PlanarLimits:
    """State and input limits (Tables 2 and 3), SI units.

    ``angular_acc`` bounds thetadd (the deputy's angular acceleration) and is enforced as a
    path constraint on (omega, wheel_acc) since with damping it depends on both.
    """

    thrust: Interval  # N
    wheel_acc: Interval  # rad/s^2
    position: Interval  # m, both x and y
    velocity: Interval  # m/s, both vx and vy
    angle: Interval  # rad
    rate: Interval  # rad/s
    angular_acc: Interval  # rad/s^2

    def __post_init__(self):
        for name, unit in (
            ("thrust", "N"),
            ("wheel_acc", "rad/s^2"),
            ("position", "m"),
            ("velocity", "m/s"),
            ("angle", "rad"),
            ("rate", "rad/s"),
            ("angular_acc", "rad/s^2"),
        ):
            getattr(self, name).check(f"limits.{name}", unit)
        if self.angle.lo < -math.pi - 1e-12 or self.angle.hi > math.pi + 1e-12:
            raise input_error("limits.angle", [self.angle.lo, self.angle.hi], "must lie within [-pi, pi]", "rad")

    def state_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) bounds of the state vector."""
        lo = np.array([self.position.lo, self.position.lo, self.angle.lo, self.velocity.lo, self.velocity.lo, self.rate.lo])
        hi = np.array([self.position.hi, self.position.hi, self.angle.hi, self.velocity.hi, self.velocity.hi, self.rate.hi])
        return lo, hi

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([self.thrust.lo, self.wheel_acc.lo]), np.array([self.thrust.hi, self.wheel_acc.hi])

    def check_state(self, s, name: str = "initial_state") -> None:
        """Raise ProxopsInputError if ``s`` lies outside the state limits."""
        s = np.asarray(s, dtype=float)
        if s.shape != (N_STATE,) or not np.all(np.isfinite(s)):
            raise input_error(name, s.tolist(), f"must be {N_STATE} finite numbers [x, y, theta, vx, vy, omega]")
        lo, hi = self.state_bounds()
        for i in range(N_STATE):
            if not lo[i] <= s[i] <= hi[i]:
                raise ProxopsInputError(
                    f"{name}.{STATE_NAMES[i]} = {s[i]!r} {STATE_UNITS[i]}: outside the limits "
                    f"[{lo[i]!r}, {hi[i]!r}] {STATE_UNITS[i]}"
                )


def symmetric(value: float) -> Interval:
    return Interval(-value, value)


# Table 2 (case study 1, limits of [11]) and Table 3 (case study 2, realistic 6U).
TABLE2_LIMITS = PlanarLimits(
    thrust=symmetric(2.0),
    wheel_acc=symmetric(1604.0 * DEG),
    position=symmetric(2000.0),
    velocity=symmetric(10.0),
    angle=symmetric(math.pi),
    rate=symmetric(2.0 * DEG),
    angular_acc=symmetric(1.0 * DEG),
)
TABLE3_LIMITS = PlanarLimits(
    thrust=symmetric(0.1),
    wheel_acc=symmetric(15.0 * DEG),
    position=symmetric(2000.0),
    velocity=symmetric(2.0),
    angle=symmetric(math.pi),
    rate=symmetric(2.0 * DEG),
    angular_acc=symmetric(1.0 * DEG),
)


@dataclass(frozen=True)
class DockingSet:
    """Admissible docking set of Table 1: |x|,|y| <= position_m, |vx|,|vy| <= velocity_mps,
    |theta| <= angle_rad, |omega| <= rate_rad_s."""

    position_m: float = 0.1
    velocity_mps: float = 0.2
    angle_rad: float = 2.0 * DEG
    rate_rad_s: float = 1.0 * DEG

    def __post_init__(self):
        for name in ("position_m", "velocity_mps", "angle_rad", "rate_rad_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise input_error(f"docking.{name}", value, "must be a finite number > 0")

    def contains(self, s) -> bool:
        s = np.asarray(s, dtype=float)
        return bool(
            abs(s[0]) <= self.position_m
            and abs(s[1]) <= self.position_m
            and abs(wrap_angle(s[2])) <= self.angle_rad
            and abs(s[3]) <= self.velocity_mps
            and abs(s[4]) <= self.velocity_mps
            and abs(s[5]) <= self.rate_rad_s
        )


def wrap_angle(a: float) -> float:
    """Angle wrapped to [-pi, pi) (rad)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class PlanarCubeSatPlant(PlantBase):
    """Truth plant (proxops.contracts.Plant) for the planar deputy.

    The full state is the planar state itself: ``n_x = 6`` ``[x, y, theta, vx, vy, omega]``
    (``relative_state`` wraps theta to [-pi, pi)),
    ``n_u = 2`` ``[thrust N, wheel_acc rad/s^2]`` held constant over each step. Positions are
    ``state[0:2]`` and velocities ``state[3:5]`` (``layout`` tells the engine and the result). Integration: RK4 with ``substeps`` pieces per call of the same
    :func:`planar_rhs` the optimiser uses.
    """

    n_x = N_STATE
    n_u = N_CONTROL
    control_layout = make_control_layout(("thrust", "wheel_acc"), ("N", "rad/s^2"))
    layout = StateLayout(N_STATE, (Block("position", "position", 0, 2, ("x", "y"), frame="hill"),
                                   Block("attitude", "angle", 2, 3, ("theta",)),
                                   Block("velocity", "velocity", 3, 5, ("vx", "vy"), frame="hill"),
                                   Block("rate", "rate", 5, 6, ("omega",))))

    def __init__(self, params: PlanarCubeSatParams, s0, substeps_per_s: float = 4.0):
        self.params = params
        self.s0 = np.asarray(s0, dtype=float).copy()
        if self.s0.shape != (N_STATE,) or not np.all(np.isfinite(self.s0)):
            raise input_error("initial_state", list(np.ravel(s0)), "must be 6 finite numbers [x, y, theta, vx, vy, omega]")
        if not substeps_per_s > 0:
            raise input_error("substeps_per_s", substeps_per_s, "must be > 0", "1/s")
        self.substeps_per_s = float(substeps_per_s)

    def initial_state(self) -> np.ndarray:
        return self.s0.copy()

    def relative_state(self, state: np.ndarray) -> np.ndarray:
        """The planar state with theta wrapped to [-pi, pi) (the integrated angle is not)."""
        s = np.array(state, dtype=float)
        s[2] = wrap_angle(s[2])
        return s

    def propagate(self, t: float, state: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        substeps = max(1, int(math.ceil(dt * self.substeps_per_s)))
        return rk4_step(np.asarray(state, dtype=float), np.asarray(u, dtype=float), self.params, dt, substeps)

    def apply_impulse(self, t: float, state: np.ndarray, dv: np.ndarray) -> np.ndarray:
        raise ProxopsInputError("planar CubeSat plant: impulsive commands are not supported (use kind='acceleration')")

    def delta_v(self, u: np.ndarray, kind: str, dt: float) -> float:
        """Delta-v (m/s) of one step: |thrust| / m dt (the wheel command costs no propellant)."""
        return abs(float(u[0])) / self.params.mass_kg * dt
