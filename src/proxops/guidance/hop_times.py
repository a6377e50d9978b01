"""Guidance expert of the Short Range Framework: hop times (Silva et al. 2026 §4.1-4.3).

Everything here is the paper's in-plane problem in its own LVLH convention (2-D
``[p_x, p_z]`` = [V-bar, R-bar], z towards the Earth), written without units: positions
in units of the hop start distance ``d0``, velocities in units of ``w d0``, time as the
orbit angle ``phi = w t`` (rad). ``theta`` is the approach angle from the V-bar towards the
R-bar (0 = V-bar in front of the target, 90 deg = R-bar below it). Conversion to the
Hill frame happens in the MPC (:mod:`proxops.control.srf_mpc`) via :mod:`proxops.frames.lvlh`.

* V-bar (theta = 0 or pi): a radial hop returns to the axis after half an orbit for any
  hop length (eq. 8: dp_x = 4 v_z0 / w); duration 0.5 t_orb.
* R-bar (theta = pi/2 or 3 pi/2): eq. (14) rho = (3 phi - 4 sin phi) / (3 phi cos phi - 4 sin phi);
  phi(rho = 0) = 1.2757 rad (3 phi = 4 sin phi), i.e. 0.2030 t_orb.
* Any angle: eqs. (17)-(25), solved for phi with a bracketed root finder (scipy brentq)
  on the branch that starts at rho = 1 for phi -> 0+, before the first singularity of the
  2x2 matrix of eq. (24).

Feasibility (the "infeasible band" of §5.3 / Fig. 8a): a hop is accepted only when the
solution exists on that branch AND the hop stays on one side of the approach axis -- the
side of the classical V-bar / R-bar hops, i.e. the perpendicular rotated coordinate
``r_z = -sin(theta) p_x + cos(theta) p_z <= 0`` for the whole hop. For rho = 0.7 this
holds for theta in [0, 110.1] deg (and [180, 290.1] deg); at the edge the arrival
velocity is tangent to the axis ("the chaser nearly grazes the crossing point ... a near
straight line", §5.3), beyond it the hop crosses the axis before its end, then the
branch hits the singularity (no solution) before 180 deg. The edge depends on rho
(about 94 deg for rho -> 1, 146 deg for rho -> 0); :func:`feasible_angle_limit` computes it.

Paper corrections (verified by derivation, see tests/test_hop_times.py):
* eqs. (10)-(11): the v_x0 term of p_z has the wrong sign; from eq. (3) it is
  ``rho_z = 4 - 3 cos phi + 2 (cos phi - 1) alpha_z + sin phi beta_z``. Eq. (14) follows
  from the corrected form (the printed form gives a different, wrong rho_z).
* eq. (16) rounds phi = 1.2757 rad to "0.21 t_orb"; phi / (2 pi) = 0.2030.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from proxops.core.constants import MU_EARTH
from proxops.errors import ProxopsInputError, input_error

RBAR_PHI_MAX = 1.2756981092811261
"""phi (rad) of the largest R-bar hop, rho = 0 in eq. (14): root of 3 phi = 4 sin phi."""

_AXIS_TOL_RAD = 1e-9  # |sin(theta)| or |cos(theta)| below this is exactly V-bar / R-bar
_SIDE_TOL = 1e-9  # r_z (units of d0) allowed on the wrong side of the axis (round-off)


# --------------------------------------------------------------------------- dynamics
def cw_blocks(phi):
    """Blocks (pp, pv, vp, vv) of the nondimensional in-plane CW STM of eq. (19), shape (..., 2, 2).

    Order ``[p_x, p_z]``, ``[v_x, v_z]`` (paper LVLH); velocity in units of w d0."""
    phi = np.asarray(phi, dtype=float)
    s, c = np.sin(phi), np.cos(phi)
    one, zero = np.ones_like(phi), np.zeros_like(phi)
    pp = np.stack([np.stack([one, 6 * (phi - s)], -1), np.stack([zero, 4 - 3 * c], -1)], -2)
    pv = np.stack([np.stack([4 * s - 3 * phi, 2 * (1 - c)], -1), np.stack([2 * (c - 1), s], -1)], -2)
    vp = np.stack([np.stack([zero, 6 * (1 - c)], -1), np.stack([zero, 3 * s], -1)], -2)
    vv = np.stack([np.stack([4 * c - 3, 2 * s], -1), np.stack([-2 * s, c], -1)], -2)
    return pp, pv, vp, vv


def rotation(theta: float) -> np.ndarray:
    """Eq. (20): r = R p maps paper-LVLH [p_x, p_z] to the approach frame [along axis, perpendicular]."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, s], [-s, c]])


