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
here (``MpcSolution.u0_hill``) and in :mod:`proxops.guidance.los_regimes`. So the box
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
(O(m n), ~40 us at N = 40). One jitted kernel (:func:`_shifted_qp_data`) computes p_g, f,
U_c and the bounds using the lower block-triangular structure of S; U = w + U_c. Soft mode
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

Solved by DAQP through :class:`proxops.solvers.daqp_qp.DaqpQP`, warm-started from the
previous active set.
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
from proxops.solvers.daqp_qp import DaqpQP
from proxops.status import Status

PAPER_Q = (15.0, 30.0, 15.0, 1.0, 1.0, 1.0)
_PREDICTION_CACHE: dict = {}  # (n, w_rel, dt, N) -> prediction blocks (Monte Carlo reuses them)
_WEIGHTS_CACHE: dict = {}  # (prediction key, weights) -> (W S, H, H^-1)
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


@dataclass
class MpcSolution:
    """Result of one MPC solve. ``u0`` is the body-axes input to apply (m/s^2) and
    ``u0_hill`` the same vector in LVLH components (what the plant receives; computed when asked
    from ``theta_rad`` = theta_k, the body angle at the solve)."""

    status: Status  # the solver status (proxops.status)
    u0: np.ndarray
    theta_rad: float
    inputs: np.ndarray | None  # (N, 3) planned body-axes inputs (m/s^2; the MPC's own plan: do not modify)
    prediction: tuple | None  # (p_g (6N,), S (6N, 3N), dU (3N,)): predicted states p_g + S dU, or None
    solve_time_s: float  # DAQP solve call
    build_time_s: float  # condensing + update
    iterations: int
    max_slack_m: float = 0.0  # soft mode: largest corridor slack used
    info: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status.ok

    @property
    def u0_hill(self) -> np.ndarray:
        """u0 in LVLH components: R_LB(theta_k) u0 (m/s^2)."""
        return rotate_z(self.theta_rad, self.u0)

    @property
    def states(self) -> np.ndarray | None:
        """(N, 6) predicted body-frame states x_1..x_N = p_g + S dU (p_g: exact prediction of the
        plan the QP was centred on, dU: the change of plan; computed when asked: the closed loop
        does not use them)."""
        if self.prediction is None:
            return None
        base, S, dU = self.prediction
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
        self._WS, H, self._H_inv = memo_get(_WEIGHTS_CACHE, (key, weights), self._weighted_blocks)
        self._r_d0 = np.asarray(self.cfg.R_du, float)
        G, self._h = corridor.G, corridor.h
        self._G_T = np.ascontiguousarray(G.T)
        self._G = np.ascontiguousarray(G, dtype=float)
        self._n_rows = G.shape[0]
        # per-geometry arrays, shared by every run of a campaign (read only)
        self._S_posT, A, self._HS, self._PB = memo_get(
            _WEIGHTS_CACHE, (key, weights, self._G.tobytes(), np.asarray(self._h, float).tobytes()),
            lambda: self._geometry_blocks(model))
        lb = np.full(self.n_var, -self.a_max)
        ub = np.full(self.n_var, self.a_max)
        # hard mode: DAQP gets the QP in w = U - U_c without a linear term (module doc); soft mode
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
        self._solver: DaqpQP | None = None
        self._plan: np.ndarray | None = None  # (N, 3) last planned body-axes inputs
        # per-step buffers written by the kernel (DaqpQP copies the bounds into its own vectors)
        # the kernel's arguments, packed (a jitted call costs ~0.3 us per argument):
        # inputs [x_0 (6), u_prev (3), g (3N), ref (6N)], constants [o_j = theta_j - theta_k, cos o_j,
        # sin o_j (N+1 each), R_u (3N), R_du (3N), h (r)], [Phi | Bd] (6, 9), [H^-1; S_pos^T] (2, 3N, 3N), outputs
        # [p_g (6N), f, x_c, lb - x_c, ub - x_c (n_var each), rows (N r)]
        nv, n6, nb = self.n_var, 6 * N, self._n_rows * N
        self._inp = np.zeros(9 + nu + n6)
        self._guess = self._inp[9 : 9 + nu]
        self._consts = np.concatenate([self._offsets, np.cos(self._offsets), np.sin(self._offsets), self._r_u,
                                       self._r_d, np.asarray(self._h, float)])
        self._work = np.empty(n6 + 4 * nv + nb)
        self._pred = self._work[:n6]  # p_g
        self._f = self._work[n6 : n6 + nv]  # linear term in dU (soft mode: DAQP's f)
        self._u_c = self._work[n6 + nv : n6 + 2 * nv]  # x = DAQP's solution + this (U_c or g; slack: 0)
        self._lb_w = self._work[n6 + 2 * nv : n6 + 3 * nv]
        self._ub_w = self._work[n6 + 3 * nv : n6 + 4 * nv]
        self._b = self._work[n6 + 4 * nv :]
        if self.soft:
            self._f[nu:] = self.cfg.slack_penalty
            self._u_c[nu:] = 0.0
            self._lb_w[nu:] = 0.0
            self._ub_w[nu:] = DAQP_INF

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
        """(S_pos^T (3N, 3N), corridor rows G S_pos (N r, 3N), [H^-1; S_pos^T] (2, 3N, 3N), [Phi | Bd] (6, 9))."""
        N, nu = self.N, self.n_u
        S_posT = np.ascontiguousarray(self._S[:, 0:3, :].reshape(3 * N, nu).T)
        A = np.matmul(self._G, self._S[:, 0:3, :]).reshape(self._n_rows * N, nu)
        HS = np.ascontiguousarray(np.stack([self._H_inv, S_posT]))
        PB = np.ascontiguousarray(np.hstack([model.Phi, model.Bd]))
        return S_posT, A, HS, PB

    def _weighted_blocks(self):
        """(W S (6N, 3N), H (3N, 3N), H^-1 (3N, 3N), exactly symmetric) for this configuration."""
        N, nu = self.N, self.n_u
        W = np.tile(np.asarray(self.cfg.Q, float), (N, 1))
        W[-1] *= self.cfg.terminal_factor
        W = W.reshape(6 * N)
        WS = np.ascontiguousarray(W[:, None] * self._S_flat)
        D = np.eye(nu) - np.eye(nu, k=-3)
        H = self._S_flat.T @ WS + np.diag(self._r_u) + D.T @ (self._r_d[:, None] * D)
        H = 0.5 * (H + H.T)
        H_inv = np.linalg.inv(H)
        return WS, H, np.ascontiguousarray(0.5 * (H_inv + H_inv.T))

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
        ref = np.asarray(x_ref, float)
        if ref.shape == (6,):
            return np.tile(ref, (self.N, 1))
        if ref.shape == (self.N, 6):
            return ref
        raise input_error("x_ref.shape", ref.shape, f"must be (6,) or ({self.N}, 6)")

    # ------------------------------------------------------------------ solve
    def solve(self, t: float, x_body: np.ndarray, x_ref, u_prev: np.ndarray | None = None) -> MpcSolution:
        """Solve eq. (11) from body-frame state ``x_body`` (m, m/s) at time ``t`` (s)."""
        t_build = time.perf_counter()
        N, nu = self.N, self.n_u
        x_body = np.asarray(x_body, float)
        u_prev = _ZERO3 if u_prev is None else np.asarray(u_prev, float)
        ref = (x_ref if x_ref.__class__ is np.ndarray and x_ref.shape == self._ref_shape
               else self._reference(x_ref)).reshape(6 * N)
        guess = self._guess
        if self._plan is None:
            guess.reshape(N, 3)[:] = u_prev
        else:
            guess[: nu - 3] = self._plan.reshape(nu)[3:]
            guess[nu - 3 :] = self._plan[-1]
        self._load(t, x_body, guess, ref, u_prev)
        build_time = time.perf_counter() - t_build
        res = self._solver.solve()
        solve_time, iterations = res.solve_time_s, res.iterations
        for _ in range(self.cfg.refinements):
            if res.x is None or not res.ok:
                break
            np.add(res.x[:nu], self._u_c[:nu], out=guess)
            self._load(t, x_body, guess, ref, u_prev)
            res = self._solver.solve()
            solve_time += res.solve_time_s
            iterations += res.iterations
        status = res.status
        theta_k = self.model.theta0_rad + self.model.w_rel * t
        if res.x is None or not res.ok:
            u0 = self._shifted_plan()
            return MpcSolution(status, u0, theta_k, None, None, solve_time, build_time,
                               iterations, info={"raw_status": res.info.get("raw_status")})
        x = res.x  # DAQP's w, a fresh array
        x += self._u_c  # w + x_c
        U = x[:nu]
        plan = self._plan = U.reshape(N, 3)  # never modified in place (the next guess is a copy)
        u0 = U[:3].copy()
        slack = float(x[nu:].max()) if self.soft else 0.0
        return MpcSolution(status, u0, theta_k, plan, (self._pred.copy(), self._S_flat,
                           U - guess), solve_time, build_time, iterations, max_slack_m=slack,
                           info={"raw_status": res.info.get("raw_status"), "dual": res.info.get("dual")})

    def _load(self, t: float, x_body: np.ndarray, guess: np.ndarray, ref: np.ndarray, u_prev: np.ndarray) -> np.ndarray:
        """Put the bounds of the QP in w = x - x_c, centred on the plan ``guess`` (3N,), into DAQP
        (module doc); returns p_g (6N,), the exact prediction of ``guess``."""
        theta_k = self.model.theta0_rad + self.model.w_rel * t
        nu = self.n_u
        inp = self._inp
        inp[:6] = x_body
        inp[6:9] = u_prev
        if guess is not self._guess:
            self._guess[:] = guess
        inp[9 + nu :] = ref
        finite = _shifted_qp_data(theta_k, self.model.w_rel, self.a_max, self._shift, self.n_var, inp, self._consts,
                                  self._PB, self._WS, self._HS, self._G, self._work)
        f = None if self._shift else self._f
        if self._solver is None:
            self._solver = DaqpQP(max_iter=self.cfg.max_iter)
            self._solver.setup_native(self._H, None if f is None else f.copy(), self._A, bu=self._b.copy(),
                                      lb=self._lb_w.copy(), ub=self._ub_w.copy())
        elif finite:  # finite data: rows stay inequalities, no bound crossed
            self._solver.update_fast(f=f, bu=self._b, lb=self._lb_w, ub=self._ub_w)
        else:  # NaN/inf state: the checked path turns it into a NUMERICAL_ERROR status
            self._solver.update(f=f, bu=self._b, lb=self._lb_w, ub=self._ub_w)
        return self._pred

    def _shifted_plan(self) -> np.ndarray:
        """Fallback input after a failed solve: the previous plan shifted by one step, else zero."""
        if self._plan is None or len(self._plan) < 2:
            self._plan = None
            return np.zeros(3)
        self._plan = self._plan[1:]
        if len(self._plan) < self.N:
            self._plan = np.vstack([self._plan, np.zeros((self.N - len(self._plan), 3))])
        return np.clip(self._plan[0], -self.a_max, self.a_max)

    def reset(self) -> None:
        """Forget the warm start and the stored plan."""
        self._solver = None
        self._plan = None


