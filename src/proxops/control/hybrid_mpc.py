"""Capture and post-capture MPCs of Basu et al. (Problems 2 and 3, eqs. 62-82).

Both controllers take the paper's 32-entry relative state ``x_rel``
(:mod:`proxops.dynamics.hybrid_relative`, as :func:`relative_from_truth` returns it) and
return ``Command.u = (F_d|_D [N], M_d|_D [N m])``, the input of ``truth_rhs`` and
``relative_rhs``, held over one control period (zero-order hold).

Capture MPC (Problem 2, eqs. 62-72)
-----------------------------------
Decision state ``dx0 = (rho, rho_dot, omega, q_eta)`` (12; eq. 62 with the unit quaternion
reduced to its vector part, q_mu = +sqrt(1 - |q_eta|^2), and the scalar-positive branch of
q), input ``du0 = u - kappa^0(p, omega_c)`` (eqs. 41, 43, 63).

* Model (69): ``dx0' = A(p, omega_c) dx0 + B du0``, the Jacobian of the paper's f_0
  (:func:`relative_rhs`, one CasADi definition, differentiated symbolically) at the docking
  configuration (rho = 0, rho' = 0, omega = 0, q = q_I) with u = kappa^0(p, omega_c). At that
  point f_0 vanishes (kappa^0 holds the docking configuration in equilibrium), so the model
  has no affine term. (p, omega_c) is the current chief state, refreshed every step and
  *frozen over the horizon* (the chief turns by |omega_c| T^0 = 0.04 rad over 10 s in §VII).
* Exact discretisation: ``[Ad Bd; 0 I] = expm([A B; 0 0] dt)`` (zero-order hold).
* Cost (71, 72) with L_D^0 = 0, J^0 = 0 as the paper sets them: the flow integral is the
  Riemann sum ``dt sum_{k=0}^{N-1} (dx_k' Q dx_k + du_k' R du_k + V_k)`` (the k = 0 state
  term is a constant and dropped) plus ``dx_N' Q_f dx_N``. Weights (79) while the collision
  count c = 0, (80) for c >= 1 (:meth:`CaptureMPC.set_collision_count`).
* Input box (63): ``-u_max - kappa^0 <= du0 <= u_max - kappa^0`` on every stage; the
  applied ``u = kappa^0 + du0_0`` lies in the +-1 N / +-1 N m box (§VII) to round-off.
* Face pointing (66): ``V = lambda_f (|rho| - v' rho)^2`` with v = P_c/|P_c| in C (see the
  corrections). Two forms (``face_form``):
  - ``"qp"`` (default): |rho| is linearised at the previous plan's predicted rho_k (shifted
    one step; the measured rho on the first step). |rho| is positively homogeneous, so its
    tangent is ``e_k' rho`` (e_k = rho_bar_k/|rho_bar_k|) and the penalty becomes the
    rank-one quadratic ``lambda_f ((e_k - v)' rho_k)^2``: exact on the ray of rho_bar_k, zero
    when aligned with v. The QP is condensed (inputs only, box bounds only) and solved by
    DAQP (:class:`proxops.solvers.DaqpQP`).
  - ``"socp"``: the exact convex penalty through a slack, ``||rho_k|| <= s_k + v' rho_k``,
    cost lambda_f s_k^2, solved by Clarabel (:class:`proxops.solvers.ClarabelSOCP`).
  benchmarks/bench_hybrid_mpc.py measures both; the QP is the default because it is faster
  and its first input agrees with the SOCP's (tests/test_hybrid_mpc.py bounds the exact-cost
  excess of the QP plan).
* Thrust map (our choice, ``thrust_at_current_attitude``): the force block of B is eq. 22's
  ``Q^T F_d / m_d`` at the measured q instead of at q = q_I (and kappa_1^0, a force in C, is
  applied in D as ``Q kappa_1^0``). The deputy of eq. 78 starts 180 deg from q_I; the docked
  identity would aim every thrust along the wrong axes until the attitude has converged.
* Attitude kinematics (our choice, ``kinematics_at_current_attitude``): the q_eta rows of A are
  eq. 27's ``(q_eta^x + q_mu I) / 2`` at the measured q instead of the docked ``I / 2``; the
  latter overstates the attitude rate by 1/q_mu (contacts flip the deputy far from q_I, and
  with the (80) weights the mismatch drove the deputy's relative rate up to 4 rad/s in a
  dispersed §VII run). At q_mu = 0 exactly (eq. 78) |q_eta| has no first-order change
  under any rate: the plan rotates the deputy only through the omega cost for the first step.
* Approach guidance (not in the paper, ``approach_guidance``): the position target is rho = 0
  only once the deputy port is inside a cone of half-angle 20 deg about the port axis v
  (seen from the chief CoM); before that, it is a waypoint 30 deg further round on a sphere
  about the chief CoM whose radius keeps the deputy clear of the chief in any attitude (from
  inside 0.9 of that radius, first straight out to the sphere: going round from close in
  scrapes the chief, and every contact spins it up, see the report). The
  eq. 78 deputy starts 1.9 m *behind* the docking face (rho = (-0.23, -2.46, -0.23) m in C):
  the printed problem (a quadratic pull to rho = 0 plus eq. 66, whose descent direction from
  behind the face is also straight at the chief) pushes it into the chief's back face and
  grinds there. Only the target of the rho cost changes; the model and constraints are
  Problem 2's. ``approach_guidance=False`` is Problem 2 as printed.
* Jumps: contacts (eqs. 33-39) happen at instants no QP can predict (the paper sets J^0 = 0
  for that reason); the prediction is flow-only and the MPC re-solves from the post-jump
  state at its next sample; the supervisor raises the collision count, which switches the
  weights to (80).

Control period: 1 s (``CaptureMPCConfig.period_s``). The paper gives no sampling; with the
±1 N bound on 120 kg one period changes the relative velocity by at most 8 mm/s, below the
~cm/s contact speeds of §VII, the prediction is exact (ZOH) whatever the period, and
N = T^0/dt = 10 stages keeps a step near 1 ms (0.5 s doubles N; DAQP's cost of a new
Hessian grows ~N^3, benchmarks/bench_hybrid_mpc.py).

Post-capture MPC (Problem 3, eqs. 73-77, 82)
---------------------------------------------
Decision state ``dx1 = (p_eta, omega_c, rho_n - r_des, rho_n' - r_des')`` (12), linearised
about A_1 (eq. 14: p = q_I, omega_c = 0, rho_n = r_des) with the deputy docked (rho = 0,
q = q_I, omega = 0; x^0 are parameters, eq. 62), input ``du1 = u - kappa^1(x_ref)`` (eq. 65).
The composite pieces are those of :mod:`proxops.dynamics.hybrid_relative` (corrected
eqs. 48, 51: composite inertia about the pair CoM, moment arm (m_c/m) d of F_d); their
Jacobian is analytic (:func:`post_capture_linearization`, tested against finite differences
of :func:`post_capture_rhs`):

    p_eta'  = omega_c / 2                      (at p = q_I; see below)
    omega_c' = -2 K omega_t^x p_eta - (omega_t^x + K) omega_c + J^-1 (M_d + (m_c/m) d^x F_d)
    e_n''   = G1 e_n + G2 e_n' - (2/m) kappa_1^1 x p_eta + C_{T<-D} F_d / m

with K = J^-1 (omega_t^x J - (J omega_t)^x). Two blocks are taken at the measured attitude
instead of at p = q_I (our choices, not the paper's; both switchable in the config): the
translational input block C_{T<-D} = R^T Q^T (eq. 48; the identity would aim the thrust
along the wrong axes while the chief is still far from q_I, e.g. the 120 deg p of eq. 78),
and the kinematics p_eta' = (p_eta^x + p_mu I) omega_c / 2 (eq. 29; the docked 1/2 I
overstates the attitude rate by 1/p_mu = 2 at 120 deg). x_ref follows
:func:`reference_rhs` (natural CW), so the reference error has the same linear model.
Box (64): ±5 N / ±5 N m around kappa^1. Horizon T^1 and period: not in the paper; defaults
10 s and 1 s. Solved by DAQP (condensed; A, Q, R constant, B's translational block follows
the attitude).

Solve time: ``Command.solve_time_s`` is the wall time of the whole step (linearisation,
discretisation, condensing and the solver); ``info["solver_time_s"]`` the solver alone (its
data update, where DAQP factorises the new Hessian, plus the solve call).

Failures: a solve without a usable solution returns its :class:`proxops.status.Status` with
the fallback command ``clip(kappa, box)`` (the steady input: holds the docking configuration
if there, zero net control otherwise) and a ``("fallback", ...)`` event; a non-finite state
returns Status.INVALID_INPUT with u = 0. Never an exception at run time.

Paper corrections and readings (see also :mod:`proxops.dynamics.hybrid_relative`):

* eq. 66: printed ``v' R^T drho`` with v = P_c/|P_c| "in frame T". P_c (eq. 5) and rho are
  C components, so ``v' R^T rho`` mixes frames; the docking-axis alignment of rho (C) with
  the port normal (C) is ``v_C' rho`` (= v_T' R^T rho with v_T = R^T v_C). Implemented:
  ``lambda_f (|rho| - v_C' rho)^2``.
* eq. 79: ``Q_f^0 = 10^2 I_3`` cannot weight the 12-entry dx0: read as 10^2 I_12.
  eq. 80: ``Q_f^0(c) = 10^{c+6}`` (a scalar): read as 10^{c+6} I_12. In (80) the blocks of
  ``Q^0(c) = blkdiag(10^2 I_3, 10^{c+1} I_3, 10^{c+4} I_6)`` weight (rho, rho', (omega, q_eta)).
* lambda_f (66) is not given: default 10^2 (the rho weight of (79)); a choice.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from proxops.control.hybrid_kernels import (
    Tape,
    approach_target_kernel,
    capture_model_kernel,
    capture_step_kernel,
    face_penalty_sum,
    post_model_kernel,
    post_step_kernel,
)
from proxops.core.quaternion import dcm_kernel, skew
from proxops.dynamics.hybrid_relative import (
    S_OM,
    S_OMC,
    S_P,
    S_Q,
    S_REF,
    S_RHO,
    S_RHOD,
    S_RN,
    S_RND,
    composite_inertia,
    reference_rhs,
    relative_rhs,
    steady_inputs,
)
from proxops.dynamics.two_rigid_bodies import HybridParams
from proxops.errors import input_error
from proxops.contracts import Command
from proxops.solvers import QuadraticProgram, build_conic_problem, make_solver
from proxops.solvers.daqp_qp import RAW_STATUS
from proxops.solvers.front import SOLVERS_FOR
from proxops.status import Status

N_DX = 12  # reduced decision state of both problems
N_U = 6
_DAQP_OPTIMAL = RAW_STATUS[1]  # the raw status DaqpQP.solve reports for DAQP's plain "optimal" exit


# --------------------------------------------------------------------------------------
# configurations
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CaptureMPCConfig:
    """Problem 2 settings (Basu et al. §VI.A, §VII). Weights are diagonal entries."""

    horizon_s: float = 10.0  # T^0 = 10 s (§VII)
    period_s: float = 1.0  # control period: not in the paper; our choice (module doc)
    Q_rho: float = 1e2  # eq. 79: Q^0 = blkdiag(10^2 I3, 10 I3, 10^3 I3, 10^3 I3)
    Q_rho_dot: float = 1e1  # eq. 79
    Q_omega: float = 1e3  # eq. 79
    Q_q: float = 1e3  # eq. 79 (on q_eta)
    R_force: float = 1e4  # eq. 79: R^0 = blkdiag(10^4 I3, 10^4 I3)
    R_torque: float = 1e4  # eq. 79
    Q_terminal: float = 1e2  # eq. 79: Q_f^0 = 10^2 I (printed I_3; read as I_12)
    collision_weights: bool = True  # eq. 80 for collision count c >= 1
    # eq. 80's weights grow as 10^c without bound; beyond c = 10 the condensed Hessian's
    # Q_f/R ratio (10^(c+5)) passes 1e15, the end of double precision (and 10.0**(c+6)
    # overflows at c = 303), so the weights stop growing there. Our choice, not the paper's.
    collision_weight_cap: int = 10
    face_weight: float = 1e2  # lambda_f of eq. 66: not given by the paper; our choice
    face_form: str = "qp"  # "qp" (linearised |rho|, DAQP) | "socp" (exact cone, Clarabel)
    thrust_at_current_attitude: bool = True  # force block of B at the measured q (not q_I; module doc)
    kinematics_at_current_attitude: bool = True  # q_eta' = (q_eta^x + q_mu I) omega / 2 at the measured q
    # approach guidance (not in the paper, module doc): go round the chief to the port axis
    approach_guidance: bool = True
    corridor_half_angle_deg: float = 20.0  # final approach inside this cone about v (from the chief CoM)
    waypoint_step_deg: float = 30.0  # how far round the chief each waypoint leads
    safe_margin_m: float = 0.3  # waypoint radius = chief half-diagonal + deputy port's reach + this
    retreat_fraction: float = 0.9  # closer than this fraction of the waypoint radius: back off radially first
    max_iter: int = 2000  # iteration cap of the QP / SOCP solver
    # Solvers by name (proxops.solvers.make_solver): the QP form on "daqp" (default), "piqp" or
    # "clarabel"; the SOCP form on "clarabel" (default) or "ipopt". Only DAQP relaxes the soft rate
    # rows below (its soft constraints); on the other QP solvers they are hard rows, so a measured
    # rate beyond the bound makes the QP infeasible and the step falls back to kappa^0.
    solver: str = "daqp"
    socp_solver: str = "clarabel"
    # Rate bound (not in the paper): |omega_i| <= rate_max_deg_s per axis of the deputy's
    # rate relative to the chief on every predicted stage, as soft rows (DAQP relaxes them at a
    # penalty when the measured rate is already beyond). 10 deg/s: 1.6 x the eq. 78 start
    # (|omega| = 6.2 deg/s), so the paper's case is untouched while the 10 m start, which spun
    # the deputy to 65 deg/s, is held. None: no bound.
    rate_max_deg_s: float | None = 10.0
    # Far from the port the linear model's lever arm is wrong (failure analysis): eq. 19
    # makes the port move with the deputy's attitude (rho = R rho_0 + Q^T P_d - P_c); linearised,
    # a constant rate moves the port without bound (omega x P_d t), while the true port only
    # circles the deputy CoM within |P_d| = 0.35 m. At 10 m the plan spun the deputy up to
    # "translate" the port. Beyond this port range (m) the translational rows of A do not see
    # the deputy's rate and attitude (the port moves with the CoM). None: never.
    decouple_beyond_m: float | None = 1.0

    def check(self) -> None:
        for name in ("horizon_s", "period_s", "Q_rho", "Q_rho_dot", "Q_omega", "Q_q", "R_force", "R_torque",
                     "Q_terminal"):
            _positive(f"capture_mpc.{name}", getattr(self, name))
        if not (math.isfinite(self.face_weight) and self.face_weight >= 0.0):
            raise input_error("capture_mpc.face_weight", self.face_weight, "must be a finite number >= 0")
        if self.face_form not in ("qp", "socp"):
            raise input_error("capture_mpc.face_form", self.face_form, "allowed: qp, socp")
        _solver_name("capture_mpc.solver", self.solver, "QP")
        _solver_name("capture_mpc.socp_solver", self.socp_solver, "SOCP")
        if not 1 <= int(self.collision_weight_cap) <= 10:
            raise input_error("capture_mpc.collision_weight_cap", self.collision_weight_cap,
                              "must lie in [1, 10] (10^(c+5) Q_f/R beyond 10 exceeds double precision)")
        for name in ("corridor_half_angle_deg", "waypoint_step_deg"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0.0 < value < 180.0):
                raise input_error(f"capture_mpc.{name}", value, "must lie in (0, 180)", "deg")
        if not (isinstance(self.retreat_fraction, (int, float)) and 0.0 <= self.retreat_fraction <= 1.0):
            raise input_error("capture_mpc.retreat_fraction", self.retreat_fraction, "must lie in [0, 1]")
        if not (math.isfinite(self.safe_margin_m) and self.safe_margin_m >= 0.0):
            raise input_error("capture_mpc.safe_margin_m", self.safe_margin_m, "must be a finite number >= 0", "m")
        _steps("capture_mpc", self.horizon_s, self.period_s)


@dataclass(frozen=True)
class PostCaptureMPCConfig:
    """Problem 3 settings (Basu et al. §VI.B, §VII)."""

    horizon_s: float = 10.0  # T^1: not in the paper; our choice (= T^0)
    period_s: float = 1.0  # control period: not in the paper; our choice
    Q_attitude: float = 1e8  # eq. 82: Q_1^1 = 10^8 I6 on (p_eta, omega_c)
    Q_orbit: float = 1e4  # eq. 82: Q_2^1 = 10^4 I6 on (rho_n - r_des, rho_n' - r_des')
    R_input: float = 1e2  # eq. 82: R^1 = 10^2 I6
    Q_terminal_attitude: float = 1e8  # eq. 82: Q_f^1 = blkdiag(10^8 I6, 10^6 I6)
    Q_terminal_orbit: float = 1e6  # eq. 82
    thrust_at_current_attitude: bool = True  # force block of B at the measured R^T Q^T (module doc)
    kinematics_at_current_attitude: bool = True  # p_eta' = E(p) omega_c at the measured p (module doc)
    max_iter: int = 2000
    solver: str = "daqp"  # QP solver by name (as CaptureMPCConfig.solver; soft rate rows on DAQP only)
    # Rate bound (not in the paper): |omega_c_i| <= rate_max_deg_s per axis of the
    # composite's tumble on every predicted stage (soft rows). 0.5 deg/s per axis (|omega_c| <= 0.87 deg/s,
    # 3.6 x the eq. 78 tumble
    # of 0.238 deg/s); without it the +-5 N m slew from p(0) (120 deg from q_I) spun the pair up to
    # 25.7 deg/s. None: no bound.
    rate_max_deg_s: float | None = 0.5

    def check(self) -> None:
        for name in ("horizon_s", "period_s", "Q_attitude", "Q_orbit", "R_input", "Q_terminal_attitude",
                     "Q_terminal_orbit"):
            _positive(f"post_capture_mpc.{name}", getattr(self, name))
        _steps("post_capture_mpc", self.horizon_s, self.period_s)
        _solver_name("post_capture_mpc.solver", self.solver, "QP")


def _norm(v) -> float:
    """|v| of a float64 vector as np.linalg.norm computes it (sqrt of v.dot(v)), without its checks."""
    return math.sqrt(v.dot(v))


def _solver_name(field: str, name, kind: str) -> None:
    if name not in SOLVERS_FOR[kind]:
        raise input_error(field, name, f"allowed: {', '.join(SOLVERS_FOR[kind])}")


def _positive(name: str, value) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
        raise input_error(name, value, "must be a finite number > 0")


def _steps(prefix: str, horizon_s: float, period_s: float) -> int:
    ratio = horizon_s / period_s
    n = int(round(ratio))
    if n < 1 or abs(ratio - n) > 1e-9 * max(1.0, ratio):
        raise input_error(f"{prefix}.horizon_s", horizon_s,
                          f"must be a whole number (>= 1) of control periods ({prefix}.period_s = {period_s:g} s)", "s")
    return n


def _solve_box_qp(solver, name: str, H, f, lb, ub, max_iter: int, kappa, A=None, bl=None, bu=None, trusted=False):
    """Solve min 1/2 U'HU + f'U, lb <= U <= ub (and, given A, the rows bl <= A U <= bu: the rate
    bounds) with the QP solver ``name`` (proxops.solvers.make_solver), set up on the first call and
    updated in place after (same structure every step). DAQP is set up natively so that the rate
    rows are soft (DAQP may relax them at a penalty); the others take the QuadraticProgram form
    (hard rows). ``trusted``: the data are finite kernel arrays with no equality row (rate bound > 0),
    updated through DAQP's lean path (``update_fast``; the MPC's arrays, rewritten in place before each
    call: DAQP reads them in the update); the other paths get copies. Returns (solver, result, info dict)."""
    t_solver = time.perf_counter()
    lean = solver is not None and name == "daqp" and trusted
    if not lean:  # a solver may keep what it is given: the MPC rewrites its arrays every step
        H, f, lb, ub = H.copy(), f.copy(), lb.copy(), ub.copy()
        if A is not None:
            A, bl, bu = A.copy(), bl.copy(), bu.copy()
    if solver is None:
        solver = make_solver("QP", name, max_iter=max_iter)
        if name == "daqp":
            soft = None if A is None else np.ones(A.shape[0], bool)
            solver.setup_native(H, f, A, bl, bu, lb=lb, ub=ub, soft_rows=soft)
        else:
            solver.setup(QuadraticProgram(P=H, q=f, A=A, bl=bl, bu=bu, lb=lb, ub=ub))
    elif lean:  # finite kernel arrays, no equality row: DAQP's lean path
        if A is None:
            solver.update_fast(H=H, f=f, lb=lb, ub=ub)
        else:
            solver.update_fast(H=H, f=f, A=A, bl=bl, bu=bu, lb=lb, ub=ub)
        status, x, iterations, _, raw = solver.solve_fast()  # no SolverResult (the fields used below)
        out = {"status": status, "kappa": kappa, "iterations": iterations,
               "solver_time_s": time.perf_counter() - t_solver,
               "detail": _DAQP_OPTIMAL if raw is None else str(raw.get("raw_status", ""))}
        return solver, _Solved(status, x), out
    elif name == "daqp":  # native names after setup_native
        if A is None:
            solver.update(H=H, f=f, lb=lb, ub=ub)
        else:
            solver.update(H=H, f=f, A=A, bl=bl, bu=bu, lb=lb, ub=ub)
    elif A is None:
        solver.update(P=H, q=f, lb=lb, ub=ub)
    else:
        solver.update(P=H, q=f, A=A, bl=bl, bu=bu, lb=lb, ub=ub)
    res = solver.solve()
    out = {"status": res.status, "kappa": kappa, "iterations": res.iterations,
           "solver_time_s": time.perf_counter() - t_solver, "detail": str(res.info.get("raw_status", ""))}
    return solver, res, out


class _Solved:
    """The two fields of a SolverResult that the MPCs read after DAQP's ``solve_fast``."""

    __slots__ = ("status", "x", "ok")

    def __init__(self, status, x):
        self.status, self.x, self.ok = status, x, status.ok