def _rotated_blocks(phi, theta: float):
    """Eq. (21): R Phi_ab R^-1 for each block."""
    R = rotation(theta)
    return tuple(R @ blk @ R.T for blk in cw_blocks(phi))


def _solve_eq24(phi, theta: float):
    """Eq. (24) for r0 = [1, 0]: rotated initial velocity (w_x0, w_z0), determinant, eq. (25) rho."""
    pp, pv, vp, vv = _rotated_blocks(phi, theta)
    a, b = pv[..., 1, 0], pv[..., 1, 1]
    c, d = vv[..., 0, 0], vv[..., 0, 1]
    rhs1, rhs2 = -pp[..., 1, 0], -vp[..., 0, 0]
    det = a * d - b * c
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        wx0 = (d * rhs1 - b * rhs2) / det
        wz0 = (a * rhs2 - c * rhs1) / det
        rho = pp[..., 0, 0] + pv[..., 0, 0] * wx0 + pv[..., 0, 1] * wz0
    return wx0, wz0, det, rho


def hop_rho(phi, theta: float):
    """Eq. (25): displacement fraction rho reached at orbit angle ``phi`` (rad) for approach ``theta`` (rad)."""
    return _solve_eq24(phi, theta)[3]


def hop_velocity(phi: float, theta: float) -> np.ndarray:
    """Eq. (24): initial velocity [v_x, v_z] (paper LVLH, units of w d0) of a hop of angle ``phi``
    starting at d0 on the approach axis ``theta``."""
    if _is_vbar(theta):
        raise input_error("theta", theta, "V-bar hops are not defined by eq. (24); use vbar_hop_velocity", "rad")
    wx0, wz0, _, _ = _solve_eq24(float(phi), theta)
    return rotation(theta).T @ np.array([float(wx0), float(wz0)])


def vbar_hop_velocity(rho: float, theta: float = 0.0) -> np.ndarray:
    """Eq. (8): radial initial velocity [v_x, v_z] (units of w d0) of a V-bar hop d0 -> rho d0.

    Along the axis the hop covers (1 - rho) d0 = 4 |v_z0| / w towards the target."""
    w_rot = np.array([0.0, -(1.0 - rho) / 4.0])  # rotated frame: perpendicular component only
    return rotation(theta).T @ w_rot


def rbar_rho(phi):
    """Eq. (14) closed form of the R-bar hop."""
    phi = np.asarray(phi, dtype=float)
    return (3 * phi - 4 * np.sin(phi)) / (3 * phi * np.cos(phi) - 4 * np.sin(phi))


def _brentq():
    """scipy's brentq, imported where a root is needed: V-bar plans need none, and importing
    scipy.optimize costs a campaign worker 0.3 s (measured)."""
    from scipy.optimize import brentq

    return brentq


def rbar_phi(rho: float) -> float:
    """Eq. (14) solved for phi (rad) with brentq on (0, 1.2757]; ``rho`` in [0, 1)."""
    rho = _check_rho(rho)
    if rho == 0.0:
        return RBAR_PHI_MAX
    brentq = _brentq()
    return float(brentq(lambda p: rbar_rho(p) - rho, 1e-6, RBAR_PHI_MAX, xtol=1e-14, rtol=1e-14))


# --------------------------------------------------------------------------- any angle
@dataclass
class HopSolution:
    """One hop d0 -> rho d0 along approach ``theta``: orbit angle, period fraction, initial velocity."""

    theta_rad: float
    rho: float
    phi_rad: float
    velocity_lvlh: np.ndarray  # [v_x, v_z] at the start (paper LVLH, units of w d0)

    @property
    def period_fraction(self) -> float:
        return self.phi_rad / (2.0 * math.pi)