_ZERO3 = np.zeros(3)


@njit(cache=True)
def _shifted_qp_data(theta_k, w_rel, a_max, shift, n_var, inp, consts, PB, WS, HS, G, work):  # pragma: no cover
    """Per-step data of the QP (module doc), written into ``work``: in w = U - U_c without a
    linear term (``shift`` True) or in dU = U - g with the linear term f (False). Returns True
    when every output is finite.

    theta_k (rad), w_rel (rad/s), a_max (m/s^2); inp = [x_0 (6), u_prev (3), plan g (3N,
    body-axes m/s^2), ref (6N)]; consts = [o_j = theta_j - theta_k, cos o_j, sin o_j (N+1 each),
    diag R_u (3N), diag R_du (3N), h (r)]; PB = [Phi | B_d] (6, 9) CW ZOH step; WS = W S (6N, 3N); HS = [H^-1 (symmetric);
    S_pos^T] (2, 3N, 3N), S_pos the position rows of S; G (r, 3) corridor rows.
    work = [p_g (6N), f (n_var; [:3N] written: the linear term in dU), x_c (n_var; [:3N] = U_c
    (shift) or g), lb_w, ub_w (n_var; [:3N] = -+a_max - x_c), b (N r) = h - G (p_g + S (x_c - g))_pos].
    Loops run over the nonzero blocks of S only (x_j+1 depends on u_0..u_j) and are written as
    column sweeps (axpy) so that they vectorise without reordering any sum."""
    n3 = WS.shape[1]
    N = n3 // 3
    n_rows = G.shape[0]
    x_body = inp[0:6]
    u_prev = inp[6:9]
    guess = inp[9 : 9 + n3]
    ref = inp[9 + n3 :]
    cos_o = consts[N + 1 : 2 * N + 2]
    sin_o = consts[2 * N + 2 : 3 * N + 3]
    r_u = consts[3 * N + 3 : 3 * N + 3 + n3]
    r_d = consts[3 * N + 3 + n3 : 3 * N + 3 + 2 * n3]
    h = consts[3 * N + 3 + 2 * n3 :]
    H_inv = HS[0]
    S_posT = HS[1]
    n6 = 6 * N
    pred = work[0:n6]
    f = work[n6 : n6 + n_var]
    x_c = work[n6 + n_var : n6 + 2 * n_var]
    lb_w = work[n6 + 2 * n_var : n6 + 3 * n_var]
    ub_w = work[n6 + 3 * n_var : n6 + 4 * n_var]
    b = work[n6 + 4 * n_var :]
    # 1. p_g: exact LTV prediction of the plan (LVLH recursion, rotated to the body frame)
    ck = math.cos(theta_k)
    sk = math.sin(theta_k)
    c, s = ck, sk
    v0 = x_body[3] - w_rel * x_body[1]
    v1 = x_body[4] + w_rel * x_body[0]
    xl = np.empty(6)
    xn = np.empty(6)
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
    # 2. f = S'W (p_g - ref) + (R_u + D'R_du D) g - [R_du u_prev; 0]
    for i in range(n3):
        f[i] = 0.0
    for row in range(6 * N):
        d = pred[row] - ref[row]
        lim = 3 * (row // 6 + 1)
        for i in range(lim):
            f[i] += WS[row, i] * d
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
    if shift:
        for j in range(n3):
            fj = f[j]
            for i in range(n3):
                x_c[i] -= H_inv[j, i] * fj
    # 4. positions of p_g + S (U_c - g): column sweeps over the lower block triangle
    xp = np.empty(n3)
    for j in range(N):
        xp[3 * j] = pred[6 * j]
        xp[3 * j + 1] = pred[6 * j + 1]
        xp[3 * j + 2] = pred[6 * j + 2]
    for i in range(n3):
        di = x_c[i]
        for r in range(3 * (i // 3), n3):
            xp[r] += S_posT[i, r] * di
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
    for i in range(b.shape[0]):
        total += b[i]
    return math.isfinite(total)
