"""Thruster chain of Wijayatunga et al. §4.1.3-4.1.4: main-engine on-time by the rocket
equation with mass depletion (eq. 32), RCS force/torque-to-PWM allocation (Algorithm 4) and the
PWM on/off law (eq. 33).

Default layout (:func:`six_thruster_layout`, documented choice: the paper names six RCS thrusters
with 1.2 N total minimum thrust but gives no geometry): six thrusters of ``f_max_n`` each, one per
body half-axis, firing along +x, -x, +y, -y, +z, -z, all through the centre of mass (position
``lever_m`` along their own axis). Their unit vectors positively span R^3, so every force with
|F_i| <= f_max per axis is produced exactly; their lines of action pass through the centre of
mass, so they produce no torque (a torque request is met with the least error: none of it).

Algorithm 4 is a linear programme (no integer variable appears in it although the paper calls it
a MILP): ``min sum_j e_j  s.t.  -e <= A diag(F_max) d - c <= e,  0 <= d <= 1`` with A = [t_i;
r_i x t_i] (6 x n). Solved by HiGHS by default (any LP solver of :func:`proxops.solvers.make_solver` by name):
the least-L1-error duty cycles; exact (error 0) whenever c is achievable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxops.core.constants import G0
from proxops.errors import input_error
from proxops.solvers import LinearProgram, make_solver

# HiGHS for Algorithm 4: tight feasibility tolerances (the duty cycles are exact to 1e-10 when c is achievable)
HIGHS_SETTINGS = {"settings": {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}}


@dataclass
class ThrusterLayout:
    """n thrusters: body positions ``positions_m`` (n, 3), unit directions ``directions`` (n, 3) of the
    thrust (force on the spacecraft), maxima ``f_max_n`` (n,)."""

    positions_m: np.ndarray
    directions: np.ndarray
    f_max_n: np.ndarray

    def __post_init__(self):
        p = np.atleast_2d(np.asarray(self.positions_m, float))
        d = np.atleast_2d(np.asarray(self.directions, float))
        n = d.shape[0]
        f = np.broadcast_to(np.asarray(self.f_max_n, float), (n,)).copy()
        if d.shape != (n, 3) or p.shape != (n, 3) or n == 0:
            raise input_error("thruster layout", f"positions {p.shape}, directions {d.shape}",
                              "needs n >= 1 thrusters with 3-vector positions and directions")
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(d)) and np.all(np.isfinite(f))):
            raise input_error("thruster layout", "non-finite value", "positions, directions and thrusts must be finite")
        norms = np.linalg.norm(d, axis=1)
        if np.any(norms < 1e-12):
            raise input_error("thruster direction", int(np.argmin(norms)), "every direction needs a non-zero length")
        if np.any(f <= 0):
            raise input_error("thruster f_max", f.tolist(), "every maximum thrust must be > 0", "N")
        self.positions_m, self.directions, self.f_max_n = p, d / norms[:, None], f
        self._check_force_span()

    @property
    def n(self) -> int:
        return self.directions.shape[0]

    def actuation_matrix(self) -> np.ndarray:
        """A (6, n): columns [t_i; r_i x t_i] (Algorithm 4 lines 3-6)."""
        return np.vstack([self.directions.T, np.cross(self.positions_m, self.directions).T])

    def _check_force_span(self) -> None:
        """Every force direction must be producible: the thrust directions must positively span R^3.
        A convex cone holding +-e_x, +-e_y, +-e_z is all of R^3, so six non-negative least-squares
        tests decide it."""
        from scipy.optimize import nnls

        D = self.directions.T
        for axis, name in enumerate("xyz"):
            for sign in (1.0, -1.0):
                target = np.zeros(3)
                target[axis] = sign
                _, resid = nnls(D, target)
                if resid > 1e-9:
                    raise input_error("thruster layout", f"{self.n} thrusters",
                                      f"cannot produce a force along {'+' if sign > 0 else '-'}{name} (the thrust "
                                      "directions do not positively span 3-D space; add thrusters)")


def six_thruster_layout(f_max_n: float = 0.2, lever_m: float = 0.5) -> ThrusterLayout:
    """The documented six-thruster layout (module docstring): +-x, +-y, +-z through the centre of mass.
    Default 0.2 N each: 1.2 N in total as in §5.1 (the paper's a_max = 1.2 N / 500 kg)."""
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    return ThrusterLayout(positions_m=-lever_m * dirs, directions=dirs, f_max_n=np.full(6, f_max_n))


@dataclass
class Allocation:
    duty: np.ndarray  # (n,) PWM duty cycles in [0, 1]
    error: np.ndarray  # (6,) |A F d - c| per force/torque component (N, N m)
    achieved: np.ndarray  # (6,) A F d
    status: str


class Allocator:
    """Algorithm 4 for one layout, set up once: each :meth:`solve` changes only the row bounds (the
    command c) and re-solves in place (HiGHS hot-starts from the previous basis; measured: a fresh
    set-up per command costs ~30 ms, an update well under 1 ms).

    ``solver``: any LP solver of :func:`proxops.solvers.make_solver` ("highs", default, "piqp",
    "clarabel", "daqp"); ``settings`` go to its adapter (default for HiGHS: feasibility tolerances
    1e-10)."""

    def __init__(self, layout: ThrusterLayout, solver: str = "highs", settings: dict | None = None):
        self.layout = layout
        n = layout.n
        self.M = layout.actuation_matrix() * layout.f_max_n[None, :]  # (6, n)
        # variables [d (n), e (6)]: rows M d - e <= c and M d + e >= c
        self.A = np.block([[self.M, -np.eye(6)], [self.M, np.eye(6)]])
        zero, inf6 = np.zeros(6), np.full(6, np.inf)
        lp = LinearProgram(c=np.concatenate([np.zeros(n), np.ones(6)]), A=self.A,
                           rl=np.concatenate([-inf6, zero]), ru=np.concatenate([zero, inf6]),
                           lb=np.zeros(n + 6), ub=np.concatenate([np.ones(n), inf6]))
        if settings is None:
            settings = HIGHS_SETTINGS if solver == "highs" else {}
        self.lp = make_solver(lp, solver, **settings)
        self._rl, self._ru = lp.rl.copy(), lp.ru.copy()

    def solve(self, command) -> Allocation:
        c = np.asarray(command, float)
        if c.shape != (6,) or not np.all(np.isfinite(c)):
            raise input_error("force/torque command", np.ravel(c).tolist(), "must be 6 finite numbers [F (N), tau (N m)]")
        n = self.layout.n
        self._rl[6:] = c
        self._ru[:6] = c
        self.lp.update(rl=self._rl, ru=self._ru)
        res = self.lp.solve()
        if res.x is None:
            return Allocation(np.zeros(n), np.abs(c), np.zeros(6), res.status.value)
        d = np.clip(res.x[:n], 0.0, 1.0)
        achieved = self.M @ d
        return Allocation(d, np.abs(achieved - c), achieved, res.status.value)


def allocate(layout: ThrusterLayout, command, solver: str = "highs", settings: dict | None = None) -> Allocation:
    """Algorithm 4: duty cycles d in [0, 1] minimising sum_j |(A F d - c)_j| for the body
    force/torque command c = [F (N); tau (N m)] (6,). Infeasibility cannot occur (d = 0 is
    feasible with e = |c|); a solver failure is a status. One-off form of :class:`Allocator`."""
    return Allocator(layout, solver, settings).solve(command)


def pwm_on(t_s: float, duty: np.ndarray, t_control_s: float) -> np.ndarray:
    """Eq. (33): thruster i is on (1.0) when (t mod t_control) < d_i t_control, else 0.0."""
    if not (math.isfinite(t_control_s) and t_control_s > 0):
        raise input_error("t_control", t_control_s, "must be a finite number > 0", "s")
    phase = math.fmod(float(t_s), t_control_s)
    if phase < 0:
        phase += t_control_s
    return (phase < np.asarray(duty, float) * t_control_s).astype(float)


def main_engine_on_time(dv_mps: float, mass_kg: float, thrust_n: float, isp_s: float) -> tuple[float, float]:
    """Eq. (32): on-time t_on = (m0 - m_f) / mdot with m_f = m0 exp(-|dv| / (Isp g0)) and
    mdot = F / (Isp g0). Returns (t_on s, m_f kg) -- the mass after the burn (depletion)."""
    for name, v, unit in (("mass", mass_kg, "kg"), ("thrust", thrust_n, "N"), ("isp", isp_s, "s")):
        if not (math.isfinite(v) and v > 0):
            raise input_error(name, v, "must be a finite number > 0", unit)
    if not (math.isfinite(dv_mps) and dv_mps >= 0):
        raise input_error("dv", dv_mps, "must be a finite number >= 0", "m/s")
    ve = isp_s * G0
    m_f = mass_kg * math.exp(-dv_mps / ve)
    return (mass_kg - m_f) / (thrust_n / ve), m_f


def burn_sequence(dvs_mps, mass_kg: float, thrust_n: float, isp_s: float) -> tuple[np.ndarray, np.ndarray]:
    """On-times of consecutive impulses with the mass depleted by each (eq. 32 applied in turn).
    Returns (t_on (k,), mass before each burn (k+1,), the last entry the final mass)."""
    dvs = np.atleast_1d(np.asarray(dvs_mps, float))
    t_on = np.empty(dvs.size)
    masses = np.empty(dvs.size + 1)
    masses[0] = mass_kg
    for i, dv in enumerate(dvs):
        t_on[i], masses[i + 1] = main_engine_on_time(float(dv), float(masses[i]), thrust_n, isp_s)
    return t_on, masses


def pwm_impulse(layout: ThrusterLayout, duty, t_control_s: float, mass_kg: float, isp_s: float,
                attitude=None) -> tuple[np.ndarray, float, float]:
    """Velocity change (m/s, frame of ``attitude`` @ body; body frame without it) of one PWM window
    of eq. (33) -- thruster i on for (t mod t_control) < d_i t_control -- with the mass depleted
    while the thrusters fire (rocket equation piece by piece: between on/off switches the force F
    and the mass flow mdot = sum F_i / (Isp g0) are constant, dv = F / mdot ln(m / (m - mdot dt))).
    Returns (dv (3,), propellant kg, summed thruster on-time s)."""
    d = np.clip(np.asarray(duty, float), 0.0, 1.0)
    ve = isp_s * G0
    edges = np.unique(np.concatenate([[0.0, t_control_s], d * t_control_s]))
    m = float(mass_kg)
    dv = np.zeros(3)
    on_time = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a <= 0.0:
            continue
        on = pwm_on(0.5 * (a + b), d, t_control_s)  # eq. (33) on this piece of the window
        if not on.any():
            continue
        force = (layout.directions * (layout.f_max_n * on)[:, None]).sum(axis=0)  # N, body
        mdot = float((layout.f_max_n * on).sum()) / ve
        dm = mdot * (b - a)
        dv += force / mdot * math.log(m / (m - dm))
        m -= dm
        on_time += float(on.sum()) * (b - a)
    if attitude is not None:
        dv = np.asarray(attitude, float) @ dv
    return dv, float(mass_kg) - m, on_time


class ThrusterChainActuator:
    """The engine's actuator slot through the thruster chain of §4.1.3-4.1.4 (scenario key
    ``[actuator] model = "thrusters"`` of the cortex system).

    Each commanded impulse dv (m/s, Hill) of a window of ``t_control_s`` (the impulse spacing
    delta t_g) goes, in order, through: ``errors`` (the Algorithm 3 execution errors of
    :class:`proxops.actuators.ThrusterModel`, on the command, if given); eq. (32) -- the force that
    delivers |dv| over the window by the rocket equation at the current mass,
    F = (m0 - m_f) Isp g0 / t_control with m_f = m0 exp(-|dv| / (Isp g0)) (eq. 32 solved for F at
    t_on = t_control); Algorithm 4 -- duty cycles of the ``layout`` thrusters for the body
    force/torque [F; 0] (HiGHS LP); eq. (33) -- the PWM on/off law; and :func:`pwm_impulse`, the
    velocity change those on-times deliver with the mass depleted during the burn. The body axes
    are held on the Hill axes (fixed attitude, as the paper's plume simplification; attitude
    control is not modelled). Duty cycles below ``min_on_time_s / t_control`` fire nothing (minimum
    on-time). The delivered velocity change is applied as one impulse at the window start (the
    engine's impulse model, the same discretisation as CP_g). Bookkeeping: ``mass_kg``,
    ``propellant_kg``, ``on_time_s``, ``max_allocation_error_n`` (largest force the LP could not
    produce: saturation)."""

    def __init__(self, layout: ThrusterLayout, mass_kg: float, isp_s: float, t_control_s: float, errors=None,
                 min_on_time_s: float = 0.0, period_s: float | None = None):
        for name, v, unit in (("servicer.mass_kg", mass_kg, "kg"), ("actuator.isp_s", isp_s, "s"),
                              ("guidance.substep_s", t_control_s, "s")):
            if not (math.isfinite(v) and v > 0):
                raise input_error(name, v, "must be a finite number > 0", unit)
        if not (math.isfinite(min_on_time_s) and 0.0 <= min_on_time_s <= t_control_s):
            raise input_error("actuator.min_on_time_s", min_on_time_s, f"must be in [0, {t_control_s:g}] (the PWM period)", "s")
        self.layout, self.isp_s, self.t_control_s = layout, float(isp_s), float(t_control_s)
        self.errors, self.min_on_time_s, self.period_s = errors, float(min_on_time_s), period_s
        self.mass0_kg = self.mass_kg = float(mass_kg)
        self.propellant_kg = 0.0
        self.on_time_s = 0.0
        self.max_allocation_error_n = 0.0
        self.allocations = 0
        self.lp_time_s = 0.0
        self._allocator = None

    def command_force(self, dv) -> np.ndarray:
        """Eq. (32) solved for the force that delivers ``dv`` over one window at the current mass (N, Hill = body)."""
        dv = np.asarray(dv, float)
        mag = float(np.linalg.norm(dv))
        if mag == 0.0:
            return np.zeros(3)
        ve = self.isp_s * G0
        m_f = self.mass_kg * math.exp(-mag / ve)
        return dv / mag * (self.mass_kg - m_f) * ve / self.t_control_s

    def apply(self, t: float, u, kind: str, rng) -> np.ndarray:
        import time

        if kind != "impulse":
            raise input_error("actuator.model", "thrusters", "takes impulse commands (the cortex loop); "
                              f"got a command of kind {kind!r}")
        u = np.asarray(u, float)
        if self.errors is not None:
            u = np.asarray(self.errors.apply(t, u, kind, rng), float)
        if not u.any():
            return np.zeros(3)
        force = self.command_force(u)
        t0 = time.perf_counter()
        if self._allocator is None:
            self._allocator = Allocator(self.layout)
        alloc = self._allocator.solve(np.concatenate([force, np.zeros(3)]))
        self.lp_time_s += time.perf_counter() - t0
        self.allocations += 1
        self.max_allocation_error_n = max(self.max_allocation_error_n, float(alloc.error[:3].max()))
        duty = alloc.duty.copy()
        duty[duty * self.t_control_s < self.min_on_time_s] = 0.0
        dv, dm, on = pwm_impulse(self.layout, duty, self.t_control_s, self.mass_kg, self.isp_s)
        self.mass_kg -= dm
        self.propellant_kg += dm
        self.on_time_s += on
        return dv