def _is_vbar(theta: float) -> bool:
    return abs(math.sin(theta)) < _AXIS_TOL_RAD


def _check_rho(rho: float) -> float:
    rho = float(rho)
    if not (0.0 <= rho < 1.0) or not math.isfinite(rho):
        raise input_error("rho", rho, "hop displacement fraction must satisfy 0 <= rho < 1 (end / start distance)")
    return rho


def _first_pole(theta: float, n_grid: int = 2048) -> float:
    """First phi in (0, 2 pi] where the 2x2 matrix of eq. (24) is singular."""
    grid = np.linspace(1e-4, 2 * math.pi, n_grid)
    det = _solve_eq24(grid, theta)[2]
    idx = np.nonzero(np.sign(det[1:]) != np.sign(det[:-1]))[0]
    if idx.size == 0:
        return 2 * math.pi
    i = int(idx[0])
    brentq = _brentq()
    return float(brentq(lambda p: float(_solve_eq24(p, theta)[2]), grid[i], grid[i + 1], xtol=1e-15))


def _branch_root(theta: float, rho: float) -> float | None:
    """First phi on the branch rho(0+) = 1 with rho(phi) = ``rho``, or None when the branch
    reaches the eq.-(24) singularity first."""
    pole = _first_pole(theta)
    # Grid dense near the pole (the root approaches it as theta -> V-bar).
    gap = np.geomspace(pole * 1e-10, pole * (1 - 1e-6), 1500)[::-1]
    grid = np.unique(np.concatenate([np.linspace(1e-6, pole * (1 - 1e-3), 1500), pole - gap]))
    f = _solve_eq24(grid, theta)[3] - rho
    idx = np.nonzero(np.sign(f[1:]) != np.sign(f[:-1]))[0]
    if idx.size == 0:
        return None
    i = int(idx[0])
    brentq = _brentq()
    return float(brentq(lambda p: float(_solve_eq24(p, theta)[3]) - rho, grid[i], grid[i + 1], xtol=1e-14, rtol=1e-14))


def _hop_side_ok(theta: float, phi: float, velocity_lvlh: np.ndarray, n: int = 400) -> bool:
    """True when the hop stays on the V-bar/R-bar side of the axis: r_z(tau) <= 0 on (0, phi)."""
    tau = np.linspace(0.0, phi, n)[1:-1]
    pp, pv, _, _ = cw_blocks(tau)
    p0 = np.array([math.cos(theta), math.sin(theta)])
    pos = pp @ p0 + pv @ velocity_lvlh
    r_perp = -math.sin(theta) * pos[:, 0] + math.cos(theta) * pos[:, 1]
    return bool(np.all(r_perp <= _SIDE_TOL))


def try_solve_hop(theta: float, rho: float) -> HopSolution | None:
    """Hop solution for approach ``theta`` (rad) and fraction ``rho``, or None in the infeasible band."""
    rho = _check_rho(rho)
    theta = float(theta) % (2 * math.pi)
    if _is_vbar(theta):
        return HopSolution(theta, rho, math.pi, vbar_hop_velocity(rho, theta))
    phi = _branch_root(theta, rho)
    if phi is None:
        return None
    vel = hop_velocity(phi, theta)
    if not _hop_side_ok(theta, phi, vel):
        return None
    return HopSolution(theta, rho, phi, vel)


def feasible_angle_limit(rho: float) -> float:
    """Upper edge (rad, in (pi/2, pi)) of the feasible approach angles [0, edge] for ``rho``;
    by the pi-periodicity of CW the third-quadrant band is [pi, pi + edge]."""
    lo, hi = math.pi / 2, math.pi - 1e-6
    if try_solve_hop(hi, rho) is not None:
        return hi
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if try_solve_hop(mid, rho) is not None:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-7:
            break
    return lo


