"""Nonlinear MPC for the planar underactuated CubeSat (Aborizk et al. §3-§5).

Two variants (CasADi ``nlpsol``, multiple shooting, RK4 of the shared model in
:mod:`proxops.dynamics.planar_cubesat`):

- ``"general"`` (eq. 9): J_H = sum_{k<H} l(s_k, u_k) + F(s_H) with the terminal
  constraint s_H = 0 and terminal cost F(s) = s' P s, P = ``terminal_weight`` * Q.
  Deviation (documented): by default s_H = 0 is enforced as the small box
  |s_H| <= ``terminal_box_fraction`` (0.1) x the docking tolerances of Table 1. The exact
  equality makes the NLP degenerate once the plan reaches the origin: there the
  linearisation is not controllable (f_x = 0 gives no authority along y, the lack of
  controllability the paper cites), so the terminal rows lose rank (LICQ fails). Measured
  from the case-1 start: with the equality, H = 60 gave 3 warm-solver failures and 2 steps
  without any solution, H = 80 gave 5 and 0; with the box, 1 and 0, 0 and 0.
  ``terminal_box_fraction = 0`` restores the equality.
- ``"averaged"`` (eq. 14): no terminal cost or constraint, plus J_H <= Vbar where Vbar is
  the mean of the last N optimal values V_H, refreshed every N steps (no bound during the
  first N steps).

  The objective of this variant *is* J_H, so the bound cannot move a minimiser: either
  the minimiser satisfies it or no point near it does; the bound only rejects local
  minima above Vbar. It is therefore applied in two stages: the plain NLP (no terminal
  ingredients) is solved; only if its value exceeds Vbar is the bounded NLP solved, with
  the state augmented by the accumulated cost c (c_0 = 0, c_{k+1} = c_k + l) and a slack
  (c_H <= Vbar + sigma, sigma >= 0, penalty ``slack_weight`` * sigma, so it is never
  infeasible). A step whose final value still exceeds Vbar is reported
  ``bound_relaxed`` (the value was not bounded by its average there). Measured: carrying
  c and sigma in every solve took ~1.7x the time per step (8.0 vs 4.6 ms CPU, case-1
  start, H = 30) for the same trajectory.

Stage cost l(s, u) = s' Q s + u' R u (§4.2) with s in SI units (angles in rad).

NLP layout (stage-wise, so fatrop's structure detection applies): decision variables
``[z_0, u_0, ..., z_{H-1}, u_{H-1}, z_H]``; rows per stage: the gap
z_{k+1} = F_d(z_k, u_k), at k = 0 the initial condition, the angular-acceleration path
constraint, at the last stage the terminal rows. Variables and rows are scaled to O(1).

Warm start: the previous solution shifted by one stage (primal variables and multipliers,
the tail repeats the last control). IPOPT takes the multipliers
(``warm_start_init_point``); the CasADi fatrop plugin takes only the primal guess (it
builds a new fatrop solver per call and ignores ``lam_x0``/``lam_g0``), so multipliers are
shifted only when the warm solver is IPOPT. The first solve and every failure of the warm
solver go to IPOPT from its default initialisation ("cold"). Every returned point is
checked for feasibility (bounds, gaps, path and terminal rows), not only the solver status.

Evaluation cost: every CasADi Function called per step (solvers, constraint check, value)
runs on preallocated numpy buffers (``Function.buffer``); converting an 800-element numpy
vector to a DM and back costs ~0.1 ms each way, which with the default call added 1-3 ms
per step at H = 100. What remains is fatrop itself (H = 100, 5 iterations: function
evaluations ~40 %, Riccati ~35 %, rest of the iteration and initialisation ~25 %).
Measured and not adopted: the NLP in MX without ``expand`` (2.4x slower per solve), CasADi
``jit`` of the expanded NLP (evaluations 3-4x faster, but gcc -O1 takes 12 s at H = 30 and
35 s at H = 100), fatrop linear-solver and barrier options (same iterates or more
iterations), ``tol`` 1e-5 (5-10 % fewer iterations, plans differ by up to 2.5 % of scale).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from proxops.dynamics.planar_cubesat import (
    N_CONTROL,
    N_STATE,
    DockingSet,
    PlanarCubeSatParams,
    PlanarLimits,
    rk4_step,
    wrap_angle,
)
from proxops.errors import input_error
from proxops.contracts import Command
from proxops.solvers.casadi_nlp import Buffered as _Buffered
from proxops.solvers.casadi_nlp import CasadiNLP, NonlinearProgram
from proxops.status import Status

VARIANTS = ("general", "averaged")
# Warm solver: fatrop (structure-exploiting, ships with CasADi) measured ~3x faster than
# warm-started IPOPT here (case-1 start, averaged H = 30: median 4.9 vs 14.5 ms per step,
# same trajectory); IPOPT stays as the cold start and the fallback.
SOLVERS = ("fatrop", "ipopt")

# Options of the warm-started solves. fatrop: small barrier and bound push (measured:
# general H = 100 from 18-28 to 3-5 iterations per step; averaged unchanged, ~12).
WARM_FATROP = {"mu_init": 1e-5, "bound_push": 1e-8, "bound_frac": 1e-8}
WARM_IPOPT = {
    "warm_start_init_point": "yes",
    "mu_init": 1e-4,
    "warm_start_bound_push": 1e-9,
    "warm_start_mult_bound_push": 1e-9,
    "warm_start_slack_bound_push": 1e-9,
}

# Default weights (SI, angles in rad), chosen by us: the paper gives no Q, R.
DEFAULT_Q = (1.0, 1.0, 10.0, 10.0, 10.0, 1000.0)
DEFAULT_R = (1.0e-2, 1.0e-6)


@dataclass
class NMPCConfig:
    """Tuning of :class:`UnderactuatedNMPC` (SI units).

    ``horizon`` H (steps of ``dt_s``), ``average_window`` N of eq. 14, weights ``q_diag``
    (6, for [x, y, theta, vx, vy, omega]) and ``r_diag`` (2, for [thrust, wheel_acc]),
    terminal weight P = ``terminal_weight`` * Q and terminal box (general variant), RK4
    sub-steps per interval of the prediction model, warm solver ``"fatrop"`` or ``"ipopt"``.
    """

    variant: str = "averaged"
    horizon: int = 30
    dt_s: float = 2.0
    average_window: int = 10
    q_diag: tuple = DEFAULT_Q
    r_diag: tuple = DEFAULT_R
    terminal_weight: float = 10.0
    terminal_box_fraction: float = 0.1  # general: |s_H| <= f * docking set; 0 -> s_H = 0 (eq. 9)
    slack_weight: float = 1.0  # eq. 14 slack penalty (any > 0 gives the same minimiser)
    model_substeps: int = 1
    solver: str = "fatrop"
    max_iter: int = 200
    tol: float = 1e-6
    position_scale_m: float = 10.0  # NLP scaling of x, y (conditioning only)
    stop_when_docked: bool = False
    solver_options: dict = field(default_factory=dict)  # extra plugin options {"fatrop": {...}, "ipopt": {...}}

    def __post_init__(self):
        if self.variant not in VARIANTS:
            raise input_error("controller.variant", self.variant, f"allowed: {', '.join(VARIANTS)}")
        if self.solver not in SOLVERS:
            raise input_error("controller.solver", self.solver, f"allowed: {', '.join(SOLVERS)}")
        _check_int("controller.horizon", self.horizon, 1, "steps")
        _check_int("controller.average_window", self.average_window, 1, "steps")
        _check_int("controller.model_substeps", self.model_substeps, 1, "")
        _check_int("controller.max_iter", self.max_iter, 1, "")
        for name, unit in (("dt_s", "s"), ("tol", ""), ("position_scale_m", "m"), ("slack_weight", "")):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise input_error(f"controller.{name}", value, "must be a finite number > 0", unit)
        if len(self.q_diag) != N_STATE or any(not (math.isfinite(q) and q >= 0) for q in self.q_diag):
            raise input_error("controller.q_diag", list(self.q_diag), "must be 6 finite numbers >= 0")
        if len(self.r_diag) != N_CONTROL or any(not (math.isfinite(r) and r > 0) for r in self.r_diag):
            raise input_error("controller.r_diag", list(self.r_diag), "must be 2 finite numbers > 0")
        if not (math.isfinite(self.terminal_weight) and self.terminal_weight >= 0):
            raise input_error("controller.terminal_weight", self.terminal_weight, "must be a finite number >= 0")
        if not (math.isfinite(self.terminal_box_fraction) and 0.0 <= self.terminal_box_fraction <= 1.0):
            raise input_error("controller.terminal_box_fraction", self.terminal_box_fraction, "must be within [0, 1]")


def _check_int(name: str, value, minimum: int, unit: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise input_error(name, value, f"must be an integer >= {minimum}", unit)


class _Nlp:
    """One stage-wise NLP with its solvers: ``terminal`` is "none" (plain averaged),
    "origin" (general, eq. 9) or "value-bound" (averaged with c, sigma, eq. 14)."""

    def __init__(self, ctrl: "UnderactuatedNMPC", terminal: str):
        import casadi as ca

        cfg, p, lim = ctrl.config, ctrl.params, ctrl.limits
        H, nx, nu = cfg.horizon, N_STATE, N_CONTROL
        self.horizon, self.terminal = H, terminal
        self.solver_time_s = 0.0  # accumulated wall time inside the NLP solvers
        self.augmented = terminal == "value-bound"
        nz = nx + 2 if self.augmented else nx  # [s; c; sigma]
        self.nz, self.nu, self.block = nz, nu, nz + nu
        self.n_w = H * self.block + nz

        # Discrete model (RK4 of the shared right-hand side) and stage cost.
        zs, us = ca.SX.sym("z", nz), ca.SX.sym("u", nu)
        s_next = rk4_step(zs[:nx], us, p, cfg.dt_s, cfg.model_substeps)
        stage = ctrl.stage_cost(zs[:nx], us)
        z_next = ca.vertcat(s_next, zs[nx] + stage, zs[nx + 1]) if self.augmented else s_next
        f_step = ca.Function("f_step", [zs, us], [z_next])
        ss = ca.SX.sym("s", nx)
        f_stage = ca.Function("l", [ss, us], [ctrl.stage_cost(ss, us)])

        # Scaled decision variables: w = w_scale * w_scaled.
        z_scale = np.array(ctrl.state_scale() + ([1.0, 1.0] if self.augmented else []))
        u_scale = np.array(ctrl.control_scale())
        self.w_scale = np.concatenate([np.tile(np.concatenate([z_scale, u_scale]), H), z_scale])
        acc_scale = max(abs(lim.angular_acc.lo), abs(lim.angular_acc.hi))

        s_meas = ca.MX.sym("s0", nx)
        Zt = [ca.MX.sym(f"z{k}", nz) for k in range(H + 1)]
        Ut = [ca.MX.sym(f"u{k}", nu) for k in range(H)]
        Z = [z_scale * zt for zt in Zt]
        U = [u_scale * ut for ut in Ut]
        w = []
        for k in range(H):
            w += [Zt[k], Ut[k]]
        w.append(Zt[H])

        s_lo, s_hi = lim.state_bounds()
        u_lo, u_hi = lim.control_bounds()
        lbw, ubw = np.full(self.n_w, -np.inf), np.full(self.n_w, np.inf)
        for k in range(H + 1):
            z0 = k * self.block
            if k > 0:  # z_0 is fixed by the initial-condition rows
                lbw[z0 : z0 + nx], ubw[z0 : z0 + nx] = s_lo, s_hi
            if self.augmented:
                lbw[z0 + nx + 1] = 0.0  # sigma >= 0
            if k < H:
                lbw[z0 + nz : z0 + self.block], ubw[z0 + nz : z0 + self.block] = u_lo, u_hi
        self.lbw, self.ubw = lbw / self.w_scale, ubw / self.w_scale

        n_init = nx + 1 if self.augmented else nx  # s_0 = s_meas (and c_0 = 0); sigma is free
        z_init = ca.vertcat(s_meas, 0) if self.augmented else s_meas
        g, lbg, ubg, equality, checked = [], [], [], [], []
        self.gap_rows, self.path_rows = [], []
        objective = 0
        penalty = 0
        row = 0

        def add(expr, lo, hi, n, is_eq, check=True):
            nonlocal row
            g.append(expr)
            lbg.extend(np.broadcast_to(lo, n))
            ubg.extend(np.broadcast_to(hi, n))
            equality.extend([is_eq] * n)
            checked.extend(np.broadcast_to(check, n))
            row += n

        bookkeeping = [True] * nx + ([False, False] if self.augmented else [])
        for k in range(H):  # row order per stage as fatrop's structure detection expects
            self.gap_rows.append(slice(row, row + nz))
            add((Z[k + 1] - f_step(Z[k], U[k])) / z_scale, 0.0, 0.0, nz, True, bookkeeping)
            if k == 0:
                add((Z[0][:n_init] - z_init) / z_scale[:n_init], 0.0, 0.0, n_init, True, bookkeeping[:n_init])
            self.path_rows.append(row)
            acc = p.angular_acceleration(Z[k][5], U[k][1]) / acc_scale
            add(acc, lim.angular_acc.lo / acc_scale, lim.angular_acc.hi / acc_scale, 1, False)
            objective += f_stage(Z[k][:nx], U[k])
            if k == H - 1 and terminal == "origin":
                tol = ctrl.terminal_tolerance() / z_scale[:nx]
                if np.any(tol > 0):
                    add(Z[H][:nx] / z_scale[:nx], -tol, tol, nx, False)
                else:
                    add(Z[H][:nx] / z_scale[:nx], 0.0, 0.0, nx, True)
                objective += ctrl.terminal_cost(Z[H][:nx])
            elif k == H - 1 and self.augmented:
                self.bound_row = row  # c_H - sigma_H <= Vbar (upper bound set per solve)
                add(Z[H][nx] - Z[H][nx + 1], -np.inf, np.inf, 1, False, False)
                penalty = cfg.slack_weight * Z[0][nx + 1]
        self.lbg, self.ubg = np.array(lbg), np.array(ubg)
        self.checked_rows = np.array(checked, dtype=bool)
        self._shift_maps()

        wvec = ca.vcat(w)
        nlp = {"x": wvec, "f": objective + penalty, "g": ca.vcat(g), "p": s_meas}
        # bounds fixed per NLP; ubg is set per solve
        problem = NonlinearProgram(wvec, nlp["f"], nlp["g"], s_meas, self.lbw, self.ubw, self.lbg, self.ubg, equality)
        self.solvers = {"warm": _make_solver(cfg, cfg.solver, problem, warm=True)}
        if not self.augmented:  # the bounded NLP is only ever warm started from the plain one
            self.solvers["cold"] = _make_solver(cfg, "ipopt", problem, warm=False)
        # the warm solver takes multipliers (IPOPT) or only the primal guess (fatrop)
        self.warm_uses_multipliers = self.solvers["warm"][0] == "ipopt"
        self.g_fn = _Buffered(ca.Function("g", [wvec, s_meas], [nlp["g"]]).expand())
        self.value_fn = _Buffered(ca.Function("J", [wvec], [objective]).expand())
        self.costs_fn = f_stage.map(H)

    # --------------------------------------------------------------- vectors
    def split(self, w_scaled: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unscaled planar states S (H+1, 6) and controls U (H, 2) of a scaled vector."""
        H, b = self.horizon, self.block
        w = w_scaled * self.w_scale
        stages = w[: H * b].reshape(H, b)
        S = np.vstack([stages[:, :N_STATE], w[H * b : H * b + N_STATE][None, :]])
        return S, stages[:, self.nz :].copy()

    def join(self, S: np.ndarray, U: np.ndarray, bound: float = math.inf) -> np.ndarray:
        """Scaled vector from planar states and controls (cost and slack states filled in)."""
        H = self.horizon
        Z = S
        if self.augmented:
            costs = np.array(self.costs_fn(S[:H].T, U.T)).ravel()
            c = np.concatenate([[0.0], np.cumsum(costs)])
            sigma = np.full(H + 1, max(0.0, c[-1] - bound) + 1e-8)
            Z = np.column_stack([S, c, sigma])
        return np.concatenate([np.hstack([Z[:H], U]).ravel(), Z[H]]) / self.w_scale

    def _shift_maps(self) -> None:
        """Index maps of the one-stage shift of the constraint multipliers: gap and path rows
        of stage k+1 move to stage k (initial-condition and terminal rows stay)."""
        dst, src = [], []
        for k in range(self.horizon - 1):
            dst += list(range(self.gap_rows[k].start, self.gap_rows[k].stop)) + [self.path_rows[k]]
            src += list(range(self.gap_rows[k + 1].start, self.gap_rows[k + 1].stop)) + [self.path_rows[k + 1]]
        self._lam_g_dst, self._lam_g_src = np.array(dst, dtype=int), np.array(src, dtype=int)

    def shift_multipliers(self, lam_g: np.ndarray, lam_x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Multipliers shifted one stage (initial-condition and terminal rows kept)."""
        H, b = self.horizon, self.block
        lam_x_new = lam_x.copy()
        lam_x_new[: (H - 1) * b + self.nz] = lam_x[b:]
        lam_g_new = lam_g.copy()
        lam_g_new[self._lam_g_dst] = lam_g[self._lam_g_src]
        return lam_g_new, lam_x_new

    def feasible(self, w: np.ndarray, s: np.ndarray, ubg: np.ndarray, tol: float = 1e-5) -> bool:
        """Check the returned point, not only the status: variable bounds, dynamics gaps,
        initial condition, path and terminal rows within ``tol`` (scaled units), with the
        constraints re-evaluated here from ``w`` and ``s``."""
        if not np.all(np.isfinite(w)):
            return False
        if np.any(w < self.lbw - tol) or np.any(w > self.ubw + tol):
            return False
        g = self.g_fn(w, s)["o0"]
        m = self.checked_rows
        return not (np.any(g[m] < self.lbg[m] - tol) or np.any(g[m] > ubg[m] + tol))

    def solve(self, s, w0, warm_start: bool, lam_g0=None, lam_x0=None, bound: float = math.inf):
        """Warm solver (when ``warm_start``: a shifted previous solution exists), then cold
        IPOPT. ``lam_g0``/``lam_x0`` go to a warm solver that takes multipliers.

        Returns (result or None, status, iterations, warm_used); the result holds copies of
        ``x``, ``lam_g`` and ``lam_x``. Wall time inside the solvers accumulates in
        ``solver_time_s``."""
        self.last_status = Status.FAILED  # the vocabulary status of a failed solve (the returned text is the detail)
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(w0))):
            self.last_status = Status.INVALID_INPUT
            return None, "invalid_input", 0, False  # fatrop does not return from a NaN guess
        ubg = self.ubg
        if self.augmented:
            ubg = ubg.copy()
            ubg[self.bound_row] = bound
        keys = ["warm", "cold"] if warm_start or self.augmented else ["cold"]
        status, iters = "failed", 0
        for key in keys:
            if key not in self.solvers:
                continue
            name, solver = self.solvers[key]
            solver.update(p=s, ubg=ubg)
            if key == "warm" and lam_g0 is not None and self.warm_uses_multipliers:
                solver.warm_start(x=w0, lam_g=lam_g0, lam_x=lam_x0)
            else:
                solver.warm_start(x=w0)
            t_start = time.perf_counter()
            res = solver.solve()  # CasadiNLP: evaluation errors are a status (raw "error")
            self.solver_time_s += time.perf_counter() - t_start
            iters += res.iterations
            if res.info["success"] and self.feasible(res.x, s, ubg):
                return {"x": res.x, "lam_g": res.info["lam_g"], "lam_x": res.info["lam_x"]}, "ok", iters, key == "warm"
            status = f"{name}:{res.info['raw_status']}"
            self.last_status = Status.INFEASIBLE_SOLUTION if res.info["success"] else res.status
        return None, status, iters, False


def _make_solver(cfg: NMPCConfig, name: str, problem: NonlinearProgram, warm: bool):
    """A CasADi NLP adapter (:class:`proxops.solvers.casadi_nlp.CasadiNLP`) set up on ``problem``."""
    max_iter = cfg.max_iter if warm else 5 * cfg.max_iter
    if name == "fatrop":
        plugin = {"print_level": 0, "max_iter": max_iter, "tol": cfg.tol, **(WARM_FATROP if warm else {})}
    else:
        plugin = {"print_level": 0, "sb": "yes", "max_iter": max_iter, "tol": cfg.tol, **(WARM_IPOPT if warm else {})}
    plugin.update(cfg.solver_options.get(name, {}))
    solver = CasadiNLP(name, options=plugin, label=f"nmpc_{name}_{'warm' if warm else 'cold'}")
    solver.setup(problem)
    return name, solver


class UnderactuatedNMPC:
    """NMPC controller (proxops.contracts.Controller) for the planar CubeSat.

    ``step(t, s)`` takes the planar state ``[x, y, theta, vx, vy, omega]`` and returns
    ``Command(u=[thrust N, wheel_acc rad/s^2], kind="acceleration")`` whose ``info`` holds
    ``value_function`` (V_H), ``value_bound`` (Vbar of eq. 14, nan when inactive),
    ``iterations``, ``bound_solve`` (1 if the bounded NLP was solved), ``bound_relaxed``
    (1 if V_H > Vbar remained), ``warm_solver`` (1 if the warm solver answered) and
    ``solver_time_s`` (s, wall time inside the NLP solver calls alone).
    ``solve_time_s`` is the controller's whole computation for the step.
    """

    def __init__(
        self,
        params: PlanarCubeSatParams,
        limits: PlanarLimits,
        config: NMPCConfig | None = None,
        docking: DockingSet | None = None,
    ):
        self.params = params
        self.limits = limits
        self.config = config or NMPCConfig()
        self.docking = docking or DockingSet()
        self.dt = float(self.config.dt_s)
        self._nlp = _Nlp(self, "origin" if self.config.variant == "general" else "none")
        self._bounded: _Nlp | None = None  # built on first need (averaged variant)
        self.reset(0.0, np.zeros(N_STATE))

    # ------------------------------------------------------------------ model pieces
    def stage_cost(self, s, u):
        q, r = self.config.q_diag, self.config.r_diag
        return sum(q[i] * s[i] * s[i] for i in range(N_STATE)) + sum(r[j] * u[j] * u[j] for j in range(N_CONTROL))

    def terminal_cost(self, s):
        w, q = self.config.terminal_weight, self.config.q_diag
        return sum(w * q[i] * s[i] * s[i] for i in range(N_STATE))

    def terminal_tolerance(self) -> np.ndarray:
        """Half-widths of the terminal box |s_H| <= tol (general variant)."""
        d, f = self.docking, self.config.terminal_box_fraction
        return f * np.array([d.position_m, d.position_m, d.angle_rad, d.velocity_mps, d.velocity_mps, d.rate_rad_s])

    def state_scale(self) -> list:
        """Characteristic magnitudes of [x, y, theta, vx, vy, omega] for NLP scaling."""
        lim, cfg = self.limits, self.config
        vmax = max(abs(lim.velocity.lo), abs(lim.velocity.hi))
        wmax = max(abs(lim.rate.lo), abs(lim.rate.hi))
        return [cfg.position_scale_m, cfg.position_scale_m, 1.0, min(1.0, vmax), min(1.0, vmax), wmax]

    def control_scale(self) -> list:
        lim = self.limits
        return [max(abs(lim.thrust.lo), abs(lim.thrust.hi)), max(abs(lim.wheel_acc.lo), abs(lim.wheel_acc.hi))]

    # ------------------------------------------------------------------ running
    def reset(self, t0: float, x0: np.ndarray) -> None:
        self._plan: tuple[np.ndarray, np.ndarray] | None = None  # (S, U) of the last solution
        self._lam: tuple[np.ndarray, np.ndarray] | None = None  # plain-NLP multipliers
        self._values: list[float] = []
        self._bound = math.inf
        self._k = 0

    @property
    def last_plan(self) -> np.ndarray | None:
        """Predicted planar states (H+1, 6) of the last solution."""
        return None if self._plan is None else self._plan[0]

    @property
    def values(self) -> list:
        """Optimal value V_H of every step (nan where every solve failed)."""
        return list(self._values)

    def _initial_guess(self, s0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cold start: states interpolated linearly from the measurement to the origin
        (general variant, whose terminal state is 0) or held at the measurement; zero controls."""
        H = self.config.horizon
        general = self.config.variant == "general"
        fraction = np.linspace(1.0, 0.0, H + 1) if general else np.ones(H + 1)
        return fraction[:, None] * s0[None, :], np.zeros((H, N_CONTROL))

    def _shifted_plan(self, s0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Previous plan shifted one stage; the tail repeats the last control."""
        S, U = self._plan
        s_end = rk4_step(S[-1], U[-1], self.params, self.dt, self.config.model_substeps)
        S = np.vstack([S[1:], s_end])
        U = np.vstack([U[1:], U[-1:]])
        S[0] = s0
        return S, U

    def step(self, t: float, x_est: np.ndarray) -> Command:
        t_start = time.perf_counter()
        s = np.array(x_est, dtype=float)
        s[2] = wrap_angle(s[2])
        cfg = self.config
        if cfg.stop_when_docked and self.docking.contains(s):
            return Command(u=np.zeros(N_CONTROL), status=Status.OK, mode="docked", stop=True)

        # eq. 14: every N steps the bound becomes the mean of the last N values
        if cfg.variant == "averaged" and self._k >= cfg.average_window and self._k % cfg.average_window == 0:
            recent = np.array(self._values[-cfg.average_window :])
            if np.any(np.isfinite(recent)):
                self._bound = float(np.nanmean(recent))
        self._k += 1

        nlp = self._nlp
        solver_time_before = self._solver_time_s()
        lam_g0 = lam_x0 = None
        if self._plan is None:
            S0, U0 = self._initial_guess(s)
        else:
            S0, U0 = self._shifted_plan(s)
            if nlp.warm_uses_multipliers:
                lam_g0, lam_x0 = nlp.shift_multipliers(*self._lam)
        result, status, iters, warm_used = nlp.solve(s, nlp.join(S0, U0), self._plan is not None, lam_g0, lam_x0)
        value = math.nan
        bound_solve = relaxed = False
        if result is not None:
            w = result["x"]
            value = float(nlp.value_fn(w)["o0"][0])
            self._plan = nlp.split(w)
            self._lam = (result["lam_g"], result["lam_x"])
            if cfg.variant == "averaged" and value > self._bound * (1.0 + 1e-9):
                bound_solve = True
                value, extra_iters = self._bounded_solve(s, value)
                iters += extra_iters
                relaxed = value > self._bound * (1.0 + 1e-6)

        info = {
            "value_function": value,
            "value_bound": self._bound if math.isfinite(self._bound) else math.nan,
            "iterations": float(iters),
            "bound_solve": float(bound_solve),
            "bound_relaxed": float(relaxed),
            "warm_solver": float(warm_used),
            "solver_time_s": self._solver_time_s() - solver_time_before,
        }
        self._values.append(value)
        if result is None:  # every attempt failed: apply the shifted previous plan
            if self._plan is not None:
                self._plan = (S0, U0)
                u = np.clip(U0[0], *self.limits.control_bounds())
            else:
                u = np.zeros(N_CONTROL)
            st = nlp.last_status  # the solver's own words ("ipopt:Infeasible_Problem_Detected") are the detail
            return Command(u=u, status=st, solve_time_s=time.perf_counter() - t_start, mode=cfg.variant,
                           info=info, status_detail="" if st.value == status else status)
        return Command(u=self._plan[1][0].copy(), status=Status.OK, solve_time_s=time.perf_counter() - t_start,
                       mode=cfg.variant, info=info)

    def _solver_time_s(self) -> float:
        """Wall time spent inside the NLP solvers so far (s)."""
        return self._nlp.solver_time_s + (self._bounded.solver_time_s if self._bounded is not None else 0.0)

    def _bounded_solve(self, s: np.ndarray, plain_value: float) -> tuple[float, int]:
        """Eq. 14 with the bound: search for a minimiser with J_H <= Vbar from the plain
        solution. Keeps whichever result has the lower value; returns (value, iterations)."""
        if self._bounded is None:
            self._bounded = _Nlp(self, "value-bound")
        bnlp = self._bounded
        S, U = self._plan
        result, _, iters, _ = bnlp.solve(s, bnlp.join(S, U, self._bound), True, bound=self._bound)
        if result is None:
            return plain_value, iters
        w = result["x"]
        value = float(bnlp.value_fn(w)["o0"][0])
        if value < plain_value:
            self._plan = bnlp.split(w)  # the plain multipliers stay: a fair guess for the next shift
            return value, iters
        return plain_value, iters
