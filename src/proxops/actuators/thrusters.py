"""Thruster chain of cortex-convex-guidance.md §4.1.3-4.1.4: main-engine on-time by the rocket
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
r_i x t_i] (6 x n). Solved by HiGHS (:class:`proxops.solvers.HighsLP`): the least-L1-error duty
cycles; exact (error 0) whenever c is achievable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxops.core.constants import G0
from proxops.errors import input_error
from proxops.solvers import HighsLP


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


def allocate(layout: ThrusterLayout, command, solver=None) -> Allocation:
    """Algorithm 4: duty cycles d in [0, 1] minimising sum_j |(A F d - c)_j| for the body
    force/torque command c = [F (N); tau (N m)] (6,). Infeasibility cannot occur (d = 0 is
    feasible with e = |c|); a solver failure is a status."""
    c = np.asarray(command, float)
    if c.shape != (6,) or not np.all(np.isfinite(c)):
        raise input_error("force/torque command", np.ravel(c).tolist(), "must be 6 finite numbers [F (N), tau (N m)]")
    n = layout.n
    M = layout.actuation_matrix() * layout.f_max_n[None, :]  # (6, n)
    # variables [d (n), e (6)]: rows M d - e <= c and M d + e >= c
    A = np.block([[M, -np.eye(6)], [M, np.eye(6)]])
    rl = np.concatenate([np.full(6, -np.inf), c])
    ru = np.concatenate([c, np.full(6, np.inf)])
    cost = np.concatenate([np.zeros(n), np.ones(6)])
    lb = np.zeros(n + 6)
    ub = np.concatenate([np.ones(n), np.full(6, np.inf)])
    lp = solver or HighsLP(settings={"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10})
    lp.setup(cost, A, rl, ru, lb, ub)
    res = lp.solve()
    if res.x is None:
        return Allocation(np.zeros(n), np.abs(c), np.zeros(6), res.status.value)
    d = np.clip(res.x[:n], 0.0, 1.0)
    achieved = M @ d
    return Allocation(d, np.abs(achieved - c), achieved, res.status.value)


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