def solve_hop(theta: float, rho: float) -> HopSolution:
    """Like :func:`try_solve_hop` but raises ProxopsInputError in the infeasible band."""
    sol = try_solve_hop(theta, rho)
    if sol is None:
        edge = math.degrees(feasible_angle_limit(rho))
        raise ProxopsInputError(
            f"approach angle = {math.degrees(theta) % 360:.3f} deg with hop fraction rho = {rho:.4g}: no passively "
            f"safe hop exists (eqs. 17-25 have no solution that stays on one side of the approach axis); "
            f"allowed for this rho: 0 <= angle <= {edge:.1f} deg or 180 <= angle <= {180 + edge:.1f} deg "
            "(Silva et al. 2026 §5.3, Fig. 8a)"
        )
    return sol


# --------------------------------------------------------------------------- Algorithm 1
def orbital_period_s(sma_m: float, mu: float = MU_EARTH) -> float:
    """t_orb = 2 pi sqrt(a^3 / mu) (s)."""
    if not (sma_m > 0 and math.isfinite(sma_m)):
        raise input_error("sma", sma_m, "must be finite and > 0", "m")
    return 2 * math.pi * math.sqrt(sma_m**3 / mu)


def hop_distances(start_m: float, end_m: float, n_hops: int, gamma: float) -> np.ndarray:
    """Algorithm 1 step 1: distances d_0 = start > d_1 > ... > d_n = end (m) from the target.

    Hop lengths decay geometrically, L_{k+1} = gamma L_k, and add up to start - end
    (gamma = 1 would be equal hops; the paper requires decreasing hops, so 0 < gamma < 1)."""
    if not (isinstance(n_hops, (int, np.integer)) and n_hops >= 1):
        raise input_error("hops", n_hops, "must be a whole number >= 1")
    gamma = float(gamma)
    if not (0.0 < gamma < 1.0):
        raise input_error("gamma", gamma, "hop aggressiveness must satisfy 0 < gamma < 1 (ratio of successive hop lengths)")
    start_m, end_m = float(start_m), float(end_m)
    if not (math.isfinite(start_m) and start_m > 0):
        raise input_error("start_m", start_m, "must be finite and > 0", "m")
    if not (math.isfinite(end_m) and 0 < end_m < start_m):
        raise input_error("end_m", end_m, f"must satisfy 0 < end_m < start_m = {start_m:g}", "m")
    first = (start_m - end_m) * (1 - gamma) / (1 - gamma**n_hops)
    lengths = first * gamma ** np.arange(n_hops)
    d = start_m - np.concatenate([[0.0], np.cumsum(lengths)])
    d[-1] = end_m
    return d


@dataclass
class Hop:
    start_m: float
    end_m: float
    rho: float
    phi_rad: float
    duration_s: float
    period_fraction: float
    velocity_lvlh_mps: np.ndarray  # [v_x, v_z] right after the first impulse (m/s, paper LVLH, from rest)

    def as_dict(self) -> dict:
        return {"start_m": self.start_m, "end_m": self.end_m, "rho": self.rho, "phi_rad": self.phi_rad,
                "duration_s": self.duration_s, "period_fraction": self.period_fraction}


@dataclass
class HopPlan:
    """Output of Algorithm 1: hops and their instants (s from the first impulse)."""

    theta_rad: float
    period_s: float
    hops: list[Hop] = field(default_factory=list)

    @property
    def durations_s(self) -> np.ndarray:
        return np.array([h.duration_s for h in self.hops])

    @property
    def hop_times_s(self) -> np.ndarray:
        """t_hop^k: end of hop k, cumulative (s)."""
        return np.cumsum(self.durations_s)

    def as_dict(self) -> dict:
        return {"approach_deg": math.degrees(self.theta_rad), "period_s": self.period_s,
                "total_s": float(self.durations_s.sum()), "hops": [h.as_dict() for h in self.hops]}


