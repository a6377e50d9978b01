"""Receding-horizon QP (Iskender 2026 eq. 11) in the target body frame.

Problem at time t with body-frame state x_0 (m, m/s) and inputs u_j (m/s^2)::

    min  sum_{j=1}^{N-1} |x_j - r_j|_Q^2 + |x_N - r_N|_{Q_N}^2
         + sum_{j=0}^{N-1} |u_j|_{R_u}^2 + |u_j - u_{j-1}|_{R_du}^2          (11a)
    s.t. x_{j+1} = A_j x_j + B_j u_j                                      (11b,c)
         G p_j <= h,  j = 1..N            (corridor eq. 9, body frame)     (11d)
         -a_max <= u_j <= a_max           (per target-body axis)           (11e)

Input frame. The decision variables u_j are *target-body-axes* components of the
chaser acceleration, taken at the sample instant t_j and then held constant in LVLH
over the step (ZOH): the plant receives u_L,j = R_LB(theta_j) u_j, the rotation being done
here (``MpcSolution.u0_hill``) and in :mod:`proxops.control.los_regimes`. So the box
(11e) is a box on the body axes. The paper does not say in which frame its input box is
written (its eq. 11 is posed in the body frame, its plant takes LVLH accelerations); a box
in LVLH axes would be a different, rotating set in body axes (same per-axis limit, up to
sqrt(2) larger body-axis components at 45 deg) - an ambiguity of the paper, not a derivation.

u_{-1} is the previously applied input and r_j the reference (one state or a
trajectory). The (11a) sum written from j = 0 also contains |x_0 - r|_Q^2, a constant.
The corridor row at j = 0 is the measured state, not a decision, so the simulation
checks it instead of the QP.

Prediction model. A_j, B_j are the exact Jacobians of the body-frame CW step
(:class:`proxops.dynamics.tumbling_target.BodyFrameModel`), time-varying because the
body frame turns: x_j = T_j (Phi^j T_0^-1 x_0 + sum_i Phi^(j-1-i) B_d R_LB(theta_i) u_i).
Were the CW model isotropic about the orbit normal, this map would not depend on the
current angle theta_k at all; only the 3 n^2 x gravity-gradient term is anisotropic
(relative size ~1.5 n^2 t^2 / 2 = 1.5e-3 over a 40 s horizon). So the condensed map is
split into its rotation average S (constant: H and the corridor rows never change, and
DAQP keeps its factorisation; updating H or A would cost DAQP 3-4 ms at N = 40) plus an
exact affine offset evaluated at the previous plan shifted by one step (real-time-iteration
style). Predictions are exact at that plan and the remaining
error is the anisotropic part acting on the change of plan; for the first step it is
~n^2 dt^2 ~ 1e-6 of the input effect (tested in tests/test_los_mpc.py). The paper
instead freezes the step-k finite-difference linearisation over the horizon (§4.4).

Per-step data without re-condensing. The QP is centred on the plan guess g (the previous
plan shifted by one step): with U = g + dU the predicted states are p_g + S dU, p_g the exact
LTV prediction of g (one recursion x_L,j+1 = Phi x_L,j + B_d R_LB(theta_j) g_j in LVLH,
rotated to the body frame: O(N), tests/test_los_mpc.py checks it against the product of
exact one-step Jacobians). The linear term is
f = S'W (p_g - r) + (R_u + D'R_du D) g - [R_du u_{-1}; 0] and the unconstrained minimiser
U_c = g - H^-1 f. DAQP is given the QP in w = U - U_c, which has no linear term
(1/2 w'Hw): its bounds are -a_max - U_c <= w <= a_max - U_c and
G (S w)_pos,j <= h - G (p_g + S (U_c - g))_pos,j. This is the same LDP DAQP builds from
(H, f) (its u = R (U - U_c) either way), but DAQP then keeps no linear term, so a step
only rewrites bound vectors (O(m)) instead of DAQP recomputing R^-T f and d = b + M v
(O(m n), ~40 us at N = 40). One jitted kernel (:func:`_qp_data`) forms g, computes p_g, f,
U_c and the bounds in place (the corridor rows G S_pos and H never change; no per-step allocation but DAQP's
fresh solution): in hard mode on DAQP straight into the bound vectors DAQP reads, else into preallocated buffers,
using that S is block lower-triangular Toeplitz (block (j, i) = K_(j-i), see
``LosMpc._geometry_blocks``): its products read the N blocks K_d, not S; U = w + U_c. Soft mode
keeps the linear term (the QP in dU with f, DAQP's own update): shifting the slack to its
unconstrained minimiser -rho / w = -1e7 m would put 1e7 m offsets into every row and cost
~1e-9 of accuracy (tests/test_los_mpc.py compares both forms with the direct QP).

Constraint handling (``constraint_mode``):
- ``"hard"`` (paper, used for feasibility classification): an infeasible QP is returned
  as status ``"infeasible"``; the caller treats it as a failed run.
- ``"soft"`` (operational): one slack s_j >= 0 per predicted step, ``G p_j - h <= s_j 1``,
  cost ``rho * s_j + 0.5 * w * s_j^2`` (written into 1/2 of (11a)). By exact-penalty
  theory (Nocedal & Wright Thm. 17.3; Kerrigan & Maciejowski 2000) the soft solution
  equals the hard one whenever the hard QP is feasible and rho exceeds the l1 norm of each
  step's corridor multipliers (``slack_penalty`` default 1e7; the multipliers seen in the
  runs here are below ~1e4, the test checks the equality).

Solver: the one named by ``LosMpcConfig.solver`` through :func:`proxops.solvers.make_solver`
(the :class:`proxops.solvers.forms.QuadraticProgram` P = H, q, A = corridor rows, bu, lb, ub; data
updated in place each step by the form's field names). Default DAQP, warm-started from the previous
active set, with its lean paths: no linear term in hard mode (``setup_native`` with f = None),
in hard mode the kernel's bounds written into DAQP's own bound vectors (``DaqpQP.bound_vectors``), re-read and
solved by ``solve_bounds_fast`` (no copies, no keyword update, no SolverResult per step); soft mode through
``update_fast`` and ``solve_fast``. PIQP and Clarabel (interior point) start cold every step. The closed loop
calls :meth:`LosMpc.solve_raw` (MpcSolution's fields as a tuple, no solution object per step); on the staged
DAQP path its guidance runs this kernel itself, fused with the reference (:meth:`LosMpc.lean_inputs`,
``los_regimes._guided_qp_data``), then :meth:`LosMpc.solve_staged`: one kernel call and one solver call a step.

Per-step cost (benchmarks/bench_los.py prints it for N = 20..160): the kernel reads H^-1 (3N x 3N) and
O(N) data, ~22 N^2 multiply-adds, below one DAQP iteration (its constraint check reads M = A R^-1,
9N x 3N); everything else is O(N) or fixed.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from proxops.constraints.los_corridor import LosCorridor
from proxops.dynamics.tumbling_target import BodyFrameModel, body_from_hill_matrix, hill_from_body_matrix, rotate_z
from proxops.core.memo import memo_get
from proxops.errors import input_error
from proxops.solvers.forms import QuadraticProgram
from proxops.solvers.front import QP_SOLVERS, make_solver
from proxops.status import Status

PAPER_Q = (15.0, 30.0, 15.0, 1.0, 1.0, 1.0)
_PREDICTION_CACHE: dict = {}  # (n, w_rel, dt, N) -> prediction blocks (Monte Carlo reuses them)
_WEIGHTS_CACHE: dict = {}  # (prediction key, weights[, corridor]) -> (H, H^-1) [, geometry blocks]
DAQP_INF = 1e30  # DAQP's "no bound" (proxops.solvers.daqp_qp.DAQP_INF)


@dataclass
class LosMpcConfig:
    """Weights and sizes of eq. (11). Defaults: §6 single-run configuration."""

    horizon: int = 40
    Q: tuple = PAPER_Q
    terminal_factor: float = 30.0  # Q_N = terminal_factor * Q (§6)
    R_u: tuple = (1e-2, 1e-2, 1e-2)
    R_du: tuple = (1e4, 1e4, 1e4)
    constraint_mode: str = "hard"  # "hard" | "soft"
    slack_penalty: float = 1e7  # rho, l1 exact penalty per step (soft mode)
    slack_quadratic: float = 1.0  # w, keeps the Hessian positive definite (soft mode)
    max_iter: int = 2000
    refinements: int = 0  # extra solves re-centred on the new plan (0 = one QP per step)
    solver: str = "daqp"  # QP solver by name (proxops.solvers.make_solver): daqp, piqp, clarabel
    solver_settings: dict = field(default_factory=dict)  # keyword settings of that solver's adapter

    @classmethod
    def single_run(cls, **kw) -> "LosMpcConfig":
        """§6 single-scenario configuration: N_p = 40, R_du = 1e4 I (T_sim = 600 s)."""
        return cls(horizon=40, R_du=(1e4, 1e4, 1e4), **kw)

    @classmethod
    def monte_carlo(cls, **kw) -> "LosMpcConfig":
        """§6 Monte Carlo configuration: N_p = 20, R_du = diag(1e5, 1e4, 1e5) (T_sim = 400 s)."""
        return cls(horizon=20, R_du=(1e5, 1e4, 1e5), **kw)

    def check(self) -> None:
        if int(self.horizon) != self.horizon or self.horizon < 1:
            raise input_error("mpc.horizon", self.horizon, "must be an integer >= 1", "steps")
        for name in ("Q", "R_u", "R_du"):
            vals = np.asarray(getattr(self, name), float)
            size = 6 if name == "Q" else 3
            if vals.shape != (size,) or np.any(vals < 0) or not np.all(np.isfinite(vals)):
                raise input_error(f"mpc.{name}", getattr(self, name), f"must be {size} finite numbers >= 0 (diagonal)")
        if self.constraint_mode not in ("hard", "soft"):
            raise input_error("mpc.constraint_mode", self.constraint_mode, "allowed: hard, soft")
        if not self.slack_penalty > 0:
            raise input_error("mpc.slack_penalty", self.slack_penalty, "must be > 0")
        if self.solver not in QP_SOLVERS:
            raise input_error("mpc.solver", self.solver, f"allowed: {', '.join(QP_SOLVERS)}")


@dataclass(slots=True)
class MpcSolution:
    """Result of one MPC solve. ``u0`` is the body-axes input to apply (m/s^2) and
    ``u0_hill`` the same vector in LVLH components (what the plant receives; computed when asked
    from ``theta_rad`` = theta_k, the body angle at the solve)."""

    status: Status  # the solver status (proxops.status)
    u0: np.ndarray  # (3,) a view of ``inputs`` after a solve (do not modify)
    theta_rad: float
    inputs: np.ndarray | None  # (N, 3) planned body-axes inputs (m/s^2; the MPC's own plan: do not modify)
    solve_time_s: float  # QP solver's solve call(s)
    build_time_s: float  # QP data update: kernel + solver update (DAQP, hard mode: its update is in the solve call)
    iterations: int
    max_slack_m: float = 0.0  # soft mode: largest corridor slack used
    info: dict = field(default_factory=dict)
    # [plan guess g (3N), p_g (6N)] of this solve (a fresh array) and the averaged map S (6N, 3N)
    basis: np.ndarray | None = field(default=None, repr=False)
    S: np.ndarray | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        return self.status.ok

    @property
    def u0_hill(self) -> np.ndarray:
        """u0 in LVLH components: R_LB(theta_k) u0 (m/s^2)."""
        return rotate_z(self.theta_rad, self.u0)

    @property
    def prediction(self) -> tuple | None:
        """(p_g (6N,), S (6N, 3N), dU (3N,)): the predicted states are p_g + S dU (p_g: exact
        prediction of the plan g the QP was centred on, dU = U - g the change of plan); None
        after a failed solve. Computed when asked (the closed loop does not use it)."""
        if self.basis is None or self.inputs is None:
            return None
        n3 = self.S.shape[1]
        return self.basis[n3:], self.S, self.inputs.reshape(n3) - self.basis[:n3]

    @property
    def states(self) -> np.ndarray | None:
        """(N, 6) predicted body-frame states x_1..x_N = p_g + S dU (see ``prediction``)."""
        pred = self.prediction
        if pred is None:
            return None
        base, S, dU = pred
        return (base + S @ dU).reshape(-1, 6)


def _rotations_hill_from_body(theta: np.ndarray) -> np.ndarray:
    """R_LB(theta) = R_z(theta) for an array of angles, shape (n, 3, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros((theta.size, 3, 3))
    R[:, 0, 0] = c
    R[:, 0, 1] = -s
    R[:, 1, 0] = s
    R[:, 1, 1] = c
    R[:, 2, 2] = 1.0
    return R


class LosMpc:
    """Condensed eq.-(11) MPC in the body frame with DAQP (see module doc).

    ``model``: BodyFrameModel (n, w_t, dt, theta0); ``corridor``: LosCorridor (G, h);
    ``a_max``: per-axis input bound (m/s^2); ``config``: LosMpcConfig.

    ``solve(t, x_body, x_ref, u_prev)`` -> :class:`MpcSolution`; ``u_prev`` is the
    previously applied body-axes input. ``exact_prediction(t, x_body, inputs)`` gives the
    exact LTV prediction of a plan (for checks).
    """

    n_average_angles = 16  # rotation average of the condensed map (kills harmonics < 16)

    def __init__(self, model: BodyFrameModel, corridor: LosCorridor, a_max: float, config: LosMpcConfig | None = None):
        if not a_max > 0:
            raise input_error("chaser.a_max_mps2", a_max, "must be > 0", "m/s^2")
        self.model = model
        self.corridor = corridor
        self.a_max = float(a_max)
        self.cfg = config or LosMpcConfig()
        self.cfg.check()
        N = self.N = int(self.cfg.horizon)
        nu = self.n_u = 3 * N
        self.soft = self.cfg.constraint_mode == "soft"
        self.n_var = nu + (N if self.soft else 0)
        self._offsets = model.w_rel * model.dt * np.arange(N + 1)  # theta_j - theta_k
        self._ref_shape = (N, 6)
        self._plan_shape = (N, 3)
        self._ref_buffer = np.zeros((N, 6))  # a single reference state held over the horizon
        key = (model.n, model.w_rel, model.dt, N)
        cached = memo_get(_PREDICTION_CACHE, key, lambda: self._prediction_blocks(model, N))
        self._Phi_pow, self._Su_L, self._S = cached
        self._Phi_pow_flat = self._Phi_pow.reshape(6 * N, 6)
        self._Su_L_flat = self._Su_L.reshape(6 * N, nu)
        self._S_flat = self._S.reshape(6 * N, nu)
        # QP written as 1/2 U'HU + f'U = 1/2 of (11a): H = S'WS + R_u + D' R_du D, W = diag(Q, ..., Q, Q_N)
        self._r_u = np.tile(np.asarray(self.cfg.R_u, float), N)
        self._r_d = np.tile(np.asarray(self.cfg.R_du, float), N)
        weights = (tuple(self.cfg.Q), float(self.cfg.terminal_factor), tuple(self.cfg.R_u), tuple(self.cfg.R_du))
        H, self._H_inv = memo_get(_WEIGHTS_CACHE, (key, weights), self._weighted_blocks)
        self._r_d0 = np.asarray(self.cfg.R_du, float)
        G, self._h = corridor.G, corridor.h
        self._G_T = np.ascontiguousarray(G.T)
        self._G = np.ascontiguousarray(G, dtype=float)
        self._n_rows = G.shape[0]
        # per-geometry arrays, shared by every run of a campaign (read only)
        A, self._KK, self._PB, self._mats = memo_get(
            _WEIGHTS_CACHE, (key, weights, self._G.tobytes(), np.asarray(self._h, float).tobytes()),
            lambda: self._geometry_blocks(model))
        lb = np.full(self.n_var, -self.a_max)
        ub = np.full(self.n_var, self.a_max)
        # hard mode: the solver gets the QP in w = U - U_c without a linear term (module doc); soft mode
        # keeps the linear term (QP in dU = U - g): shifting the slack to its unconstrained
        # minimiser -rho / w_s = -1e7 m would put 1e7 m offsets into every row (errors ~1e-9)
        self._shift = not self.soft
        if self.soft:
            Hs = np.zeros((self.n_var, self.n_var))
            Hs[:nu, :nu] = H
            Hs[nu:, nu:] = np.eye(N) * self.cfg.slack_quadratic
            As = np.zeros((self._n_rows * N, self.n_var))
            As[:, :nu] = A
            As[:, nu:] = -np.kron(np.eye(N), np.ones((self._n_rows, 1)))
            H, A = Hs, As
            lb[nu:] = 0.0
            ub[nu:] = np.inf
        self._H = H
        self._A = A
        self._lb, self._ub = lb, ub
        self._solver = None  # the QP solver's adapter (proxops.solvers.base.SolverAdapter), made at the first solve
        self._fast = False  # DAQP: bounds (and f) through update_fast / solve_fast (soft) or its bound vectors (hard)
        self._lean = False  # DAQP in hard mode: bounds only, written into DAQP's own bound vectors
        self._lean_step = False  # _lean and no refinements: solve_raw's short path
        self._staged = False  # the kernel's bounds are in DAQP's vectors, not yet re-read (_solve_qp)
        self._form = True  # set up with the QuadraticProgram form (update takes its names)
        self._plan: np.ndarray | None = None  # (3N,) last planned body-axes inputs (a fresh array per solve)
        self._zeros_n = np.zeros(nu)  # the "plan" argument before the first solve
        # constants of the kernel, packed (a jitted call costs ~0.1 us per argument):
        # [w_rel, a_max, shift (1/0), rho, n_var, N, r, cos o_j, sin o_j (N+1 each; o_j = theta_j - theta_k), R_u (3N),
        #  R_du (3N), h (r)]; its read-only matrices are packed in self._mats (_geometry_blocks)
        self._consts = np.concatenate([[model.w_rel, self.a_max, float(self._shift), self.cfg.slack_penalty,
                                        float(self.n_var), float(N), float(self._n_rows)], np.cos(self._offsets),
                                       np.sin(self._offsets), self._r_u, self._r_d, np.asarray(self._h, float)])
        # persistent outputs of the kernel, rewritten in place every step: work = [f, x_c (n_var each), scratch] and the
        # bounds in DAQP's layout, upper = [ub - x_c (n_var), corridor bounds b (N r)], lower = [lb - x_c (n_var),
        # -1e30 (N r)]. DAQP in hard mode: the kernel writes the bounds straight into the vectors DAQP reads
        # (DaqpQP.bound_vectors); else into these buffers, handed to the solver (which copies them)
        nv = self.n_var
        self._work = np.empty(2 * nv + 12 + nu)  # [f, x_c (n_var each), the kernel's scratch (12 + 3N)]
        self._f = self._work[:nv]  # linear term in dU (soft mode: the solver's f)
        self._u_c = self._work[nv : 2 * nv]  # x = the solver's solution + this (U_c or g; slack: 0)
        self._upper = np.empty(nv + self._n_rows * N)
        self._lower = np.full(nv + self._n_rows * N, -DAQP_INF)
        self._lb_w = self._lower[:nv]
        self._ub_w = self._upper[:nv]
        self._b = self._upper[nv:]
        self._basis = np.empty(9 * N)  # [g (3N), p_g (6N)] of the last solve (MpcSolution.prediction: a copy)
        self._kernel_data = (self._consts, self._mats)  # the kernel's read-only inputs

    # ------------------------------------------------------------------ prediction
    def _prediction_blocks(self, model: BodyFrameModel, N: int):
        """(Phi^j (N,6,6), LVLH input map (N,6,3N), rotation-averaged body input map S (N,6,3N))."""
        nu = 3 * N
        # LVLH blocks: x_L,j = Phi^j x_L,0 + sum_i Phi^(j-1-i) Bd u_L,i, j = 1..N
        powers = [np.eye(6)]
        for _ in range(N):
            powers.append(model.Phi @ powers[-1])
        PB = [pw @ model.Bd for pw in powers]
        Su = np.zeros((N, 6, nu))
        for j in range(1, N + 1):
            for i in range(j):
                Su[j - 1, :, 3 * i : 3 * i + 3] = PB[j - 1 - i]
        self._Su_L = Su
        self._Phi_pow = np.array(powers[1:])
        angles = 2.0 * np.pi * np.arange(self.n_average_angles) / self.n_average_angles
        S = np.mean([self.input_map(a) for a in angles], axis=0)
        return self._Phi_pow, Su, S

    def _geometry_blocks(self, model: BodyFrameModel):
        """(corridor rows G S_pos (N r, 3N), KK (15, 3N), [Phi | Bd] (6, 9), the kernel's matrices packed flat:
        [PB, KK, H^-1, G] (one argument of :func:`_qp_data` instead of four)).

        S is block lower-triangular Toeplitz: its block (j, i) is K_(j-i) = S[j-i, :, 0:3] (6 x 3). The
        rotation average of T(a + o_(j+1)) Phi^(j-i) Bd R(a + o_i) over 16 angles equals the continuous
        average (harmonics <= 2), which does not depend on the common shift o_i; checked to 1e-15
        relative in tests/test_los_mpc.py. So the per-step products with S use the N blocks
        K_d (L1-resident) instead of S itself (6N x 3N): rows 0-5 of KK are W_r K_(N-1-m)[r, c] at
        column 3m + c (weights of steps 1..N-1), rows 6-11 the same with the terminal weights, rows
        12-14 K_d[a, c] at column 3d + a (row c): the kernel's sums become contiguous sweeps."""
        N, nu = self.N, self.n_u
        A = np.matmul(self._G, self._S[:, 0:3, :]).reshape(self._n_rows * N, nu)
        K = self._S[:, :, 0:3]  # (N, 6, 3): K_d
        Wq = np.asarray(self.cfg.Q, float)
        KK = np.zeros((15, nu))
        rev = K[::-1]  # rev[m] = K_(N-1-m)
        KK[0:6] = (Wq[None, :, None] * rev).transpose(1, 0, 2).reshape(6, nu)
        KK[6:12] = (self.cfg.terminal_factor * Wq[None, :, None] * rev).transpose(1, 0, 2).reshape(6, nu)
        KK[12:15] = K[:, 0:3, :].transpose(2, 0, 1).reshape(3, nu)
        PB = np.ascontiguousarray(np.hstack([model.Phi, model.Bd]))
        return A, KK, PB, np.concatenate([PB.ravel(), KK.ravel(), self._H_inv.ravel(), self._G.ravel()])

    def _weighted_blocks(self):
        """(H (3N, 3N), H^-1 (3N, 3N), exactly symmetric) for this configuration."""
        N, nu = self.N, self.n_u
        W = np.tile(np.asarray(self.cfg.Q, float), (N, 1))
        W[-1] *= self.cfg.terminal_factor
        W = W.reshape(6 * N)
        WS = np.ascontiguousarray(W[:, None] * self._S_flat)
        D = np.eye(nu) - np.eye(nu, k=-3)
        H = self._S_flat.T @ WS + np.diag(self._r_u) + D.T @ (self._r_d[:, None] * D)
        H = 0.5 * (H + H.T)
        H_inv = np.linalg.inv(H)
        return H, np.ascontiguousarray(0.5 * (H_inv + H_inv.T))

    def exact_map(self, theta_k: float) -> np.ndarray:
        """Exact d x_j / d [x_0, U] (body frame, body-axes inputs) at angle theta_k, (N, 6, 6 + 3N)."""
        th = theta_k + self._offsets
        T = body_from_hill_matrix(th[1:], self.model.w_rel)  # (N, 6, 6)
        state_map = T @ self._Phi_pow @ hill_from_body_matrix(float(theta_k), self.model.w_rel)
        return np.concatenate([state_map, self.input_map(theta_k)], axis=2)

    def input_map(self, theta_k: float) -> np.ndarray:
        """Exact d x_j / d u_i (body frame, body-axes inputs) at angle theta_k, (N, 6, 3N)."""
        th = theta_k + self._offsets
        T = body_from_hill_matrix(th[1:], self.model.w_rel)  # (N, 6, 6)
        R = _rotations_hill_from_body(th[:-1])  # (N, 3, 3): u_L,i = R_LB(theta_i) u_B,i
        Su = np.matmul(T, self._Su_L).reshape(self.N, 6, self.N, 3)
        return np.einsum("jaib,ibc->jaic", Su, R).reshape(self.N, 6, self.n_u)

    def exact_prediction(self, t: float, x_body: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """Exact LTV prediction x_1..x_N (N, 6) of body-axes ``inputs`` (N, 3) from ``x_body``.

        Written with element-wise rotations (no batched 6x6 products) because it runs
        every step: u_L,i = R_z(theta_i) u_B,i; x_L,j = Phi^j x_L,0 + sum Phi^(j-1-i) B_d u_L,i;
        x_B,j = T(theta_j) x_L,j."""
        th = float(self.model.theta(t)) + self._offsets
        c, s, w = np.cos(th), np.sin(th), self.model.w_rel
        x_L0 = self.model.hill_from_body(t, np.asarray(x_body, float))
        u = np.asarray(inputs, float).reshape(self.N, 3)
        ci, si = c[:-1], s[:-1]
        u_L = np.column_stack([ci * u[:, 0] - si * u[:, 1], si * u[:, 0] + ci * u[:, 1], u[:, 2]])
        x = (self._Phi_pow_flat @ x_L0 + self._Su_L_flat @ u_L.reshape(-1)).reshape(self.N, 6)
        cj, sj = c[1:], s[1:]
        out = np.empty((self.N, 6))
        out[:, 0] = cj * x[:, 0] + sj * x[:, 1]
        out[:, 1] = -sj * x[:, 0] + cj * x[:, 1]
        out[:, 2] = x[:, 2]
        out[:, 3] = cj * x[:, 3] + sj * x[:, 4] + w * out[:, 1]
        out[:, 4] = -sj * x[:, 3] + cj * x[:, 4] - w * out[:, 0]
        out[:, 5] = x[:, 5]
        return out

    def _reference(self, x_ref) -> np.ndarray:
        """The (N, 6) reference trajectory: ``x_ref`` itself, or one state (6,) written into every row of
        a buffer kept per controller (the kernel reads it during the solve only)."""
        ref = np.asarray(x_ref, float)
        if ref.shape == (6,):
            buf = self._ref_buffer
            buf[:] = ref
            return buf
        if ref.shape == (self.N, 6):
            return np.ascontiguousarray(ref)
        raise input_error("x_ref.shape", ref.shape, f"must be (6,) or ({self.N}, 6)")

    # ------------------------------------------------------------------ solve
    def solve(self, t: float, x_body: np.ndarray, x_ref, u_prev: np.ndarray | None = None) -> MpcSolution:
        """Solve eq. (11) from body-frame state ``x_body`` (m, m/s) at time ``t`` (s)."""
        status, u0, theta_k, U, solve_time, build_time, iterations, slack, info = self.solve_raw(t, x_body, x_ref,
                                                                                                 u_prev)
        if U is None:
            return MpcSolution(status, u0, theta_k, None, solve_time, build_time, iterations, info=info)
        return MpcSolution(status, u0, theta_k, U.reshape(self._plan_shape), solve_time, build_time, iterations, slack,
                           info, self._basis.copy(), self._S_flat)

    def solve_raw(self, t: float, x_body: np.ndarray, x_ref, u_prev: np.ndarray | None = None) -> tuple:
        """:meth:`solve` without building the :class:`MpcSolution` (the closed loop's per-step call):
        (status, u0, theta_k, U (3N,) or None after a failed solve, solve_time_s, build_time_s, iterations,
        max_slack_m, info), i.e. MpcSolution's fields with the plan flat and no basis (it stays in a buffer
        rewritten every step)."""
        t_build = _perf_counter()
        model = self.model
        theta_k = model.theta0_rad + model.w_rel * t
        if x_body.__class__ is not np.ndarray or x_body.dtype != _F64:
            x_body = np.asarray(x_body, float)
        if u_prev is None:
            u_prev = _ZERO3
        elif u_prev.__class__ is not np.ndarray or u_prev.dtype != _F64:
            u_prev = np.asarray(u_prev, float)
        ref = (x_ref if x_ref.__class__ is np.ndarray and x_ref.shape == self._ref_shape
               else self._reference(x_ref))
        plan = self._plan
        if self._lean_step and plan is not None:  # DAQP, hard mode, one QP per step: every step but the first
            upper, lower = self._solver.bound_vectors()
            if _qp_data(theta_k, _SHIFT_PLAN, x_body, u_prev, ref, plan, *self._kernel_data, self._basis, self._work,
                        upper, lower):
                return self.solve_staged(theta_k, t_build)
            # a NaN/inf state: the general path below (the kernel runs again on the same data, then the checked update)
        if plan is None:
            self._load(theta_k, x_body, ref, u_prev, self._zeros_n, _HOLD_U_PREV)
        else:
            self._load(theta_k, x_body, ref, u_prev, plan, _SHIFT_PLAN)
        build_time = _perf_counter() - t_build
        status, x, iterations, solve_time, info = self._solve_qp()
        for _ in range(self.cfg.refinements):
            if x is None or not status.ok:
                break
            self._load(theta_k, x_body, ref, u_prev, x[: self.n_u] + self._u_c[: self.n_u], _PLAN_AS_IS)
            status, x, its, dt, info = self._solve_qp()
            solve_time += dt
            iterations += its
        return self._finish(status, x, iterations, solve_time, build_time, info, theta_k)

    def lean_inputs(self) -> tuple | None:
        """The arguments of :func:`_qp_data` after its reference (plan, constants, matrices, basis, work, DAQP's
        upper and lower bound vectors) when the next step is the staged one (DAQP, hard mode, one QP per step, after
        the first step), else None: a caller that runs the kernel itself (fused with its guidance,
        :mod:`proxops.control.los_regimes`) with g = the plan shifted, then :meth:`solve_staged`."""
        if not self._lean_step or self._plan is None:
            return None
        upper, lower = self._solver.bound_vectors()
        return self._plan, self._consts, self._mats, self._basis, self._work, upper, lower

    def solve_staged(self, theta_k: float, t_build: float) -> tuple:
        """:meth:`solve_raw`'s result once :func:`_qp_data` wrote finite bounds into DAQP's vectors (the
        staged path): DAQP re-reads them and solves; ``t_build`` (perf_counter s) the start of the data update."""
        build_time = _perf_counter() - t_build
        status, x, iterations, solve_time, info = self._solver.solve_bounds_fast()
        if status is _OPTIMAL:
            x += self._u_c  # w + x_c (DAQP's x is a fresh array)
            self._plan = x
            return status, x[:3], theta_k, x, solve_time, build_time, iterations, 0.0, {} if info is None else info
        return self._finish(status, x, iterations, solve_time, build_time, info, theta_k)

    def _finish(self, status, x, iterations: int, solve_time: float, build_time: float, info, theta_k: float) -> tuple:
        """:meth:`solve_raw`'s result from the solver's (status, x in its variables, ...): the plan U = x + x_c
        (slacks split off in soft mode), or after a failed solve the previous plan shifted."""
        if x is None or (status is not _OPTIMAL and not status.ok):
            u0 = self._shifted_plan()
            return (status, u0, theta_k, None, solve_time, build_time, iterations, 0.0,
                    {"raw_status": (info or {}).get("raw_status")})
        if self._fast:
            x += self._u_c  # w + x_c (DAQP's x is a fresh array)
        else:
            x = x + self._u_c  # another adapter's x may be its own buffer
        if self.soft:
            U = self._plan = x[: self.n_u]
            slack = float(x[self.n_u :].max())
        else:
            U = self._plan = x
            slack = 0.0
        # the plan is never modified in place (the next guess is written into a new array)
        return status, U[:3], theta_k, U, solve_time, build_time, iterations, slack, {} if info is None else info

    def _solve_qp(self) -> tuple:
        """One solve of the QP in the buffers: (status, x in the solver's variables, iterations, solve wall
        time s, info dict or None). DAQP through its lean ``solve_fast`` (no SolverResult per step)."""
        if self._staged:  # DAQP re-reads the bounds the kernel wrote into its vectors (DaqpQP.solve_bounds_fast)
            return self._solver.solve_bounds_fast()
        if self._fast:
            return self._solver.solve_fast()
        res = self._solver.solve()
        return res.status, res.x, res.iterations, res.solve_time_s, res.info

    def _load(self, theta_k: float, x_body: np.ndarray, ref: np.ndarray, u_prev: np.ndarray, plan: np.ndarray,
              how: int) -> np.ndarray:
        """Write the data of the QP in w = x - x_c (hard) or dU (soft) into the persistent buffers and hand
        them to the solver (module doc). The QP is centred on the plan guess g: ``u_prev`` held
        (``how`` = 0), ``plan`` (3N,) shifted by one step (1), or ``plan`` itself (2). Returns the new
        buffer [g (3N), p_g (6N)], p_g the exact prediction of g (body frame, m, m/s). DAQP in hard mode
        (``_lean``): the kernel writes the bounds into the vectors DAQP reads and :meth:`_solve_qp` has DAQP
        re-read them (``_staged``)."""
        basis = self._basis
        solver = self._solver
        if self._lean:  # DAQP in hard mode: only the bounds change, written where DAQP reads them
            upper, lower = solver.bound_vectors()
            if _qp_data(theta_k, how, x_body, u_prev, ref, plan, *self._kernel_data, basis, self._work, upper, lower):
                self._staged = True
                return basis
            nv = self.n_var  # a NaN/inf state: the checked path turns it into a NUMERICAL_ERROR status
            self._staged = False
            solver.update(bu=upper[nv:].copy(), lb=lower[:nv].copy(), ub=upper[:nv].copy())
            return basis
        finite = _qp_data(theta_k, how, x_body, u_prev, ref, plan, *self._kernel_data, basis, self._work,
                          self._upper, self._lower)
        f = None if self._shift else self._f
        if solver is None:
            self._make_solver(f)
        elif finite and self._fast:  # DAQP, finite data: rows stay inequalities, no bound crossed
            solver.update_fast(f=f, bu=self._b, lb=self._lb_w, ub=self._ub_w)
        else:  # other solvers, or a NaN/inf state (the checked path turns it into a NUMERICAL_ERROR status)
            if not self._fast and self.soft:
                self._ub_w[self.n_u :] = np.inf  # the slacks' missing upper bound (DAQP's is 1e30)
            # copies: an adapter may keep what it is given (the buffers are rewritten next step)
            data = {"bu": self._b.copy(), "lb": self._lb_w.copy(), "ub": self._ub_w.copy()}
            if f is not None:
                data["q" if self._form else "f"] = f.copy()
            solver.update(**data)
        return basis

    def _make_solver(self, f: np.ndarray | None) -> None:
        """The QP solver named by ``config.solver`` (proxops.solvers.make_solver) for the problem in the
        buffers. DAQP in hard mode is set up without a linear term (``setup_native`` with f = None: it keeps
        no v, so a bound update costs O(m); module doc) and its bounds written into its own vectors (``_lean``:
        ``DaqpQP.bound_vectors``, ``solve_bounds_fast``); soft mode on DAQP through ``update_fast``; every other
        case is the :class:`QuadraticProgram` form, updated by its field names (bu, lb, ub, and q in soft mode)."""
        name = self.cfg.solver
        settings = dict(self.cfg.solver_settings)
        if name == "daqp":
            settings.setdefault("max_iter", self.cfg.max_iter)
        ub = self._ub_w.copy()
        if name != "daqp":
            ub[self.n_u :] = np.inf
        form = QuadraticProgram(P=self._H, q=np.zeros(self.n_var) if f is None else f.copy(), A=self._A,
                                bu=self._b.copy(), lb=self._lb_w.copy(), ub=ub)
        if name == "daqp" and f is None:
            solver = make_solver("QP", "daqp", **settings)
            solver.setup_native(form.P, None, form.A, bu=form.bu, lb=form.lb, ub=form.ub)
            self._form = False
        else:
            solver = make_solver(form, name, **settings)
            self._form = True
        self._fast = name == "daqp"
        self._lean = self._fast and f is None  # bounds-only updates (hard mode)
        self._lean_step = self._lean and self.cfg.refinements == 0
        self._solver = solver

    def _shifted_plan(self) -> np.ndarray:
        """Fallback input after a failed solve: the previous plan shifted by one step, else zero."""
        if self._plan is None or self.N < 2:
            self._plan = None
            return np.zeros(3)
        plan = np.zeros(self.n_u)
        plan[:-3] = self._plan[3:]  # shifted, zero last input
        self._plan = plan
        return np.clip(plan[:3], -self.a_max, self.a_max)

    def reset(self) -> None:
        """Forget the warm start and the stored plan."""
        self._solver = None
        self._lean = self._lean_step = self._staged = False
        self._plan = None


_ZERO3 = np.zeros(3)
_F64 = np.dtype(np.float64)
_perf_counter = time.perf_counter
_HOLD_U_PREV, _SHIFT_PLAN, _PLAN_AS_IS = 0, 1, 2  # how the kernel forms the plan guess g
_OPTIMAL = Status.OPTIMAL


@njit(cache=True)
def _qp_data(theta_k, how, x_body, u_prev, plan_ref, plan, consts, mats, basis, work, upper,
             lower):  # pragma: no cover
    """Per-step data of the QP (module doc), written into ``basis`` and ``work``: in w = U - U_c
    without a linear term (hard mode) or in dU = U - g with the linear term f (soft mode). Returns
    True when every output is finite.

    theta_k (rad); how: plan guess g = u_prev held (0), ``plan`` shifted by one step (1), ``plan``
    itself (2); x_body (6,) body-frame state (m, m/s); u_prev (3,) previous input (body axes, m/s^2);
    plan_ref (N, 6) reference states; plan (3N,) body-axes inputs (m/s^2);
    consts = [w_rel (rad/s), a_max (m/s^2), shift (1/0), rho, n_var, N, r, cos o_j, sin o_j (N+1 each),
    diag R_u (3N), diag R_du (3N), h (r)]; mats = [PB, KK, H_inv, G] flat: PB = [Phi | B_d] (6, 9) CW ZOH
    step; KK (15, 3N) the Toeplitz blocks K_d of S (LosMpc._geometry_blocks); H_inv (3N, 3N) symmetric;
    G (r, 3) corridor rows.
    basis = [g (3N), p_g (6N)]; work = [f (n_var; [:3N] the linear term in dU), x_c (n_var; [:3N] = U_c
    (shift) or g), scratch (12 + 3N)]; upper = [ub_w (n_var; [:3N] = a_max - x_c), b (N r) = h - G (p_g + S (x_c - g))_pos] and
    lower[:n_var] = lb_w ([:3N] = -a_max - x_c): DAQP's full bound vectors (lower's row part is not written).
    Every sum runs over the nonzero blocks of S only (x_j+1 depends on u_0..u_j) as contiguous sweeps
    that vectorise (one sweep per block row/column); the O(N^2) part reads H^-1 and O(N) data."""
    w_rel = consts[0]
    a_max = consts[1]
    shift = consts[2] != 0.0
    rho = consts[3]
    n_var = int(consts[4])
    N = int(consts[5])
    n_rows = int(consts[6])
    n3 = 3 * N
    PB = mats[0:54].reshape((6, 9))
    KK = mats[54 : 54 + 15 * n3].reshape((15, n3))
    H_inv = mats[54 + 15 * n3 : 54 + 15 * n3 + n3 * n3].reshape((n3, n3))
    G = mats[54 + 15 * n3 + n3 * n3 :].reshape((n_rows, 3))
    c0 = 7
    cos_o = consts[c0 : c0 + N + 1]
    sin_o = consts[c0 + N + 1 : c0 + 2 * N + 2]
    r_u = consts[c0 + 2 * N + 2 : c0 + 2 * N + 2 + n3]
    r_d = consts[c0 + 2 * N + 2 + n3 : c0 + 2 * N + 2 + 2 * n3]
    h = consts[c0 + 2 * N + 2 + 2 * n3 :]
    guess = basis[0:n3]
    pred = basis[n3 : n3 + 6 * N]
    f = work[0:n_var]
    x_c = work[n_var : 2 * n_var]
    lb_w = lower[0:n_var]
    ub_w = upper[0:n_var]
    b = upper[n_var:]
    # 0. the plan guess g
    if how == 0:
        for j in range(N):
            guess[3 * j] = u_prev[0]
            guess[3 * j + 1] = u_prev[1]
            guess[3 * j + 2] = u_prev[2]
    elif how == 1:
        for i in range(n3 - 3):
            guess[i] = plan[i + 3]
        for i in range(n3 - 3, n3):
            guess[i] = plan[i]
    else:
        for i in range(n3):
            guess[i] = plan[i]
    # 1. p_g: exact LTV prediction of the plan (LVLH recursion, rotated to the body frame)
    ck = math.cos(theta_k)
    sk = math.sin(theta_k)
    c, s = ck, sk
    v0 = x_body[3] - w_rel * x_body[1]
    v1 = x_body[4] + w_rel * x_body[0]
    xl = work[2 * n_var : 2 * n_var + 6]  # scratch (no allocation per step)
    xn = work[2 * n_var + 6 : 2 * n_var + 12]
    xl[0] = c * x_body[0] - s * x_body[1]
    xl[1] = s * x_body[0] + c * x_body[1]
    xl[2] = x_body[2]
    xl[3] = c * v0 - s * v1
    xl[4] = s * v0 + c * v1
    xl[5] = x_body[5]
    for j in range(N):
        g0, g1, g2 = guess[3 * j], guess[3 * j + 1], guess[3 * j + 2]
        ul0 = c * g0 - s * g1  # u_L,j = R_LB(theta_j) g_j
        ul1 = s * g0 + c * g1
        for r in range(6):
            acc = PB[r, 6] * ul0 + PB[r, 7] * ul1 + PB[r, 8] * g2
            for q in range(6):
                acc += PB[r, q] * xl[q]
            xn[r] = acc
        for r in range(6):
            xl[r] = xn[r]
        c = ck * cos_o[j + 1] - sk * sin_o[j + 1]  # cos, sin of theta_k + o_j+1 (angle addition)
        s = sk * cos_o[j + 1] + ck * sin_o[j + 1]
        rb0 = c * xl[0] + s * xl[1]
        rb1 = -s * xl[0] + c * xl[1]
        k = 6 * j
        pred[k] = rb0
        pred[k + 1] = rb1
        pred[k + 2] = xl[2]
        pred[k + 3] = c * xl[3] + s * xl[4] + w_rel * rb1
        pred[k + 4] = -s * xl[3] + c * xl[4] - w_rel * rb0
        pred[k + 5] = xl[5]
    # 2. f = S'W (p_g - ref) + (R_u + D'R_du D) g - [R_du u_prev; 0]; block (j, i) of W S is
    #    W_j K_(j-i) = KK[r (+6 at j = N-1), 3(N-1-j) + 3i + c]
    for i in range(n3):
        f[i] = 0.0
    for j in range(N):  # one sweep per step j over its 6 rows
        off = 3 * (N - 1 - j)
        kr = 6 if j == N - 1 else 0
        d0 = pred[6 * j] - plan_ref[j, 0]
        d1 = pred[6 * j + 1] - plan_ref[j, 1]
        d2 = pred[6 * j + 2] - plan_ref[j, 2]
        d3 = pred[6 * j + 3] - plan_ref[j, 3]
        d4 = pred[6 * j + 4] - plan_ref[j, 4]
        d5 = pred[6 * j + 5] - plan_ref[j, 5]
        k0, k1, k2 = KK[kr, off:], KK[kr + 1, off:], KK[kr + 2, off:]
        k3, k4, k5 = KK[kr + 3, off:], KK[kr + 4, off:], KK[kr + 5, off:]
        for i in range(3 * (j + 1)):
            f[i] += k0[i] * d0 + k1[i] * d1 + k2[i] * d2 + k3[i] * d3 + k4[i] * d4 + k5[i] * d5
    for i in range(n3):
        dg = guess[i] - guess[i - 3] if i >= 3 else guess[i]
        e = r_d[i] * dg
        if i + 3 < n3:
            e -= r_d[i + 3] * (guess[i + 3] - guess[i])
        f[i] += r_u[i] * guess[i] + e
    for i in range(3):
        f[i] -= r_d[i] * u_prev[i]
    # 3. U_c - g = -H^-1 f (shift), else 0
    for i in range(n3):
        x_c[i] = 0.0
    if shift:  # one sweep per 3 rows of H^-1 (symmetric: rows = columns)
        for j in range(0, n3, 3):
            f0, f1, f2 = f[j], f[j + 1], f[j + 2]
            h0, h1, h2 = H_inv[j], H_inv[j + 1], H_inv[j + 2]
            for i in range(n3):
                x_c[i] -= h0[i] * f0 + h1[i] * f1 + h2[i] * f2
    # 4. positions of p_g + S (U_c - g): column sweeps, S_pos[3j + a, 3i + c] = K_(j-i)[a, c] = KK[12 + c, 3(j-i) + a]
    xp = work[2 * n_var + 12 : 2 * n_var + 12 + n3]
    for j in range(N):
        xp[3 * j] = pred[6 * j]
        xp[3 * j + 1] = pred[6 * j + 1]
        xp[3 * j + 2] = pred[6 * j + 2]
    k0, k1, k2 = KK[12], KK[13], KK[14]
    for i in range(N):  # one sweep per input step i over its 3 columns
        base = 3 * i
        d0, d1, d2 = x_c[base], x_c[base + 1], x_c[base + 2]
        for q in range(n3 - base):
            xp[base + q] += k0[q] * d0 + k1[q] * d1 + k2[q] * d2
    # 5. corridor rows and input bounds in w
    for j in range(N):
        p0, p1, p2 = xp[3 * j], xp[3 * j + 1], xp[3 * j + 2]
        for q in range(n_rows):
            b[j * n_rows + q] = h[q] - (G[q, 0] * p0 + G[q, 1] * p1 + G[q, 2] * p2)
    total = 0.0
    for i in range(n3):
        x_c[i] += guess[i]
        lb_w[i] = -a_max - x_c[i]
        ub_w[i] = a_max - x_c[i]
        total += ub_w[i] + f[i]
    for i in range(n3, n_var):  # soft mode: the slacks s >= 0, cost rho s + w/2 s^2
        f[i] = rho
        x_c[i] = 0.0
        lb_w[i] = 0.0
        ub_w[i] = DAQP_INF
    for i in range(b.shape[0]):
        total += b[i]
    return math.isfinite(total)