def capture_weights(config: CaptureMPCConfig, collisions: int):
    """(Q diag (12), R diag (6), Q_f diag (12)) of eq. 79 (c = 0) or eq. 80 (c >= 1)."""
    if collisions >= 1 and config.collision_weights:
        c = min(int(collisions), config.collision_weight_cap)
        Q = np.concatenate([np.full(3, 1e2), np.full(3, 10.0 ** (c + 1)), np.full(6, 10.0 ** (c + 4))])  # eq. 80
        return Q, np.full(6, 10.0), np.full(12, 10.0 ** (c + 6))  # eq. 80 (Q_f read as 10^{c+6} I_12)
    Q = np.repeat([config.Q_rho, config.Q_rho_dot, config.Q_omega, config.Q_q], 3)  # eq. 79
    R = np.repeat([config.R_force, config.R_torque], 3)
    return Q, R, np.full(12, config.Q_terminal)


# --------------------------------------------------------------------------------------
# models
# --------------------------------------------------------------------------------------
def zoh_discretize(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation: expm([[A, B], [0, 0]] dt) = [[Ad, Bd], [0, I]]."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    E = scipy.linalg.expm(M * dt)
    return E[:n, :n], E[:n, n:]


class CaptureLinearization:
    """(A, B, kappa^0, f_0 at the linearisation point) of the capture flow f_0 about the
    docking configuration, as functions of (p, omega_c): the symbolic Jacobian of
    :func:`relative_rhs` (one CasADi definition) in the reduced state (rho, rho', omega, q_eta)."""

    def __init__(self, params: HybridParams):
        import casadi as ca

        z = ca.SX.sym("z", N_DX)
        u = ca.SX.sym("u", N_U)
        p = ca.SX.sym("p", 4)
        wc = ca.SX.sym("wc", 3)
        q_eta = z[9:12]
        x = ca.vertcat(z[0:9], q_eta, ca.sqrt(1.0 - ca.dot(q_eta, q_eta)), p, wc, ca.SX.zeros(12))
        fz = relative_rhs(x, u, params)[0:12]  # (rho', rho'', omega', q_eta')
        u1, u2 = steady_inputs(p, wc, params)
        kappa = ca.vertcat(u1, u2)
        at = (ca.vertcat(z, u), ca.vertcat(ca.SX.zeros(N_DX), kappa))
        A = ca.substitute(ca.jacobian(fz, z), *at)
        B = ca.substitute(ca.jacobian(fz, u), *at)
        f0 = ca.substitute(fz, *at)
        # one packed output: a single conversion per call
        self._fun = ca.Function("capture_linearization", [p, wc],
                                [ca.vertcat(ca.vec(A), ca.vec(B), kappa, f0)])
        self._fz = ca.Function("capture_reduced_rhs", [z, u, p, wc], [fz])
        self._tape = Tape(self._fun)  # the same operations replayed in numba (hybrid_kernels.Tape)
        self._inp = np.empty(7)

    def __call__(self, p, omega_c):
        """(A (12, 12), B (12, 6), kappa^0 (6,), f0 (12,)) at (p, omega_c)."""
        if self._tape.ok:
            inp = self._inp
            inp[0:4] = p
            inp[4:7] = omega_c
            out = self._tape(inp)
        else:
            out = np.asarray(self._fun(np.asarray(p, float), np.asarray(omega_c, float))).ravel()
        A = out[:144].reshape(12, 12, order="F")
        B = out[144:216].reshape(12, 6, order="F")
        return A, B, out[216:222].copy(), out[222:234].copy()

    def reduced_rhs(self, z, u, p, omega_c) -> np.ndarray:
        """f_0 in the reduced state (for the finite-difference check)."""
        return np.asarray(self._fz(z, u, p, omega_c)).ravel()


def reduced_capture_state(x_rel) -> np.ndarray:
    """dx0 = (rho, rho', omega, q_eta) of eq. 62 with q on its scalar-non-negative branch."""
    x = np.asarray(x_rel, float)
    out = np.empty(N_DX)
    out[0:9] = x[0:9]  # rho, rho', omega (S_RHO, S_RHOD, S_OM)
    q = x[S_Q]
    out[9:12] = (-1.0 if q[3] < 0.0 else 1.0) * q[0:3]
    return out


def post_capture_linearization(params: HybridParams, kappa1_force=None):
    """(A (12, 12), B (12, 6)) of the composite dynamics (eqs. 48, 51 corrected; eq. 29) about
    A_1: p = q_I, omega_c = 0, rho_n = r_des, deputy docked (rho = 0, q = q_I, omega = 0), in
    the reduced state (p_eta, omega_c, rho_n - r_des, rho_n' - r_des') and u = kappa^1 + du.
    ``kappa1_force`` (N, T components = D at the point) enters only the p_eta -> e_n'' block."""
    x_dock = np.zeros(32)
    x_dock[S_Q.stop - 1] = 1.0
    x_dock[S_P.stop - 1] = 1.0
    J = composite_inertia(x_dock, params)
    Jinv = np.linalg.inv(J)
    m = params.mass_total_kg
    wt = params.omega_t
    Wx = skew(wt)
    K = Jinv @ (Wx @ J - skew(J @ wt))  # d/dW of J^-1 (W x J W) at W = omega_t
    d = params.P_c - params.P_d  # R rho_0 at rho = 0, q = q_I
    arm = params.mass_chief_kg / m * d
    n = params.mean_motion_rad_s
    G1 = np.diag([3.0 * n * n, 0.0, -n * n])
    G2 = -np.array([[0.0, -2.0 * n, 0.0], [2.0 * n, 0.0, 0.0], [0.0, 0.0, 0.0]])  # corrected eq. 21 sign
    A = np.zeros((12, 12))
    A[0:3, 3:6] = 0.5 * np.eye(3)  # eq. 29 at p = q_I
    A[3:6, 0:3] = -2.0 * K @ Wx  # R omega_t = omega_t + 2 omega_t x p_eta + O(p_eta^2)
    A[3:6, 3:6] = -Wx - K
    A[6:9, 9:12] = np.eye(3)
    A[9:12, 6:9] = G1
    A[9:12, 9:12] = G2
    if kappa1_force is not None:  # R^T F = F + 2 p_eta x F + ...
        A[9:12, 0:3] = -2.0 * skew(np.asarray(kappa1_force, float)) / m
    B = np.zeros((12, 6))
    B[3:6, 0:3] = Jinv @ skew(arm)
    B[3:6, 3:6] = Jinv
    B[9:12, 0:3] = np.eye(3) / m
    return A, B


def reduced_post_capture_state(x_rel) -> np.ndarray:
    """dx1 = (p_eta, omega_c, rho_n - r_des, rho_n' - r_des') with p on its scalar-non-negative branch."""
    x = np.asarray(x_rel, float)
    out = np.empty(N_DX)
    p = x[S_P]
    out[0:3] = (-1.0 if p[3] < 0.0 else 1.0) * p[0:3]
    out[3:6] = x[S_OMC]
    out[6:12] = x[20:26] - x[26:32]  # (rho_n, rho_n') - x_ref (S_RN, S_RND, S_REF)
    return out


def _post_capture_kappa_pieces(params: HybridParams):
    """(G1, G2, J composite at the docked configuration, omega_t x J omega_t, (m_c/m) d)."""
    n = params.mean_motion_rad_s
    G1 = np.diag([3.0 * n * n, 0.0, -n * n])
    G2 = -np.array([[0.0, -2.0 * n, 0.0], [2.0 * n, 0.0, 0.0], [0.0, 0.0, 0.0]])  # corrected eq. 21 sign
    x_dock = np.zeros(32)
    x_dock[S_Q.stop - 1] = 1.0
    x_dock[S_P.stop - 1] = 1.0
    J = composite_inertia(x_dock, params)
    wt = params.omega_t
    arm = params.mass_chief_kg / params.mass_total_kg * (params.P_c - params.P_d)
    return G1, G2, J, np.cross(wt, J @ wt), arm


def post_capture_steady_inputs(x_ref, params: HybridParams, pieces=None):
    """kappa^1(x_ref) of eq. 65: (m (r_des'' - G1 r_des - G2 r_des'), omega_t x J omega_t - (m_c/m) d x kappa_1^1)
    with the composite inertia J about the pair CoM and d = P_c - P_d (corrected eq. 51).
    ``pieces``: :func:`_post_capture_kappa_pieces` (cached by the controller)."""
    G1, G2, _, gyro, arm = pieces if pieces is not None else _post_capture_kappa_pieces(params)
    x_ref = np.asarray(x_ref, float)
    acc = reference_rhs(x_ref, params)[3:6]
    k1 = params.mass_total_kg * (acc - G1 @ x_ref[0:3] - G2 @ x_ref[3:6])
    return k1, gyro - np.cross(arm, k1)


def face_pointing_penalty(rho, v, weight: float) -> np.ndarray:
    """Eq. 66 (corrected frame, module doc): ``weight (|rho| - v' rho)^2`` for rho (..., 3) in C
    and the unit docking-face normal v in C; zero iff rho lies on the ray of v."""
    rho = np.asarray(rho, float)
    return weight * (np.linalg.norm(rho, axis=-1) - rho @ np.asarray(v, float)) ** 2


def face_pointing_linearized(rho_bar, v) -> np.ndarray:
    """Coefficient a of the QP form of eq. 66: ``|rho| - v' rho ~ a' rho`` with a = rho_bar/|rho_bar| - v
    (the tangent of the positively homogeneous |rho| at rho_bar; exact on the ray of rho_bar).
    Zero for |rho_bar| = 0."""
    rho_bar = np.atleast_2d(np.asarray(rho_bar, float))
    norms = np.linalg.norm(rho_bar, axis=1)
    a = np.zeros_like(rho_bar)
    ok = norms > 1e-9
    a[ok] = rho_bar[ok] / norms[ok, None] - np.asarray(v, float)
    return a


# --------------------------------------------------------------------------------------
# condensed prediction (shared)
# --------------------------------------------------------------------------------------
class _Condensed:
    """X = [x_1..x_N] = Phi x_0 + Gamma U for x_{k+1} = Ad x_k + Bd u_k (dense, numpy)."""

    def __init__(self, N: int, nx: int, nu: int):
        self.N, self.nx, self.nu = N, nx, nu
        k = np.arange(N)
        diff = k[:, None] - k[None, :]  # block (row k = x_{k+1}, column j = u_j): Ad^(k-j) Bd for k >= j
        self._idx = np.where(diff >= 0, diff, 0)
        self._mask = (diff >= 0)[:, :, None, None]

    def build(self, Ad: np.ndarray, Bd: np.ndarray):
        N, nx, nu = self.N, self.nx, self.nu
        powers = np.empty((N + 1, nx, nx))
        powers[0] = np.eye(nx)
        for i in range(N):
            powers[i + 1] = Ad @ powers[i]
        PB = powers[:N] @ Bd  # (N, nx, nu): Ad^i Bd
        G = (PB[self._idx] * self._mask).transpose(0, 2, 1, 3).reshape(N * nx, N * nu)
        Phi = powers[1:].reshape(N * nx, nx)
        return Phi, G


class _QpArrays:
    """The QP of one MPC step (N stages, n states, m inputs), filled in place by the MPC's step kernel
    (hybrid_kernels.capture_step_kernel / post_step_kernel): H, f, G, free (= Phi dx0), the rate rows
    A_rate, bl, bu (3N of them with ``rates``, else none), the input box lb, ub, kappa and dx0."""

    def __init__(self, N: int, n: int, m: int, rates: bool):
        nU, nX, r = N * m, N * n, 3 * N if rates else 0
        self.H, self.f, self.G, self.free = np.empty((nU, nU)), np.empty(nU), np.empty((nX, nU)), np.empty(nX)
        self.A_rate, self.bl, self.bu = np.empty((r, nU)), np.empty(r), np.empty(r)
        self.lb, self.ub, self.kappa, self.dx0 = np.empty(nU), np.empty(nU), np.empty(m), np.empty(n)

    def solve(self, solver, name: str, max_iter: int, rate_w: float):
        """:func:`_solve_box_qp` of these arrays (rate rows for rate_w >= 0); out["kappa"] is a copy."""
        rows = (self.A_rate, self.bl, self.bu) if rate_w >= 0.0 else (None, None, None)
        return _solve_box_qp(solver, name, self.H, self.f, self.lb, self.ub, max_iter, self.kappa.copy(), *rows,
                             trusted=rate_w != 0.0)


def _command(u, status, t_start, solver_time, mode, events=None, info=None, status_detail=""):
    return Command(u=u, kind="acceleration", status=status, solve_time_s=time.perf_counter() - t_start, mode=mode,
                   events=events or [], info={"solver_time_s": solver_time, **(info or {})},
                   status_detail=status_detail)


# --------------------------------------------------------------------------------------
# capture MPC (Problem 2)
# --------------------------------------------------------------------------------------
class CaptureMPC:
    """Problem 2 (eqs. 62-72) as a Controller: ``reset(t0, x_rel0)``, ``step(t, x_rel) -> Command``
    with ``Command.u = (F_d|_D, M_d|_D)`` (N, N m). See the module doc."""

    mode = "capture"

    def __init__(self, params: HybridParams, config: CaptureMPCConfig | None = None):
        self.params = params
        self.config = config = config or CaptureMPCConfig()
        config.check()
        self.period_s = self.dt = float(config.period_s)
        self.N = _steps("capture_mpc", config.horizon_s, config.period_s)
        self.u_max = np.array([params.force_max_capture_N] * 3 + [params.torque_max_capture_Nm] * 3)
        self.linearization = CaptureLinearization(params)
        self.v = params.P_c / np.linalg.norm(params.P_c)  # docking-face normal in C (eq. 66, corrected)
        # keep the deputy (any attitude) clear of the chief on the way round: chief half-diagonal
        # + the farthest deputy corner from its port + margin
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        self.waypoint_radius_m = float(np.linalg.norm(params.half_chief)
                                       + np.linalg.norm(corners * params.half_deputy - params.P_d, axis=1).max()
                                       + config.safe_margin_m)
        self.target_rho = np.zeros(3)
        self._cond = _Condensed(self.N, N_DX, N_U)
        self._no_plan = np.zeros((self.N, 3))
        # per-step constants of the QP form (radians, rate bound, approach-guidance angles)
        self._rate_w = -1.0 if config.rate_max_deg_s is None else math.radians(config.rate_max_deg_s)
        self._guide = (math.radians(config.corridor_half_angle_deg), config.retreat_fraction,
                       math.radians(config.waypoint_step_deg))
        self._guide_qp = np.array([1.0 if config.approach_guidance else 0.0, self.waypoint_radius_m, *self._guide])
        # the QP form's arrays, rewritten in place every step (capture_step_kernel)
        self._qp = _QpArrays(self.N, N_DX, N_U, self._rate_w >= 0.0)
        self._A, self._B = np.empty((N_DX, N_DX)), np.empty((N_DX, N_U))
        self._target, self._ref, self._face_a = np.empty(3), np.empty(self.N * N_DX), np.empty((self.N, 3))
        self.collisions = 0
        self._solver = None
        self._solver_form = None
        self._weight_cache = {}
        self.reset(0.0, None)

    # ---------------------------------------------------------------- protocol
    def set_collision_count(self, c: int) -> None:
        """Number of contacts so far (eq. 80 weights from c >= 1)."""
        self.collisions = int(c)

    def reset(self, t0: float, x_rel0) -> None:
        """Forget the last plan (the face-penalty linearisation points). The collision count is
        kept: it counts the contacts of the run, which a re-entry into capture does not undo."""
        self._plan_rho = None  # (N, 3) predicted rho_1..rho_N of the last plan
        self.last_plan = None

    def step(self, t: float, x_rel, collisions: int | None = None) -> Command:
        t_start = time.perf_counter()
        if collisions is not None:
            self.set_collision_count(collisions)
        x = np.asarray(x_rel, float)
        if x.shape != (32,) or not np.isfinite(x).all():
            return _command(np.zeros(6), Status.INVALID_INPUT, t_start, 0.0, self.mode,
                            [("fallback", "non-finite or mis-shaped relative state; applied u = 0")])
        plan = self.solve(x)
        if plan["status"].ok:
            u = plan["u"]
            events = []
        else:
            u = np.clip(plan["kappa"], -self.u_max, self.u_max)
            events = [("fallback", f"capture MPC {plan['status']}: applied the steady input kappa^0 (clipped)")]
        info = {"collisions": float(self.collisions), "iterations": float(plan["iterations"]),
                "face_penalty": plan.get("face_penalty", math.nan),
                "approach_target_m": _norm(self.target_rho)}
        return _command(u, plan["status"], t_start, plan["solver_time_s"], self.mode, events, info,
                        plan.get("detail", ""))

    # ---------------------------------------------------------------- model
    def model(self, p, omega_c, q=None, decouple: bool = False):
        """(Ad, Bd, kappa^0 (D components), A, B) at (p, omega_c) for the configured period;
        ``decouple``: the translational rows do not see the deputy's rate and attitude (far from
        the port, config ``decouple_beyond_m``)."""
        A, B, kappa = self.continuous_model(p, omega_c, q, decouple)
        Ad, Bd = zoh_discretize(A, B, self.dt)
        return Ad, Bd, kappa, A, B

    def continuous_model(self, p, omega_c, q=None, decouple: bool = False):
        """(A, B, kappa^0) of :meth:`model` before the discretisation (fresh arrays; one numba call,
        hybrid_kernels.capture_model_kernel, when the linearisation's tape replays and q is given)."""
        tape = self.linearization._tape
        if tape.ok and q is not None:
            cfg = self.config
            return capture_model_kernel(tape.code, tape.a, tape.b, tape.o, tape.c, tape.n_work, tape.n_out,
                                        np.asarray(p, float), np.asarray(omega_c, float), np.asarray(q, float),
                                        float(self.params.mass_deputy_kg), bool(decouple),
                                        bool(cfg.thrust_at_current_attitude), bool(cfg.kinematics_at_current_attitude))
        return self._continuous_model_numpy(p, omega_c, q, decouple)

    def _continuous_model_numpy(self, p, omega_c, q=None, decouple: bool = False):
        """The numpy form of :meth:`continuous_model` (CasADi or its tape, then numpy; kept for the
        test of the kernel and for a q-less call)."""
        A, B, kappa, _ = self.linearization(p, omega_c)
        if decouple:
            A[0:6, 6:12] = 0.0
        if self.config.thrust_at_current_attitude and q is not None:
            Qt = dcm_kernel(np.asarray(q, float))  # C_{C<-D} = Q^T
            B[3:6, 0:3] = Qt / self.params.mass_deputy_kg  # eq. 22's Q^T F_d / m_d at the measured q
            kappa[0:3] = Qt.T @ kappa[0:3]
        if self.config.kinematics_at_current_attitude and q is not None:
            s = 1.0 if q[3] >= 0.0 else -1.0
            x, y, z, w = (s * float(c) for c in q)
            A[9:12, 6:9] = 0.5 * np.array([[w, -z, y], [z, w, -x], [-y, x, w]])  # eq. 27: (q_eta^x + q_mu I)/2
        return A, B, kappa

    # ---------------------------------------------------------------- approach guidance
    def approach_target(self, rho) -> np.ndarray:
        """Position target of the deputy port (C components, m): 0 (the docking configuration,
        Problem 2 as printed) once the port is inside the approach corridor, a cone of half-angle
        ``corridor_half_angle_deg`` about v from the chief CoM; otherwise a waypoint on the sphere
        of radius ``waypoint_radius_m`` about the chief CoM, ``waypoint_step_deg`` further round
        towards the port axis, or, closer than ``retreat_fraction`` of that radius, the point of
        the sphere straight out from the chief CoM (not in the paper; module doc)."""
        return approach_target_kernel(np.asarray(rho, float), self.params.P_c, self.v, self.waypoint_radius_m,
                                      *self._guide)

    def _approach_target_numpy(self, rho) -> np.ndarray:
        """The numpy form of :meth:`approach_target` (kept for the test of the kernel)."""
        cfg = self.config
        s = np.asarray(rho, float) + self.params.P_c  # deputy port from the chief CoM (C)
        r = float(np.linalg.norm(s))
        if r < 1e-9:
            return np.zeros(3)
        cos_t = float(np.clip(s @ self.v / r, -1.0, 1.0))
        theta = math.acos(cos_t)
        if theta <= math.radians(cfg.corridor_half_angle_deg):
            return np.zeros(3)
        if r < cfg.retreat_fraction * self.waypoint_radius_m:  # too close to go round: back off radially first
            return self.waypoint_radius_m * s / r - self.params.P_c
        axis = np.cross(s, self.v)
        if np.linalg.norm(axis) < 1e-6 * r:  # exactly behind the port: go round any side (C x axis)
            axis = np.cross(self.v, [1.0, 0.0, 0.0]) if abs(self.v[0]) < 0.9 else np.cross(self.v, [0.0, 0.0, 1.0])
        axis /= np.linalg.norm(axis)
        step = min(theta, math.radians(cfg.waypoint_step_deg))
        e = s / r
        e_next = e * math.cos(step) + np.cross(axis, e) * math.sin(step)  # Rodrigues (axis is normal to e)
        return self.waypoint_radius_m * e_next - self.params.P_c  # on the sphere: far off, the waypoint pulls in

    # ---------------------------------------------------------------- problem
    def solve(self, x_rel) -> dict:
        """One solve of Problem 2 from ``x_rel``: dict with u (6,), status, du plan (N, 6),
        predicted dx (N, 12), kappa, iterations, solver_time_s."""
        cfg, N, dt = self.config, self.N, self.dt
        x = np.asarray(x_rel, float)
        far = cfg.decouple_beyond_m is not None and _norm(x[S_RHO]) > cfg.decouple_beyond_m
        if cfg.face_form == "qp":
            return self._solve_qp(x, far)
        dx0 = reduced_capture_state(x)
        Ad, Bd, kappa, _, _ = self.model(x[S_P], x[S_OMC], x[S_Q], decouple=far)
        Phi, G = self._cond.build(Ad, Bd)
        Qd, Rd, Qf = capture_weights(cfg, self.collisions)
        W = np.tile(dt * Qd, N)
        W[-N_DX:] = Qf
        free = Phi @ dx0
        self.target_rho = self.approach_target(x[S_RHO]) if cfg.approach_guidance else np.zeros(3)
        ref = np.zeros((N, N_DX))
        ref[:, 0:3] = self.target_rho
        ref = ref.ravel()
        lb = np.tile(-self.u_max - kappa, N)
        ub = np.tile(self.u_max - kappa, N)
        r_blk = np.tile(dt * Rd, N)
        scale = 1.0 / r_blk.max()
        return self._solve_socp(x, dx0, kappa, Phi, G, W, r_blk, free, ref, lb, ub, scale)

    def _weights(self):
        """(W (N*12), r_blk (N*6)) of the current collision count (cached per count)."""
        cfg, N, dt = self.config, self.N, self.dt
        key = min(self.collisions, cfg.collision_weight_cap) if cfg.collision_weights else 0
        if key not in self._weight_cache:
            Qd, Rd, Qf = capture_weights(cfg, self.collisions)
            W = np.tile(dt * Qd, N)
            W[-N_DX:] = Qf
            self._weight_cache[key] = (W, np.tile(dt * Rd, N))
        return self._weight_cache[key]

    def _solve_qp(self, x, far: bool) -> dict:
        """The QP form (DAQP): the whole QP built in place by one numba call
        (hybrid_kernels.capture_step_kernel): the model, stage weights, the rank-one face terms of
        stages k = 1..N-1 (at the last plan shifted by one step; the measured rho without one), the
        input box and the soft rate rows."""
        cfg, N, dt, qp = self.config, self.N, self.dt, self._qp
        tape = self.linearization._tape
        if not tape.ok:  # the numpy model into the kernel's model arrays
            self._A[:], self._B[:], qp.kappa[:] = self._continuous_model_numpy(x[S_P], x[S_OMC], x[S_Q], far)
        W, r_blk = self._weights()
        has_plan = self._plan_rho is not None
        rate_w = self._rate_w
        capture_step_kernel(x, tape.code, tape.a, tape.b, tape.o, tape.c, tape.n_work, tape.n_out, tape.ok,
                            float(self.params.mass_deputy_kg), far, bool(cfg.thrust_at_current_attitude),
                            bool(cfg.kinematics_at_current_attitude), self._guide_qp, self.params.P_c, self.v,
                            self._plan_rho if has_plan else self._no_plan, has_plan, cfg.face_weight > 0.0,
                            dt * cfg.face_weight, rate_w, self.u_max, dt, N, W, r_blk, self._A, self._B, qp.kappa,
                            qp.dx0, self._target, self._ref, self._face_a, qp.H, qp.f, qp.G, qp.free, qp.A_rate,
                            qp.bl, qp.bu, qp.lb, qp.ub)
        self.target_rho = self._target.copy()
        if self._solver is not None and self._solver_form != "qp":
            self._solver = None
        self._solver_form = "qp"
        self._solver, res, out = qp.solve(self._solver, cfg.solver, cfg.max_iter, rate_w)
        if res.x is None or not res.ok:
            self._plan_rho = None
            return out
        # np.clip's values (finite x); DAQP keeps the bounds to its tolerance
        U = np.minimum(np.maximum(res.x, qp.lb), qp.ub)
        X = qp.free + qp.G @ U
        self._plan_rho = X.reshape(N, N_DX)[:, 0:3].copy()
        face = dt * face_penalty_sum(X, N_DX, N, self.v, cfg.face_weight)
        out.update(u=out["kappa"] + U[0:6], du=U.reshape(N, 6), dx=X.reshape(N, N_DX), face_penalty=face)
        self.last_plan = out
        return out

    def _solve_socp(self, x, dx0, kappa, Phi, G, W, r_blk, free, ref, lb, ub, scale) -> dict:
        """Problem 2 with the exact (66) through slacks: ||rho_k|| <= s_k + v' rho_k, cost lambda_f dt s_k^2 (Clarabel)."""
        cfg, N, dt = self.config, self.N, self.dt
        nU = N * N_U
        ns = N - 1  # stages k = 1..N-1
        n = nU + ns
        H = G.T @ (W[:, None] * G)
        H[np.diag_indices_from(H)] += r_blk
        P = np.zeros((n, n))
        P[:nU, :nU] = (2.0 * scale) * 0.5 * (H + H.T)
        P[nU:, nU:] = np.eye(ns) * (2.0 * scale * dt * max(cfg.face_weight, 1e-12))
        q = np.zeros(n)
        q[:nU] = (2.0 * scale) * (G.T @ (W * (free - ref)))
        soc = []
        for k in range(ns):
            rows = k * N_DX + np.arange(3)
            F = np.zeros((3, n))
            F[:, :nU] = G[rows]
            c = np.zeros(n)
            c[:nU] = self.v @ G[rows]
            c[nU + k] = 1.0
            soc.append((F, free[rows], c, float(self.v @ free[rows])))
        lbz = np.concatenate([lb, np.zeros(ns)])
        ubz = np.concatenate([ub, np.full(ns, np.inf)])
        prob = build_conic_problem(q, _dense_pattern_upper(P), lb=lbz, ub=ubz,
                                   soc=[(_dense_pattern(F), g, c, d) for F, g, c, d in soc])
        t_solver = time.perf_counter()
        if self._solver is None or self._solver_form != "socp":
            self._solver = make_solver(prob, cfg.socp_solver)  # set up with the ConicProblem form
            self._solver_form = "socp"
        else:
            self._solver.update(P=prob.P, q=prob.q, A=prob.A, b=prob.b)
        res = self._solver.solve()
        out = {"status": res.status, "kappa": kappa, "iterations": res.iterations,
               "solver_time_s": time.perf_counter() - t_solver,
               "detail": str(res.info.get("raw_status", ""))}
        if res.x is None or not res.ok:
            return out
        U = np.clip(res.x[:nU], lb, ub)
        X = free + G @ U
        rho_pred = X.reshape(N, N_DX)[:, 0:3]
        self._plan_rho = rho_pred.copy()
        face = float(dt * face_pointing_penalty(rho_pred[:-1], self.v, cfg.face_weight).sum())
        out.update(u=kappa + U[0:6], du=U.reshape(N, 6), dx=X.reshape(N, N_DX), face_penalty=face)
        self.last_plan = out
        return out



def _dense_pattern(M: np.ndarray) -> sp.csc_matrix:
    """CSC with every entry stored (explicit zeros kept): a fixed sparsity pattern for in-place updates."""
    M = np.asarray(M, float)
    r, c = np.nonzero(np.ones_like(M, dtype=bool))
    return sp.csc_matrix((M[r, c], (r, c)), shape=M.shape)


def _dense_pattern_upper(M: np.ndarray) -> sp.csc_matrix:
    M = np.asarray(M, float)
    r, c = np.triu_indices(M.shape[0])
    return sp.csc_matrix((M[r, c], (r, c)), shape=M.shape)


# --------------------------------------------------------------------------------------
# post-capture MPC (Problem 3)
# --------------------------------------------------------------------------------------
class PostCaptureMPC:
    """Problem 3 (eqs. 73-77, weights 82) as a Controller: orbit tracking of the pair's CoM
    towards x_ref (``x_rel[S_REF]``) and damping of the chief's tumble. See the module doc."""

    mode = "post_capture"

    def __init__(self, params: HybridParams, config: PostCaptureMPCConfig | None = None):
        self.params = params
        self.config = config = config or PostCaptureMPCConfig()
        config.check()
        self.period_s = self.dt = float(config.period_s)
        self.N = N = _steps("post_capture_mpc", config.horizon_s, config.period_s)
        self.u_max = np.array([params.force_max_post_N] * 3 + [params.torque_max_post_Nm] * 3)
        self._cond = _Condensed(N, N_DX, N_U)
        self.A, self.B = post_capture_linearization(params)
        self._kappa_pieces = _post_capture_kappa_pieces(params)
        Qd = np.repeat([config.Q_attitude, config.Q_orbit], 6)
        W = np.tile(self.dt * Qd, N)
        W[-N_DX:] = np.repeat([config.Q_terminal_attitude, config.Q_terminal_orbit], 6)
        self._W = W
        self._r_blk = np.full(N * N_U, self.dt * config.R_input)
        self._scale = 1.0 / self._r_blk.max()
        self._zero_ref = np.zeros(N * N_DX)
        self._zero_face = np.zeros((N, 3))
        self._model_key = None
        self._solver = None
        self._rate_w = -1.0 if config.rate_max_deg_s is None else math.radians(config.rate_max_deg_s)
        self._qp = _QpArrays(N, N_DX, N_U, self._rate_w >= 0.0)  # rewritten in place every step (post_step_kernel)
        self.reset(0.0, None)

    def reset(self, t0: float, x_rel0) -> None:
        self.last_plan = None

    def model(self, x_rel):
        """(Ad, Bd, kappa^1 (D components), A, B) for the current state: A about A_1 (constant
        with the CW reference), the force block of B at the measured attitude (module doc)."""
        A, B, kappa = self.continuous_model(x_rel)
        Ad, Bd = zoh_discretize(A, B, self.dt)
        return Ad, Bd, kappa, A, B

    def continuous_model(self, x_rel):
        """(A, B, kappa^1) of :meth:`model` before the discretisation (fresh arrays; numba:
        hybrid_kernels.post_model_kernel)."""
        G1, G2, _, gyro, arm = self._kappa_pieces
        return post_model_kernel(np.asarray(x_rel, float), self.A, self.B, G1, G2, gyro, arm,
                                 float(self.params.mass_total_kg), self.config.kinematics_at_current_attitude,
                                 self.config.thrust_at_current_attitude)

    def step(self, t: float, x_rel) -> Command:
        t_start = time.perf_counter()
        x = np.asarray(x_rel, float)
        if x.shape != (32,) or not np.isfinite(x).all():
            return _command(np.zeros(6), Status.INVALID_INPUT, t_start, 0.0, self.mode,
                            [("fallback", "non-finite or mis-shaped relative state; applied u = 0")])
        plan = self.solve(x)
        if plan["status"].ok:
            u, events = plan["u"], []
        else:
            u = np.clip(plan["kappa"], -self.u_max, self.u_max)
            events = [("fallback", f"post-capture MPC {plan['status']}: applied the steady input kappa^1 (clipped)")]
        info = {"iterations": float(plan["iterations"]),
                "tracking_error_m": _norm(x[S_RN] - x[S_REF][0:3])}  # rho_n - r_des
        return _command(u, plan["status"], t_start, plan["solver_time_s"], self.mode, events, info,
                        plan.get("detail", ""))

    def solve(self, x_rel) -> dict:
        """One solve of Problem 3 from ``x_rel``: dict with u (6,), status, du plan (N, 6), predicted dx
        (N, 12), kappa, iterations, solver_time_s. The QP is built in place by one numba call
        (hybrid_kernels.post_step_kernel)."""
        N, qp, cfg = self.N, self._qp, self.config
        x = np.asarray(x_rel, float)
        G1, G2, _, gyro, arm = self._kappa_pieces
        post_step_kernel(x, self.A, self.B, G1, G2, gyro, arm, float(self.params.mass_total_kg),
                         cfg.kinematics_at_current_attitude, cfg.thrust_at_current_attitude, self._rate_w, self.u_max,
                         self.dt, N, self._W, self._r_blk, self._zero_ref, self._zero_face, qp.kappa, qp.dx0, qp.H,
                         qp.f, qp.G, qp.free, qp.A_rate, qp.bl, qp.bu, qp.lb, qp.ub)
        self._solver, res, out = qp.solve(self._solver, cfg.solver, cfg.max_iter, self._rate_w)
        if res.x is None or not res.ok:
            return out
        U = np.minimum(np.maximum(res.x, qp.lb), qp.ub)  # np.clip's values (finite x)
        X = qp.free + qp.G @ U
        out.update(u=out["kappa"] + U[0:6], du=U.reshape(N, 6), dx=X.reshape(N, N_DX))
        self.last_plan = out
        return out


__all__ = [
    "CaptureLinearization",
    "CaptureMPC",
    "CaptureMPCConfig",
    "PostCaptureMPC",
    "PostCaptureMPCConfig",
    "capture_weights",
    "face_pointing_linearized",
    "face_pointing_penalty",
    "post_capture_linearization",
    "post_capture_steady_inputs",
    "reduced_capture_state",
    "reduced_post_capture_state",
    "zoh_discretize",
]