def plan_hops(theta: float, n_hops: int, gamma: float, start_m: float, end_m: float, mean_motion: float,
              vbar_period_fraction: float = 0.5) -> HopPlan:
    """Algorithm 1: hop distances from (gamma, n_hops), then each hop's time from its rho.

    ``theta`` (rad) approach angle; ``mean_motion`` w (rad/s). V-bar hops last
    ``vbar_period_fraction`` t_orb (0.5 = eq. 8; the CBF demo of §5.4 uses 0.6).
    Raises ProxopsInputError for bad input or an angle in the infeasible band."""
    if not (mean_motion > 0 and math.isfinite(mean_motion)):
        raise input_error("mean_motion", mean_motion, "must be finite and > 0", "rad/s")
    theta = float(theta)
    if not math.isfinite(theta):
        raise input_error("approach angle", theta, "must be finite", "rad")
    d = hop_distances(start_m, end_m, n_hops, gamma)
    period = 2 * math.pi / mean_motion
    plan = HopPlan(theta % (2 * math.pi), period)
    for k in range(n_hops):
        rho = d[k + 1] / d[k]
        sol = solve_hop(theta, rho)
        phi = 2 * math.pi * vbar_period_fraction if _is_vbar(theta) else sol.phi_rad
        plan.hops.append(Hop(float(d[k]), float(d[k + 1]), float(rho), float(phi), float(phi / mean_motion),
                             float(phi / (2 * math.pi)), sol.velocity_lvlh * mean_motion * d[k]))
    return plan


def fig8a_curve(rho: float = 0.7, step_deg: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Fig. 8a data: approach angles (deg, 0..360 every ``step_deg``) and the hop's orbital-period
    fraction from eq. (25) (NaN where no passively safe hop exists)."""
    angles = np.arange(0.0, 360.0 + 1e-9, step_deg)
    frac = np.array([np.nan if (s := try_solve_hop(math.radians(a), rho)) is None else s.period_fraction
                     for a in angles])
    return angles, frac


def fig8b_hops(rho: float = 0.7, angles_deg=(0, 20, 40, 60, 90, 100, 110, 200, 250), d0: float = 1.0) -> list:
    """Fig. 8b data: per angle with a solution, ``(angle deg, CW trajectory over one orbit (400, 2),
    point where it crosses the axis (2,))`` in units of ``d0`` (LVLH x V-bar, z R-bar; eq. 24 velocity)."""
    out = []
    for a in angles_deg:
        th = math.radians(a)
        sol = try_solve_hop(th, rho)
        if sol is None:
            continue
        pp, pv, _, _ = cw_blocks(np.linspace(0.0, 2 * math.pi, 400))
        p0 = d0 * np.array([math.cos(th), math.sin(th)])
        ppx, pvx, _, _ = cw_blocks(sol.phi_rad)
        out.append((a, pp @ p0 + pv @ (sol.velocity_lvlh * d0), ppx @ p0 + pvx @ (sol.velocity_lvlh * d0)))
    return out


def hop_engine_steps(durations_s, steps_per_hop: int, dt: float) -> list[int]:
    """Each hop's duration (s) rounded to whole engine steps of ``dt`` (s), as the MPC's node schedule
    (:func:`proxops.control.srf_mpc.build_schedule`) and the build-free check of ``proxops validate`` use it;
    one input error when a hop has fewer engine steps than its ``steps_per_hop`` MPC intervals."""
    counts = []
    for j, dur in enumerate(durations_s):
        n_eng = int(round(float(dur) / dt))
        if n_eng < steps_per_hop:
            raise input_error(
                "sim.dt_s", dt,
                f"hop {j + 1} lasts {dur:.1f} s, too short for {steps_per_hop} MPC steps of at least one engine "
                f"step each: use dt_s <= {dur / steps_per_hop:.3g} or fewer mpc.steps_per_hop", "s")
        counts.append(n_eng)
    return counts


def check_trim_delay(delay_nodes: int, hop_start_node: int, hop_end_node: int) -> None:
    """The V-bar drift trim comes 1 to (hop's nodes - 1) MPC nodes after its hop start (``mpc.drift_trim_delay_nodes``):
    one input error otherwise. Used by :class:`proxops.control.srf_mpc.SrfMpc` and validate's build-free check."""
    if not 1 <= delay_nodes < hop_end_node - hop_start_node:
        raise input_error("mpc.drift_trim_delay_nodes", delay_nodes,
                          f"the trim must come 1 to {hop_end_node - hop_start_node - 1} MPC nodes after its hop start "
                          f"(the hop from node {hop_start_node} ends at node {hop_end_node}): lower it or raise "
                          f"mpc.steps_per_hop")
