"""Short Range Framework MPC (Silva et al. 2026 §4.4, problem 29) on impulsive CW.

Problem solved at every MPC node ``i`` (shrinking horizon ``i..N``, impulses ``u_i..u_N``;
``x_j`` is the state *before* the impulse at node ``j``, ``x_{j+1} = Phi(t_{j+1}-t_j)(x_j + [0; u_j])``)::

    min  1/2 (p_N - p_d)' Q (p_N - p_d) + R sum_j 1'(u+_j + u-_j)            (29a)
    s.t. x_i = x_hat (29b), impulsive CW (29c), u = u+ - u-
         |p_N - p_d|_inf <= pos_tol,  |v_N + u_N|_inf <= vel_tol             (29d) terminal set
         0 <= u+_j, u-_j <= u_max                                             (29e-f)
         sum_j 1'(u+_j + u-_j) <= u_budget - (dv already used)                (29g)
         x_u(tau) = Phi(tau)(x_i + [0; u_i]) for tau in the free-drift grid   (29h-i)
         hdot(x_u) + alpha h(x_u) >= 0 and |p_u - c| >= r at those taus       (29j) (convexified, below)
         at every future hop node j: |b . p_j| <= r_tol, |a . v_j| <= w_tol   (29k-m)
         V-bar only, hop lengths L_m = a.p(J_{m-1}) - a.p(J_m):
             h_min <= L_m <= h_max                                            (29n)
             L_{m+1} <= L_m - eps                                             (29o, corrected)

``a`` is the approach axis and ``b`` the in-plane perpendicular of eq. (20)
(``e_A``, ``e_perp2``) expressed in Hill; Hill is the only frame here.

Corrections / choices (also in the report):

* (29m) is printed on ``v_x``; it must be the rotated along-axis velocity ``w_x`` (eq. 29k
  defines w = R v and (23) requires w_xt = 0).
* (29o) as printed, ``r_{j+1} - r_j <= r_j - r_{j-1} + eps``, reads ``L_{j+1} >= L_j - eps``:
  a lower bound that does not make hops decrease. The text says it "enforces a decrease of
  hop sizes"; implemented as ``L_{j+1} <= L_j - eps``.
* Free drift (29h-j): the paper samples x_u on the remaining MPC nodes (empty at the end of a
  shrinking horizon). Here x_u is sampled on a fixed grid of ``free_drift_nodes`` points over
  ``free_drift_s`` (default one orbit, the passive-abort horizon), which does not shrink.
* (29j) is non-convex. Convexification: (1) supporting half-spaces
  ``n_f . (p_u(tau_f) - c) >= r`` with n_f from the reference unforced trajectory (sound:
  every such point is outside the sphere) and (2) the CBF condition linearised about the
  same reference (g is an indefinite quadratic, so this row alone is not conservative). The
  reference is the unforced trajectory of the previous plan's impulse for this node. Every
  solution is then checked against the TRUE conditions (|p_u - c| >= r and
  hdot + alpha h >= 0 at every tau_f); if the check fails the problem is re-linearised about
  the new solution (at most ``cbf_iterations`` solves); if it still fails the solution is
  rejected (status ``cbf_violation``) and the fallback is applied.
* Linearisation references: the previous plan's impulse for this node, replaced by the "hold"
  impulse (drift-free CW state: a closed ellipse about the current along-track position) when
  the former's drift fails the true check and the hold drift passes -- half-spaces taken on an
  unsafe drift can point across the orbit plane and buy safety with large out-of-plane
  impulses, or be empty. If that fails and the CBF rows are suspect, the problem without them is
  solved once; when it is feasible the hold impulse and its solution are tried as references.
* With drift-free rows and no plan for the node yet, the first reference is the hold impulse.
* Before relaxing, an infeasible problem is retried once about the hold impulse's drift (when
  safe): half-spaces on a safe but far-off reference drift can cut off every solution.
* Fallback (any failure): the previous plan's impulse for this node if its free drift passes
  the true check, else the hold impulse if its drift passes, else no impulse. (The drift window
  slides with time, so "no impulse" is certified only up to the previous window's end.)
* Margin: the system passes a KOZ inflated by ``keep_out.margin_m`` (default 10 m) because
  the CW prediction from the estimated state differs from the J2 truth.
* Relaxation ladder when the problem is infeasible (noise, J2, dispersions): (1) drop the
  design rows -- the V-bar decrease (29o), the guidance hop-distance bands and the drift hold rows -- (event
  ``design_rows_relaxed``); (2) also drop the terminal position box (``terminal_set_relaxed``);
  (3) also drop the hop rows (29l)-(29n) (``hops_relaxed``). The CBF rows are never dropped.
* V-bar: hop lengths cost the same fuel whatever the split ((w/2) sum L for radial hops), so
  the optimiser lands on a vertex of (29n)-(29o) where any disturbance makes the next problem
  infeasible. ``hop_distance_weight_per_m2`` adds 1/2 w (a.p(J_m) - d_m)^2 towards Algorithm 1's
  distances d_m (hop-end positions are extra variables), which picks a robust interior split.

* V-bar drift removal (not in the paper; needed for its "indefinite hold" claim): the free CW
  motion after an impulse is periodic iff ``c = vy+ + 2 n x = 0`` (Hill; the secular term of
  y(t) is ``-(6 n x0 + 3 vy0) t``). (29m) bounds the along-axis velocity *before* the hop-start
  impulse to 2 mm/s, which leaves up to ``3 * 2 mm/s * t_orb`` (about 40 m at a = 8100 km) of
  along-track drift per orbit, plus what the impulse itself adds. With ``drift_free_tol_mps``
  every hop-start node j (node 0 and every hop end but the last) gets the row
  ``|c_avg + sum_{l=i..j} k_l . u_l| <= tol``. ``c`` is a constant of the free motion (CW:
  dc/dt = ydd + 2 n xd = 0), so only impulses change it, by ``k_l . u_l`` (CW: k = e_y), and the
  controller averages the navigation samples of c taken since its last impulse (one per engine
  step) instead of using the single noisy estimate at the node (white 0.5 m / 0.5 mm/s noise is
  1 mm/s on one sample of c, 22 m of drift per orbit).
  J2-aware equivalent (``drift_model``, :class:`EnergyDrift`): on the nonlinear J2 truth ``vy + 2nx``
  is not constant (measured: it swings by ~1 mm/s within a hop at 2 km, from the rectilinear-frame
  curvature and the target orbit's J2-induced eccentricity), so c is the chaser-minus-target
  specific energy (two-body + J2 potential, both conserved on the free motion: the J2 potential is
  axisymmetric) divided by |v_t|: equal energies mean equal semi-major axes and no secular drift;
  for a circular CW target it reduces to ``vy + 2 n x``. k_l = R^T v_t / |v_t| at node l.
* V-bar drift trim (``drift_trim_delay_nodes``, not in the paper): the row at the hop impulse acts on
  what the controller knows then -- one navigation sample at the first hop (1 mm/s, 22 m/orbit at
  1 sigma) -- and cannot remove the impulse's own execution error (0.5 deg pointing on 0.2-0.4 m/s
  is 2-3 mm/s along y, 40-66 m/orbit at 1 sigma). So every hop start also gets a drift row at the
  node ``drift_trim_delay_nodes`` later (the trim node), where c is the mean of the navigation
  samples since the hop impulse (its least-squares estimate: c is constant on the free motion;
  60 samples at the default node spacing: 0.13 mm/s, 2.8 m/orbit at 1 sigma): the MPC fires a small
  trim (mm/s) that nulls it, with the same thrusters (its own pointing/magnitude errors are ~1 % of
  a few mm/s). A trim below the minimum impulse bit (``min_impulse_mps``) would fire nothing: it is
  raised to the bit by an out-of-plane component (:meth:`SrfMpc._lift_to_impulse_bit`). Option
  ``drift_hold_after_trim`` (off by default): every later impulse of the hop up to its end keeps c as
  trimmed (``|sum_{trim < l <= j} k_l . u_l| <= tol``, relaxed with the design rows), so the drift
  stays null after any of them. Measured on srf-vbar-mc (50 runs): the radial-only corrections it
  forces make the problem infeasible far more often -- relaxed with the hop rows (level 3): 117
  relaxations in 13 runs, worst l1 dv 8.4 m/s; as a design row (level 1, as now): 40 in 13 runs,
  worst l1 dv 10.2 m/s and one hop drift missing by 1.2 km/orbit -- against 12 in 4 runs, worst
  1.18 m/s and 11 m/orbit without it; so it is off by default. The passive-abort drift of a hop
  (systems.srf.passive_abort) starts after its trim.

QP (solved by the persistent adapter of ``solver``, PIQP by default, Clarabel as fallback): condensed in the
impulses, variables scaled to z = u / u_max in [0, 1] plus the terminal position error in km.
The prediction blocks Phi(t_j - t_l) of the whole node grid are built once at construction;
the shrinking horizon keeps one sparsity pattern (past impulses fixed to 0 by their bounds,
past hop rows switched off), so a single solver is set up once and updated in place; PIQP removes
the fixed past impulses from what it factors (``drop_fixed``: a new PIQP set-up at each node, updates in
place between the SCP solves of a node; 4x less solver time over a run, solutions within its tolerance).
The per-node data come from jitted passes (:func:`_row_bounds_kernel`, :func:`_cbf_rows_kernel`, with numpy's
order of the sums: the same QP bit for bit) and reach PIQP through its trusted ``update_fast`` (fixed patterns,
vectors handed over without copies). Every accepted solution is checked for feasibility against its own rows
(:func:`_max_violation_kernel`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numba import njit

from proxops.constraints.keep_out import KeepOutSphere
from proxops.control.relaxation import climb
from proxops.core.cw import cw_stm
from proxops.core.memo import memo_get
from proxops.core.twobody import accel_gravity_vec
from proxops.guidance.hop_times import check_trim_delay, hop_engine_steps
from proxops.errors import ProxopsInputError, input_error
from proxops.propagation.kernels import energy_gains, energy_invariants
from proxops.contracts import Command
from proxops.solvers import QuadraticProgram, SolveStatus, make_solver, solve_qp, successive_convexification
from proxops.status import Status

KM = 1000.0
OFF = 1e3  # bound of rows that are switched off (scaled units: km or m/s; both sides infinite makes PIQP zero the row)


@dataclass
class SrfMpcConfig:
    """Weights, limits and tolerances of problem (29) (SI units)."""

    q_terminal_per_m2: float = 1e-3  # Q = q I on the terminal position error (cost in m/s units)
    r_fuel: float = 1.0  # R on the l1 norm of the impulses
    u_max_mps: float = 2.0  # per axis per impulse (29e-f)
    u_budget_mps: float = math.inf  # cumulative l1 budget (29g)
    terminal_pos_tol_m: float = 2.0  # X_f position box half-width (29d)
    terminal_vel_tol_mps: float = 0.005  # X_f velocity box after the final (braking) impulse
    r_tol_m: float = 1.0  # (29l)
    w_tol_mps: float = 0.002  # (29m)
    vbar_rows: bool = False  # add (29n)-(29o)
    h_min_m: float = 0.0
    h_max_m: float = math.inf
    epsilon_m: float = 0.0
    hop_distance_tol_m: list[float] | None = None  # per hop: |a . p(J_m) - d_m| <= tol_m (not in the paper)
    mid_hop_fuel_weight: float = 1.0  # R multiplier for impulses between hop instants (1 = paper)
    hop_distance_weight_per_m2: float = 0.0  # 1/2 w (a.p(J_m) - d_m)^2 towards Algorithm 1's distances (0 = paper)
    drift_free_tol_mps: float | None = None  # V-bar: |vy+ + 2 n x| <= tol after every hop-start impulse (None = off)
    drift_outward_mps: float = 0.0  # V-bar: the drift rows ask s c in [b, b + 2 tol] (s: away from the target), b this
    drift_model: "EnergyDrift | None" = None  # J2-aware invariant from an onboard target ephemeris (None: CW's)
    drift_trim_delay_nodes: int | None = None  # V-bar: trim row this many nodes after every hop start (None = off)
    drift_hold_after_trim: bool = False  # with a trim: later impulses of the hop keep c as trimmed (design row)
    drift_estimator_window_s: float | None = None  # average c over the samples of this window (None: since the last impulse)
    min_impulse_mps: float = 0.0  # the thrusters' minimum impulse bit (|u| below it fires nothing)
    cbf: bool = True
    cbf_alpha_per_s: float = 0.01
    free_drift_s: float | None = None  # None: one orbital period
    free_drift_nodes: int = 72
    cbf_iterations: int = 3
    feasibility_tol: float = 1e-5  # on the scaled rows (km, m/s, u/u_max)
    solver: str = "piqp"


@njit(cache=True)
def _grid_rows(states, dt, t):
    """(states[k_j] for k_j = rint(t_j / dt), index of the first t_j off the grid or -1): off the grid when
    k_j is outside the table or |k_j dt - t_j| > 1e-6 max(1, t_j) (or t_j is NaN), as numpy's
    ``np.rint(t / dt).astype(int)`` and its mask compute it."""
    n = t.shape[0]
    out = np.empty((n, states.shape[1]))
    for j in range(n):
        tj = t[j]
        if tj != tj:
            return out, j
        kf = np.rint(tj / dt)
        if not (0.0 <= kf < states.shape[0]):
            return out, j
        k = int(kf)
        if abs(k * dt - tj) > 1e-6 * max(1.0, tj):
            return out, j
        out[j] = states[k]
    return out, -1


@dataclass
class EnergyDrift:
    """J2-aware drift invariant from an onboard target ephemeris (Hill frame with the J2 frame rate).

    ``states`` (K, 6): target ECI states at ``t = k dt`` (m, m/s); ``mu``, ``j2``, ``re``: the gravity
    model (j2 = 0 for two-body). ``invariant(t, x) = (E_chaser - E_target) / |v_t|`` (m/s), with
    E = |v|^2 / 2 + V(r) (two-body + J2, :func:`proxops.core.twobody.potential`); both energies are
    conserved on the free motion, and equal energies mean no secular along-track drift."""

    dt: float
    states: np.ndarray
    mu: float
    j2: float
    re: float

    def target(self, t: float) -> np.ndarray:
        return self.states[self._index(t)]

    def _accel(self, r: np.ndarray) -> np.ndarray:
        return accel_gravity_vec(r, self.mu, self.j2, self.re)

    def _index(self, t: float) -> int:
        k = int(round(t / self.dt))
        if not 0 <= k < len(self.states) or abs(k * self.dt - t) > 1e-6 * max(1.0, t):
            raise input_error("t", t, f"is not on the ephemeris grid (dt = {self.dt:g} s, {len(self.states)} points)", "s")
        return k

    def invariant(self, t: float, x) -> float:
        """:meth:`invariants` of one state (the same kernel on the same row: the same number)."""
        k = self._index(t)
        x6 = np.ascontiguousarray(np.asarray(x, dtype=float)[None, :6])
        return float(energy_invariants(self.states[k:k + 1], x6, self._params())[0])

    def invariants(self, t: np.ndarray, xs: np.ndarray) -> np.ndarray:
        """:meth:`invariant` of Hill states (n, 6) at times (n,) on the ephemeris grid, one jitted
        call (:func:`proxops.propagation.kernels.energy_invariants`; the same numbers row by row)."""
        return energy_invariants(self._targets(t), np.ascontiguousarray(xs[:, :6], dtype=float), self._params())

    def _params(self) -> np.ndarray:
        return np.array([self.mu, self.j2, self.re])

    def _targets(self, t) -> np.ndarray:
        """The ephemeris rows at times ``t`` (s, on the grid: ``k = rint(t / dt)``, within 1e-6 relative), one
        jitted gather (:func:`_grid_rows`); a time off the grid raises :meth:`_index`'s one-line error."""
        t = np.ascontiguousarray(t, dtype=float)
        rows, bad = _grid_rows(self.states, float(self.dt), t)
        if bad >= 0:
            self._index(float(t[bad]))  # raises the one-line error
        return rows

    def gains(self, t, xs) -> np.ndarray:
        """:meth:`gain` of Hill states (n, 6) at times (n,), one jitted call
        (:func:`proxops.propagation.kernels.energy_gains`)."""
        return energy_gains(self._targets(t), np.ascontiguousarray(xs[:, :6], dtype=float), self._params())

    def gain(self, t: float, x=None) -> np.ndarray:
        """Change of the invariant per unit impulse at chaser Hill state ``x`` (Hill components):
        ``C v_c / |v_t|`` with the chaser's inertial velocity ``C v_c = C v_t + rho' + w x rho``
        (first order in the impulse; the rotating-frame term is 1.7 m/s at 2 km along-track)."""
        x = np.zeros(6) if x is None else np.asarray(x, dtype=float)
        return self.gains(np.array([t]), x[None, :6])[0]


# Prediction blocks by (mean motion, node times): every run of a Monte Carlo campaign with the same
# orbit and hop plan (srf-*-mc: only the initial state is dispersed) reuses them (read-only arrays).
_BLOCK_CACHE: dict = {}


def _cached_blocks(key, build):
    return memo_get(_BLOCK_CACHE, key, build, read_only=True)


def _prediction_blocks(n_orb: float, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Phi (N+1, N+1, 6, 6): Phi(t_j - t_i) for j >= i (else unused); S (N+1, 6, 3(N+1)): S[j] the
    effect of impulse u_l (l < j) on x_j. Cached per (n, node times), read-only."""
    def build():
        N = len(times) - 1
        phi = np.empty((N + 1, N + 1, 6, 6))
        for i in range(N + 1):
            for j in range(i, N + 1):
                phi[j, i] = cw_stm(n_orb, times[j] - times[i])
        S = np.zeros((N + 1, 6, 3 * (N + 1)))
        for j in range(N + 1):
            for l in range(j):
                S[j, :, 3 * l:3 * l + 3] = phi[j, l][:, 3:6]
        return phi, S

    return _cached_blocks(("prediction", float(n_orb), np.asarray(times, dtype=float).tobytes()), build)


def _drift_stms(n_orb: float, tau: np.ndarray) -> np.ndarray:
    """Phi(tau_f) (F, 6, 6) of the free-drift grid, cached per (n, grid), read-only."""
    return _cached_blocks(("drift", float(n_orb), tau.tobytes()),
                          lambda: (np.array([cw_stm(n_orb, t) for t in tau]),))[0]


_NO_ROWS = np.empty(0, dtype=np.intp)
_PATTERN_CACHE: dict = {}  # fixed CSC patterns of the QP matrices by (shape, COO rows, COO cols) (SrfMpc._csc)


@njit(cache=True)
def _row_bounds_kernel(phi, i, x, relax, a, b, fN, rx_past, nodes, hop_r, hop_w, hop_j, drift_r, drift_j, hold_r, hold_j,
                       dist_r, dist_m, len_r, len_m, dec_r, dec_m, targets, dist_tol, tol, n_rows, big):  # fmt: skip
    """Bounds (lo, hi) of the rows with constant coefficients at node i (SrfMpc._row_bounds) and the constant
    part of a . p at node 0 and every hop end (rxv, m): rx_past where a node is not ahead of i, else the
    prediction a . (Phi(t_j - t_i) x)[:3]. tol = [r_tol, w_tol, drift c_lo - c, c_hi - c, hold tol, h_min,
    h_max, eps, budget upper bound, terminal velocity tol] (drift entries used only when computed)."""
    n_nodes = nodes.shape[0]
    rxv = np.empty(n_nodes)
    for m in range(n_nodes):
        j = nodes[m]
        if j > i:
            acc = 0.0
            for r in range(3):
                row = 0.0
                for k in range(6):
                    row += phi[j, i, r, k] * x[k]
                acc += a[r] * row
            rxv[m] = acc
        else:
            rxv[m] = rx_past[m]
    lo = np.full(n_rows, -big)
    hi = np.full(n_rows, big)
    for r in range(3):
        lo[r] = -tol[9] - fN[3 + r]
        hi[r] = tol[9] - fN[3 + r]
    if relax < 3:
        for q in range(hop_j.shape[0]):
            j = hop_j[q]
            if j <= i:
                continue
            vb = 0.0
            va = 0.0
            for r in range(3):
                pr = 0.0
                vr = 0.0
                for k in range(6):
                    pr += phi[j, i, r, k] * x[k]
                    vr += phi[j, i, 3 + r, k] * x[k]
                vb += b[r] * pr
                va += a[r] * vr
            lo[hop_r[q]] = (-tol[0] - vb) / 1000.0
            hi[hop_r[q]] = (tol[0] - vb) / 1000.0
            lo[hop_w[q]] = -tol[1] - va
            hi[hop_w[q]] = tol[1] - va
        for q in range(drift_j.shape[0]):
            if drift_j[q] >= i:
                lo[drift_r[q]] = tol[2]
                hi[drift_r[q]] = tol[3]
        for q in range(len_m.shape[0]):
            m = len_m[q]
            if nodes[m] > i:
                v = rxv[m - 1] - rxv[m]
                lo[len_r[q]] = (tol[5] - v) / 1000.0
                hi[len_r[q]] = (tol[6] - v) / 1000.0
    if relax < 1:
        for q in range(hold_j.shape[0]):
            if hold_j[q] >= i:
                lo[hold_r[q]] = -tol[4]
                hi[hold_r[q]] = tol[4]
        N = nodes[n_nodes - 1]
        for q in range(dist_m.shape[0]):
            m = dist_m[q]
            if nodes[m] > i and nodes[m] != N:
                lo[dist_r[q]] = (targets[m] - dist_tol[m - 1] - rxv[m]) / 1000.0
                hi[dist_r[q]] = (targets[m] + dist_tol[m - 1] - rxv[m]) / 1000.0
        for q in range(dec_m.shape[0]):
            m = dec_m[q]
            if nodes[m + 1] > i:
                v = (rxv[m] - rxv[m + 1]) - (rxv[m - 1] - rxv[m])
                lo[dec_r[q]] = -np.inf
                hi[dec_r[q]] = (-tol[7] - v) / 1000.0
    if tol[8] == tol[8]:  # budget row (last), when there is one
        hi[n_rows - 1] = tol[8]
    return lo, hi, rxv




@njit(cache=True)
def _cbf_rows_kernel(phi_tau, cx, xr, center, radius, alpha, um, eps_norm):
    """Rows (29j) of the free drift after impulse w (SrfMpc._build, scaled units), from the unforced drift
    cx = Phi(tau_f) x and the reference drift xr = cx + Phi(tau_f)[:, 3:6] u_ref (both (F, 6), numpy's
    matmul): the supporting half-spaces n_f . (p_u(tau_f) - c) >= r and the CBF condition linearised about
    xr (KeepOutSphere.halfspace / cbf_linearization, eqs. 26-28), one pass with numpy's order of the sums
    (the same rows bit for bit; with the KOZ centre off the origin the caller recomputes half_lo from n_hat
    with numpy's n . c). Returns (half (F, 3), half_lo (F,), lin (F, 3), gu (F, 3) dg/du, g_ref (F,),
    scale (F,), n_hat (F, 3), ok); ok False when a reference point lies at the KOZ centre."""
    F = phi_tau.shape[0]
    half = np.empty((F, 3))
    half_lo = np.empty(F)
    lin = np.empty((F, 3))
    gu = np.empty((F, 3))
    g_ref = np.empty(F)
    scale = np.empty(F)
    n_hat = np.empty((F, 3))
    for f in range(F):
        d0, d1, d2 = xr[f, 0] - center[0], xr[f, 1] - center[1], xr[f, 2] - center[2]
        norm = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if norm <= eps_norm:
            return half, half_lo, lin, gu, g_ref, scale, n_hat, False
        n0, n1, n2 = d0 / norm, d1 / norm, d2 / norm
        n_hat[f, 0], n_hat[f, 1], n_hat[f, 2] = n0, n1, n2
        b_half = radius + ((n0 * center[0] + n2 * center[2]) + n1 * center[1])
        for l in range(3):
            half[f, l] = (n0 * phi_tau[f, 0, 3 + l] + n1 * phi_tau[f, 1, 3 + l] + n2 * phi_tau[f, 2, 3 + l]) * um / 1000.0
        # n . cx summed as numpy's einsum('fk,fk->f') sums it ((0 + 2) + 1)
        half_lo[f] = (b_half - ((n0 * cx[f, 0] + n2 * cx[f, 2]) + n1 * cx[f, 1])) / 1000.0
        # g = hdot + alpha h, grad = [2 v + 2 alpha (p - c), 2 (p - c)]
        g_ref[f] = 2.0 * (d0 * xr[f, 3] + d1 * xr[f, 4] + d2 * xr[f, 5]) + alpha * (d0 * d0 + d1 * d1 + d2 * d2
                                                                                    - radius * radius)
        grad0 = 2.0 * xr[f, 3] + 2.0 * alpha * d0
        grad1 = 2.0 * xr[f, 4] + 2.0 * alpha * d1
        grad2 = 2.0 * xr[f, 5] + 2.0 * alpha * d2
        for l in range(3):
            gu[f, l] = (grad0 * phi_tau[f, 0, 3 + l] + grad1 * phi_tau[f, 1, 3 + l] + grad2 * phi_tau[f, 2, 3 + l]
                        + 2.0 * d0 * phi_tau[f, 3, 3 + l] + 2.0 * d1 * phi_tau[f, 4, 3 + l] + 2.0 * d2 * phi_tau[f, 5, 3 + l])
        scale[f] = max(math.sqrt(gu[f, 0] * gu[f, 0] + gu[f, 1] * gu[f, 1] + gu[f, 2] * gu[f, 2]) * um, 1e-12)
        for l in range(3):
            lin[f, l] = gu[f, l] * um / scale[f]
    return half, half_lo, lin, gu, g_ref, scale, n_hat, True


@njit(cache=True)
def _drift_check_kernel(xs, center, radius, alpha):
    """Per free-drift sample: distance to the KOZ centre and g = hdot + alpha h (eq. 28), with the same
    arithmetic as np.linalg.norm / KeepOutSphere.cbf_value; returns (min dist, min g, dist, g)."""
    F = xs.shape[0]
    dist = np.empty(F)
    g = np.empty(F)
    for f in range(F):
        d0, d1, d2 = xs[f, 0] - center[0], xs[f, 1] - center[1], xs[f, 2] - center[2]
        dd = d0 * d0 + d1 * d1 + d2 * d2
        dist[f] = math.sqrt(dd)
        g[f] = 2.0 * (d0 * xs[f, 3] + d1 * xs[f, 4] + d2 * xs[f, 5]) + alpha * (dd - radius * radius)
    return dist, g



@njit(cache=True)
def _drift_verdict_kernel(xs, center, radius, alpha, d_ok, g_ok):
    """:func:`_drift_check_kernel` and its verdict in one pass: (all dist >= d_ok and all g >= g_ok,
    min g, min dist) with numpy's min (NaN if any value is NaN; a NaN fails the verdict)."""
    dist, g = _drift_check_kernel(xs, center, radius, alpha)
    ok = True
    g_min = math.inf
    d_min = math.inf
    nan_g = False
    nan_d = False
    for f in range(dist.shape[0]):
        d, gf = dist[f], g[f]
        if not (d >= d_ok and gf >= g_ok):
            ok = False
        if d != d:
            nan_d = True
        elif d < d_min:
            d_min = d
        if gf != gf:
            nan_g = True
        elif gf < g_min:
            g_min = gf
    if nan_d:
        d_min = math.nan
    if nan_g:
        g_min = math.nan
    return ok, g_min, d_min


@njit(cache=True)
def _csc_matvec(indptr, indices, data, n_rows, z):
    """A z for a CSC matrix, column by column (scipy's csc_matvec order: the same sums)."""
    y = np.zeros(n_rows)
    for j in range(indptr.shape[0] - 1):
        zj = z[j]
        for q in range(indptr[j], indptr[j + 1]):
            y[indices[q]] += data[q] * zj
    return y


@njit(cache=True)
def _max_violation_kernel(a_ptr, a_idx, a_val, b_eq, g_ptr, g_idx, g_val, g_lo, g_hi, lb, ub, z):
    """_Qp.max_violation in one pass: max of |A_eq z - b_eq|, the row excess of G z over [g_lo, g_hi]
    and the bound excess of z over [lb, ub] (0 when nothing is violated)."""
    worst = 0.0
    eq = _csc_matvec(a_ptr, a_idx, a_val, b_eq.shape[0], z)
    for r in range(b_eq.shape[0]):
        worst = max(worst, abs(eq[r] - b_eq[r]))
    gz = _csc_matvec(g_ptr, g_idx, g_val, g_lo.shape[0], z)
    for r in range(g_lo.shape[0]):
        worst = max(worst, g_lo[r] - gz[r], gz[r] - g_hi[r])
    for k in range(z.shape[0]):
        worst = max(worst, lb[k] - z[k], z[k] - ub[k])
    return worst


@dataclass
class NodeSchedule:
    """MPC nodes on the engine grid: node ``j`` is engine step ``steps[j]`` (t = steps[j] dt).
    ``hop_nodes[m]`` is the node where hop m+1 ends (the last one is the terminal node N)."""

    dt: float
    steps: np.ndarray  # (N+1,) int, increasing, steps[0] = 0
    hop_nodes: np.ndarray  # (n_hops,) int indices into steps

    @property
    def times(self) -> np.ndarray:
        return self.steps * self.dt

    @property
    def n(self) -> int:
        return len(self.steps) - 1


def build_schedule(hop_durations_s, steps_per_hop: int, dt: float) -> NodeSchedule:
    """Nodes: each hop duration rounded to whole engine steps ``dt`` and split into
    ``steps_per_hop`` MPC intervals (as equal as the engine grid allows)."""
    durations = np.asarray(hop_durations_s, dtype=float)
    if steps_per_hop < 1:
        raise input_error("mpc.steps_per_hop", steps_per_hop, "must be >= 1")
    steps, hop_nodes, k0 = [0], [], 0
    for n_eng in hop_engine_steps(durations, steps_per_hop, dt):
        offsets = np.round(np.linspace(0, n_eng, steps_per_hop + 1)).astype(int)[1:]
        steps += list(k0 + offsets)
        k0 += n_eng
        hop_nodes.append(len(steps) - 1)
    return NodeSchedule(float(dt), np.array(steps, dtype=int), np.array(hop_nodes, dtype=int))


@dataclass
class _Qp:
    """``min 1/2 z'Pz + q'z  s.t.  A_eq z = b_eq,  g_lo <= G z <= g_hi,  lb <= z <= ub``."""

    P: sp.csc_matrix
    q: np.ndarray
    A_eq: sp.csc_matrix
    b_eq: np.ndarray
    G: sp.csc_matrix
    g_lo: np.ndarray
    g_hi: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    n_imp: int  # impulses in this horizon (N - i + 1)

    def as_form(self) -> QuadraticProgram:
        """Canonical QP with explicit equality rows (fixed row structure for in-place updates)."""
        return QuadraticProgram(self.P, self.q, self.G, self.g_lo, self.g_hi, self.lb, self.ub, self.A_eq, self.b_eq)

    def as_program(self) -> QuadraticProgram:
        A = sp.vstack([self.A_eq, self.G], format="csc")
        return QuadraticProgram(self.P, self.q, A, np.concatenate([self.b_eq, self.g_lo]),
                                np.concatenate([self.b_eq, self.g_hi]), self.lb, self.ub)

    def max_violation(self, z: np.ndarray) -> float:
        """Largest violation of any row or bound at ``z`` (scaled units); one jitted pass for a finite ``z``
        (:func:`_max_violation_kernel`: the matrix products in scipy's order, the same maximum)."""
        z = np.asarray(z, dtype=float)
        if np.isfinite(z).all():
            A, G = self.A_eq, self.G
            return float(_max_violation_kernel(A.indptr, A.indices, A.data, self.b_eq, G.indptr, G.indices, G.data,
                                               self.g_lo, self.g_hi, self.lb, self.ub, z))
        eq = np.abs(self.A_eq @ z - self.b_eq)
        gz = self.G @ z
        with np.errstate(invalid="ignore"):
            ineq = np.maximum(np.maximum(self.g_lo - gz, gz - self.g_hi), 0.0)
            bnd = np.maximum(np.maximum(self.lb - z, z - self.ub), 0.0)
        return float(max(eq.max(initial=0.0), ineq.max(initial=0.0), bnd.max(initial=0.0)))


@dataclass
class _Solve:
    u: np.ndarray | None  # (M, 3) impulses u_i..u_N (m/s) or None
    status: Status
    solve_time_s: float
    iterations: int = 0
    relax: int = 0
    cbf_min: float = math.nan
    drift_min_range_m: float = math.nan
    events: list = field(default_factory=list)


class _Samples:
    """Growing (time, value) samples in preallocated arrays (the drift invariant's navigation samples):
    ``values(t_lo)`` is the contiguous array of the values (those at times >= t_lo), whose mean is the mean
    numpy takes of the same values in a list (the same pairwise sum)."""

    def __init__(self, capacity: int = 256) -> None:
        self._t = np.empty(capacity)
        self._v = np.empty(capacity)
        self.n = 0

    def _room(self, extra: int) -> None:
        need = self.n + extra
        if need > self._t.size:
            size = max(need, 2 * self._t.size)
            self._t = np.concatenate([self._t[:self.n], np.empty(size - self.n)])
            self._v = np.concatenate([self._v[:self.n], np.empty(size - self.n)])

    def append(self, t: float, v: float) -> None:
        self._room(1)
        self._t[self.n] = t
        self._v[self.n] = v
        self.n += 1

    def extend(self, t: np.ndarray, v: np.ndarray) -> None:
        m = len(t)
        self._room(m)
        self._t[self.n:self.n + m] = t
        self._v[self.n:self.n + m] = v
        self.n += m

    def clear(self) -> None:
        self.n = 0

    def values(self, t_lo: float | None = None) -> np.ndarray:
        v = self._v[:self.n]
        return v if t_lo is None else v[self._t[:self.n] >= t_lo]


class SrfMpc:
    """SRF MPC controller (Controller protocol) issuing impulses at its nodes.

    mean_motion: n (rad/s) of the CW model; schedule: MPC nodes on the engine grid;
    axis_hill: approach direction a (unit, Hill, from the target towards the start);
    perp_hill: in-plane perpendicular b of eq. (20) in Hill; target_hill: p_d (m, Hill);
    keep_out: KeepOutSphere (Hill) or None; config: SrfMpcConfig.
    """

    def __init__(self, mean_motion: float, schedule: NodeSchedule, axis_hill, perp_hill, target_hill,
                 keep_out: KeepOutSphere | None, config: SrfMpcConfig | None = None, hop_distances_m=None):
        self.n_orb = float(mean_motion)
        self.sched = schedule
        self.dt = schedule.dt
        self.cfg = config or SrfMpcConfig()
        self.a = np.asarray(axis_hill, dtype=float)
        self.b = np.asarray(perp_hill, dtype=float)
        self.p_d = np.asarray(target_hill, dtype=float)
        self.koz = keep_out
        c = self.cfg
        if not (c.u_max_mps > 0 and math.isfinite(c.u_max_mps)):
            raise input_error("mpc.u_max_mps", c.u_max_mps, "must be finite and > 0", "m/s")
        if keep_out is not None and keep_out.contains(self.p_d):
            raise input_error("reference point", self.p_d.tolist(),
                              f"lies inside the keep-out zone (radius {keep_out.radius_m:g} m): move it out or shrink the KOZ", "m")
        # ---- prediction blocks, built once for the whole node grid (sliced per horizon length)
        self._phi, self._S = _prediction_blocks(self.n_orb, schedule.times)
        # free-drift grid (29h-i) and its STMs
        period = 2 * math.pi / self.n_orb
        span = c.free_drift_s if c.free_drift_s is not None else period
        self.tau = np.linspace(span / c.free_drift_nodes, span, c.free_drift_nodes)
        self._phi_tau = _drift_stms(self.n_orb, self.tau)
        self._node_of_step = {int(s): j for j, s in enumerate(schedule.steps)}
        self._hop_boundaries = [0] + schedule.hop_nodes.tolist()  # node 0 and every hop end
        self._hop_node_set = set(schedule.hop_nodes.tolist())
        self.drift_model = c.drift_model
        self.hop_targets_m = None  # guidance distances d_0..d_n (m) for hop_distance_tol_m
        if c.hop_distance_tol_m is not None or c.hop_distance_weight_per_m2 > 0:
            if hop_distances_m is None or len(hop_distances_m) != len(schedule.hop_nodes) + 1:
                raise input_error("hop_distances_m", hop_distances_m, "give the n_hops + 1 guidance distances "
                                  "when hop_distance_tol_m is set", "m")
            self.hop_targets_m = np.asarray(hop_distances_m, dtype=float)
        # hop-start nodes (node 0 and every hop end but the last): drift-free rows; with a drift trim also
        # the trim node of every hop start (delay nodes later, before that hop's end)
        hop_starts = [0] + schedule.hop_nodes[:-1].tolist()
        self.trim_nodes: dict[int, int] = {}  # trim node -> its hop-start node
        if c.drift_trim_delay_nodes is not None and c.drift_free_tol_mps is not None:
            d = int(c.drift_trim_delay_nodes)
            for h, end in zip(hop_starts, schedule.hop_nodes.tolist()):
                check_trim_delay(d, h, end)
                self.trim_nodes[h + d] = h
        if c.drift_estimator_window_s is not None and not c.drift_estimator_window_s > 0:
            raise input_error("mpc.drift_estimator_window_s", c.drift_estimator_window_s, "must be > 0", "s")
        self.drift_nodes = np.array(sorted(hop_starts + list(self.trim_nodes)), dtype=int)
        # nodes after a trim and before the next hop start (or the terminal node): impulses keep c
        self.hold_nodes = []
        if self.trim_nodes and c.drift_hold_after_trim:
            for t_node, h in self.trim_nodes.items():
                end = int(schedule.hop_nodes[np.searchsorted(schedule.hop_nodes, h, side="right")])
                self.hold_nodes += [(j, t_node) for j in range(t_node + 1, end)]
        self.hold_nodes = sorted(self.hold_nodes)  # (node j, its trim node)
        # last node whose drift gain a row uses (_drift_gains) and the gravity parameters of drift_model
        self._drift_last = min(int(max([self.drift_nodes.max()] + [j for j, _ in self.hold_nodes])), schedule.n)
        self._drift_params = self.drift_model._params() if self.drift_model is not None else None
        self._layout()
        pdiag = np.zeros(self._nz)
        pdiag[self._ie:self._ie + 3] = c.q_terminal_per_m2 * KM**2
        pdiag[self._ir:] = c.hop_distance_weight_per_m2 * KM**2
        self._P = sp.diags(pdiag, format="csc")
        weight = np.full(self.sched.n + 1, c.mid_hop_fuel_weight)
        weight[0] = 1.0
        weight[self.sched.hop_nodes] = 1.0
        per_u = np.repeat(weight, 3) * c.r_fuel * c.u_max_mps
        self._c = np.r_[per_u, per_u, np.zeros(6 + self._n_r)]
        if self._n_r:  # 1/2 w (r_m - d_m)^2 -> linear term -w d_m (km)
            self._c[self._ir:] = -c.hop_distance_weight_per_m2 * KM**2 * self.hop_targets_m[1:] / KM
        self.reset(0.0, np.zeros(6))

    # ------------------------------------------------------------------ protocol
    def reset(self, t0: float, x0) -> None:
        N = self.sched.n
        self.plan = np.zeros((N + 1, 3))  # latest plan of every node's impulse (m/s)
        self.used_l1 = 0.0
        self.rx_hist: dict[int, float] = {0: float(self.a @ np.asarray(x0, dtype=float)[:3])}
        self.finished = False
        self.last_drift = None  # (tau, states) of the last accepted free drift
        self.solve_log: list[dict] = []
        self._c_samples = _Samples()  # navigation samples of c since the last impulse: times (s), values (m/s)
        self.trim_log: list[dict] = []  # per trim node: t, samples used, estimate of c, trim impulse

    def drift_estimate(self, t: float, x) -> tuple[float, int]:
        """Least-squares estimate of the drift invariant c (m/s) and the number of samples behind it.

        c is a constant of the free motion, so the least-squares fit of the navigation samples taken
        since the last impulse (within ``drift_estimator_window_s`` of ``t`` if set) is their mean;
        its error is the single-sample error / sqrt(samples) for white navigation noise (0.5 m /
        0.5 mm/s per axis: 1.0 mm/s per sample). Without samples: the invariant of ``x``."""
        w = self.cfg.drift_estimator_window_s
        vals = self._c_samples.values(None if w is None else t - w - 1e-9)
        if not vals.size:
            return self.drift_invariant(t, x), 1
        return float(vals.mean()), int(vals.size)

    def drift_invariant(self, t: float, x) -> float:
        """c (m/s): constant on the free motion, zero for a drift-free one (CW: vy + 2 n x)."""
        if self.drift_model is not None:
            return self.drift_model.invariant(t, x)
        return float(x[4] + 2.0 * self.n_orb * x[0])

    def _drift_gains(self, i: int, x: np.ndarray) -> np.ndarray:
        """k_l (N+1, 3): change of c per unit impulse at node l (Hill), zero before node i. CW: e_y;
        drift_model: at the chaser state predicted from x with the previous plan's impulses."""
        N = self.sched.n
        k = np.zeros((N + 1, 3))
        if self.drift_model is None:
            k[i:, 1] = 1.0
            return k
        last = self._drift_last
        if last < i:
            return k
        plan = self.plan.copy()
        plan[:i] = 0.0
        flat = plan.ravel()
        xs = np.empty((last - i + 1, 6))
        xs[0] = x
        if last > i:  # predicted states at nodes i+1..last, then their gains in one jitted call
            xs[1:] = np.einsum("lij,j->li", self._phi[i + 1:last + 1, i], x) + self._S[i + 1:last + 1] @ flat

        every = self._per_node.get("targets")
        if every is None:  # the target states at nodes 0..last (EnergyDrift._targets), once; rows i..last are node i's
            try:
                every = self.drift_model._targets(self.sched.times[:last + 1])
            except ProxopsInputError:
                every = False  # a node off the ephemeris grid: each node's own call raises when it is reached
            self._per_node["targets"] = every
        if every is False:
            targets = self.drift_model._targets(self.sched.times[i:last + 1])
        else:
            targets = every[i:last + 1]
        k[i:last + 1] = energy_gains(targets, xs, self._drift_params)  # = drift_model.gains(times, xs)
        return k

    def _drift_gain_at(self, i: int, x: np.ndarray) -> np.ndarray:
        """Row i of :meth:`_drift_gains` (i, x): the gain at the current state alone (the same kernel on the same
        row; the predicted rows after it are not needed)."""
        if self.drift_model is None:
            return np.array([0.0, 1.0, 0.0])
        if self._drift_last < i:
            return np.zeros(3)
        every = self._per_node.get("targets")
        target = every[i:i + 1] if every is not None and every is not False else \
            self.drift_model._targets(self.sched.times[i:i + 1])
        xs = np.empty((1, 6))
        xs[0] = x
        return energy_gains(target, xs, self._drift_params)[0]

    def step(self, t: float, x_est) -> Command:
        x = np.asarray(x_est, dtype=float)
        if self.cfg.drift_free_tol_mps is not None and x.size == 6 and np.all(np.isfinite(x)):
            self._c_samples.append(float(t), self.drift_invariant(t, x))
        k = int(round(t / self.dt))
        N = self.sched.n
        if k > self.sched.steps[-1] or self.finished:
            return Command(np.zeros(3), "impulse", Status.OK, mode="handover", stop=True)
        node = self._node_of_step.get(k)
        hop = int(np.searchsorted(self.sched.hop_nodes, node if node is not None else self._node_before(k), side="right")) + 1
        mode = "brake" if node == N else f"hop {min(hop, len(self.sched.hop_nodes))}"
        if node is None:
            return Command(np.zeros(3), "impulse", Status.OK, mode=mode, info={"solved": 0.0})
        if node in self._hop_node_set:
            self.rx_hist[node] = float(self.a @ x[:3])
        res = self._solve_node(node, x)
        events = list(res.events)
        if res.u is None:
            u = self._fallback(node, x)
            events.append(("fallback", f"node {node}: {res.status}; applied {'previous plan' if np.any(u) else 'no impulse'}"))
        else:
            u = res.u[0]
            self.plan[node:] = res.u
        u = np.where(np.abs(u) < 1e-7, 0.0, u)
        if node in self.trim_nodes:
            c_hat, n_samples = self.drift_estimate(t, x)
            if res.u is not None and res.relax < 3:
                u = self._lift_to_impulse_bit(node, x, u)
                self.plan[node] = u
            self.trim_log.append({"t": float(t), "node": int(node), "hop_start_node": self.trim_nodes[node],
                                  "samples": n_samples, "c_estimate_mps": c_hat, "u": u.copy()})
        self.used_l1 += float(np.abs(u).sum())
        if np.any(u) and float(np.linalg.norm(u)) >= self.cfg.min_impulse_mps:  # below the bit nothing fires
            self._c_samples.clear()
        if node == N:
            self.finished = True
        info = {"solved": 1.0, "node": float(node), "relax": float(res.relax), "qp_iterations": float(res.iterations),
                "cbf_min": res.cbf_min, "drift_min_range_m": res.drift_min_range_m}
        self.solve_log.append({"t": t, "node": node, "status": res.status, "u": u.copy(), **info})
        if node == N:
            return Command(u, "impulse", res.status, res.solve_time_s, mode, events, info)
        # between nodes every step returns this idle command (no impulse) and only samples the drift
        # invariant: the engine may skip those steps and hand the samples to observe_coast
        idle = Command(np.zeros(3), "impulse", Status.OK, mode=mode, info={"solved": 0.0})
        return Command(u, "impulse", res.status, res.solve_time_s, mode, events, info,
                       next_decision_s=float(self.sched.times[node + 1]), idle=idle)

    def observe_coast(self, t, x_est) -> None:
        """The estimates of the steps the engine skipped between nodes (engine hook): sampled into
        the drift invariant's samples exactly as :meth:`step` samples them (same values, same order)."""
        if self.cfg.drift_free_tol_mps is None:
            return
        xs = np.asarray(x_est, dtype=float)
        if xs.shape[1] != 6:
            return
        ok = np.all(np.isfinite(xs), axis=1)
        times = np.asarray(t, dtype=float)[ok]
        if self.drift_model is not None:
            values = self.drift_model.invariants(times, xs[ok])
        else:
            values = np.array([float(x[4] + 2.0 * self.n_orb * x[0]) for x in xs[ok]])
        self._c_samples.extend(times, values)

    def drift_band(self) -> tuple[float, float]:
        """Band (m/s) of the drift invariant c after a hop-start or trim impulse: ONE-SIDED, on the side of a
        free drift away from the target. The secular along-track motion is -3 c per unit time
        (CW: y(t) has -3 (vy0 + 2 n x0) t), so the chaser at d a (d > 0 along the approach axis a) drifts away
        when c a_y < 0: with s = -sign(a_y), s c in [b, b + 2 tol] (b = ``drift_outward_mps``, tol =
        ``drift_free_tol_mps``; the same width as the two-sided |c| <= tol it replaces)."""
        c = self.cfg
        s = -1.0 if self.a[1] > 0 else 1.0
        lo, hi = c.drift_outward_mps, c.drift_outward_mps + 2.0 * c.drift_free_tol_mps
        return (lo, hi) if s > 0 else (-hi, -lo)

    def _lift_to_impulse_bit(self, node: int, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """A trim below the thrusters' minimum impulse bit would fire nothing and leave its drift (up
        to 3 bit t_orb of along-track drift per orbit, 22 m for 1 mm/s at a = 8100 km). Raise it to the
        bit by adding a component perpendicular to the invariant's gain k and to u (out of plane for
        a V-bar trim along y): c changes by k . u as planned; the extra component costs at most the
        bit and leaves a cross-track oscillation of amplitude <= bit / n (CW: z decouples; 1.2 m for
        1 mm/s). Not raised when the trim changes c by less than the row's tolerance (the drift left is
        then below 2 tol: a bit of propellant would buy less than the tolerance); kept only if the
        raised impulse's free drift passes the true KOZ/CBF check."""
        bit = self.cfg.min_impulse_mps
        norm = float(np.linalg.norm(u))
        if bit <= 0.0 or norm == 0.0 or norm >= bit:
            return u
        k = self._drift_gain_at(node, x)
        lo, hi = self.drift_band()
        c_now = self.drift_estimate(float(self.sched.times[node]), x)[0]
        if abs(float(k @ u)) <= self.cfg.drift_free_tol_mps and lo <= c_now <= hi:
            return u  # firing nothing leaves c inside the (outward) band
        basis = []
        for v in (k, u):
            v = v - sum((v @ e) * e for e in basis)
            if np.linalg.norm(v) > 1e-12:
                basis.append(v / np.linalg.norm(v))
        d = np.array([0.0, 0.0, 1.0])
        d = d - sum((d @ e) * e for e in basis)
        if np.linalg.norm(d) < 1e-6:
            return u
        d /= np.linalg.norm(d)
        lifted = u + d * math.sqrt((bit * (1.0 + 1e-6)) ** 2 - norm**2)
        if self.koz is not None and not self.check_drift(x, lifted)[0]:
            return u
        return lifted

    def _node_before(self, k: int) -> int:
        return int(np.searchsorted(self.sched.steps, k, side="right")) - 1

    # ------------------------------------------------------------------ QP
    # Variables z = [z+ (3(N+1)), z- (3(N+1)), w (3), e (3)]: u_l = u_max (z+_l - z-_l) for every
    # node of the mission (impulses of past nodes are fixed to 0 by their bounds), w = u_i / u_max
    # the impulse of the current node (the only one the CBF rows see), e = (p_N - p_d) / 1 km.
    # With this layout every matrix keeps one sparsity pattern for the whole mission: only the
    # CBF rows, the w-selection row values, right-hand sides and bounds change, so one PIQP
    # solver is set up once and updated in place (its symbolic factorisation is reused).
    def _layout(self) -> None:
        c, N = self.cfg, self.sched.n
        nu = 3 * (N + 1)
        self._nu = nu
        self._iw = 2 * nu
        self._ie = 2 * nu + 3
        self._ir = 2 * nu + 6
        n_r = len(self.sched.hop_nodes) if c.hop_distance_weight_per_m2 > 0 else 0
        self._n_r = n_r
        self._nz = 2 * nu + 6 + n_r
        um = c.u_max_mps

        def zcoef(row_u):  # coefficients on u (..., nu) -> z (..., nz)
            out = np.zeros(row_u.shape[:-1] + (self._nz,))
            out[..., :nu] = row_u * um
            out[..., nu:2 * nu] = -row_u * um
            return out

        S_N = self._S[N]
        # equality rows: terminal position error (3), then w = z+_i - z-_i (3; values set per node)
        eq = zcoef(S_N[:3] / KM)
        eq[:, self._ie:self._ie + 3] = -np.eye(3)
        wsel = np.zeros((3, self._nz))
        for k in range(3):
            wsel[k, k:nu:3] = 1.0  # pattern on every impulse of axis k (explicit zeros kept)
            wsel[k, nu + k:2 * nu:3] = 1.0
            wsel[k, self._iw + k] = 1.0
        # hop-end positions r_m = a . p(J_m) / km (only with a hop-distance preference)
        if n_r:
            rdef = np.vstack([zcoef(-self.a @ self._S[int(j)][:3] / KM) for j in self.sched.hop_nodes])
            rdef[:, self._ir:self._ir + n_r] = np.eye(n_r)
            eq = np.vstack([eq, rdef])
        # inequality rows with constant coefficients
        rows, kinds = [], []
        brake = S_N[3:].copy()
        brake[:, 3 * N:] += np.eye(3)
        rows.append(zcoef(brake)); kinds += ["brake"] * 3
        for j in self.sched.hop_nodes:
            Sj = self._S[int(j)]
            rows.append(zcoef(self.b @ Sj[:3] / KM)[None]); kinds.append(("hop_r", int(j)))
            rows.append(zcoef(self.a @ Sj[3:])[None]); kinds.append(("hop_w", int(j)))
        if c.drift_free_tol_mps is not None:
            for j in self.drift_nodes:
                # c after node j's impulse: sum of k_l . u_l over l <= j. Full pattern (placeholders);
                # the values are set per solve (k_l depends on the predicted chaser state with drift_model)
                row = np.zeros(3 * (N + 1))
                row[:3 * (int(j) + 1)] = 1.0
                rows.append(zcoef(row)[None]); kinds.append(("drift", int(j)))
            for j, t_node in self.hold_nodes:  # |sum_{t_node < l <= j} k_l . u_l| <= tol: c stays as trimmed
                row = np.zeros(3 * (N + 1))
                row[3 * (t_node + 1):3 * (j + 1)] = 1.0
                rows.append(zcoef(row)[None]); kinds.append(("hold", int(j)))
        if c.vbar_rows or c.hop_distance_tol_m is not None:
            nodes = [0] + self.sched.hop_nodes.tolist()
            rx = [self.a @ self._S[j][:3] for j in nodes]
            if c.hop_distance_tol_m is not None:
                for m in range(1, len(nodes)):
                    rows.append(zcoef(rx[m] / KM)[None]); kinds.append(("dist", m))
            if c.vbar_rows:
                for m in range(1, len(nodes)):
                    rows.append(zcoef((rx[m - 1] - rx[m]) / KM)[None]); kinds.append(("len", m))
                for m in range(1, len(nodes) - 1):
                    d = (rx[m] - rx[m + 1]) - (rx[m - 1] - rx[m])
                    rows.append(zcoef(d / KM)[None]); kinds.append(("dec", m))
        if math.isfinite(c.u_budget_mps):
            budget = np.zeros(self._nz)
            budget[:2 * nu] = um
            rows.append(budget[None]); kinds.append("budget")
        g_static = np.vstack(rows)
        self._g_kinds = kinds
        self._n_cbf = len(self.tau) if (c.cbf and self.koz is not None) else 0
        self._solver = None
        # fixed sparsity patterns (COO, explicit zeros kept): static rows, then per-node rows
        r, col = np.nonzero(eq)
        self._eq_coo = (r, col, eq[r, col])
        r, col = np.nonzero(wsel)
        self._wsel_coo = (r + eq.shape[0], col)
        self._n_eq = eq.shape[0] + 3
        # values of [eq entries, w-selection entries] at node i (SrfMpc._build): the entry of row k on column
        # 3 i + k (z+_i) is -1, on nu + 3 i + k (z-_i) +1, on the w columns 1, else 0
        wr_k, wc_ = r, col
        base = np.concatenate([self._eq_coo[2], np.where(wc_ >= self._iw, 1.0, 0.0)])
        where = {(int(k), int(cc)): q + len(self._eq_coo[2]) for q, (k, cc) in enumerate(zip(wr_k, wc_))}
        minus = np.array([[where[(k, 3 * i + k)] for k in range(3)] for i in range(N + 1)], dtype=np.intp)
        plus = np.array([[where[(k, nu + 3 * i + k)] for k in range(3)] for i in range(N + 1)], dtype=np.intp)
        base.flags.writeable = False
        self._eq_template = (base, minus, plus)
        r, col = np.nonzero(g_static)
        self._g_coo = (r, col, g_static[r, col])
        # entries of the drift rows: value = sign * u_max * k_l[comp] for column (sign, l, comp)
        drift_rows = [m + 3 for m, kd in enumerate(kinds[3:]) if isinstance(kd, tuple) and kd[0] in ("drift", "hold")]
        sel = np.nonzero(np.isin(r, drift_rows))[0]
        ucol = np.where(col[sel] < nu, col[sel], col[sel] - nu)
        self._drift_coo = (sel, ucol // 3, ucol % 3, np.where(col[sel] < nu, um, -um))
        self._n_g_static = g_static.shape[0]
        F = self._n_cbf
        self._cbf_rows = np.repeat(np.arange(2 * F), 3) + self._n_g_static
        self._cbf_cols = np.tile(np.arange(self._iw, self._iw + 3), 2 * F)
        self._csc_patterns: dict[str, tuple] = {}  # fixed CSC patterns of A_eq and G (see _csc)
        self._g_dynamic: dict[str, tuple] = {}  # CSC positions of G's per-build entries (see _g_matrix)
        self._inf_tail = np.full(2 * F, np.inf)  # upper bounds of the CBF rows
        self._inf_tail.flags.writeable = False
        self._koz_off_centre = self.koz is not None and bool(np.any(self.koz.center_m))
        self._per_node: dict = {}  # A_eq values and variable bounds, which depend on the node only (see _build)
        # index maps of the rows whose bounds depend on the node (see _row_bounds): row numbers and
        # node (or hop) of every kind, so one build sets them with array operations
        by_tag: dict[str, tuple[list, list]] = {}
        for row, kd in enumerate(kinds):
            if isinstance(kd, tuple):
                by_tag.setdefault(kd[0], ([], []))
                by_tag[kd[0]][0].append(row)
                by_tag[kd[0]][1].append(kd[1])
        self._row_sets = {tag: (np.array(r_, dtype=np.intp), np.array(j_, dtype=np.intp)) for tag, (r_, j_) in by_tag.items()}
        self._budget_row = kinds.index("budget") if "budget" in kinds else None
        if self._budget_row not in (None, len(kinds) - 1):
            raise AssertionError("the budget row is the last row with constant coefficients")

        def rows_of(tag):
            return self._row_sets.get(tag, (_NO_ROWS, _NO_ROWS))

        targets = self.hop_targets_m if self.hop_targets_m is not None else np.zeros(0)
        dist_tol = np.asarray(c.hop_distance_tol_m if c.hop_distance_tol_m is not None else [], dtype=float)
        self._row_args = (rows_of("hop_r")[0], rows_of("hop_w")[0], rows_of("hop_r")[1], *rows_of("drift"),
                          *rows_of("hold"), *rows_of("dist"), *rows_of("len"), *rows_of("dec"), targets, dist_tol)
        self._n_rows_static = len(kinds)
        self._drift_js_max = int(rows_of("drift")[1].max()) if rows_of("drift")[1].size else -1
        self._boundaries = np.array(self._hop_boundaries, dtype=np.intp)

    def _csc(self, key: str, entries, shape: tuple[int, int], values: np.ndarray) -> sp.csc_matrix:
        """CSC matrix of ``values`` on the fixed pattern ``entries`` = (rows, cols) (or a callable
        giving them), the same matrix as ``sp.csc_matrix((values, entries), shape)``: the entries
        are distinct, so the COO -> CSC conversion only permutes them; the permutation and the CSC
        matrix are made once per pattern (``key``) and each build only gathers the values into that
        matrix's data in place (no scipy construction per solve). The matrix is therefore shared by
        every build of the pattern: a build's QP is used (solved, checked) before the next build."""
        tmpl = self._csc_patterns.get(key)
        if tmpl is None:
            rows, cols = entries() if callable(entries) else entries
            rows = np.ascontiguousarray(rows, dtype=np.intp)
            cols = np.ascontiguousarray(cols, dtype=np.intp)

            def pattern():  # (perm, indices, indptr), shared read-only by every controller with this pattern
                probe = sp.csc_matrix((np.arange(1.0, len(rows) + 1.0), (rows, cols)), shape=shape)
                if probe.nnz != len(rows):
                    raise AssertionError(f"{key}: repeated entries in a fixed QP pattern")
                return probe.data.astype(np.intp) - 1, probe.indices, probe.indptr

            perm, indices, indptr = memo_get(_PATTERN_CACHE, (shape, rows.tobytes(), cols.tobytes()), pattern,
                                             read_only=True)
            # the pattern is fixed and read-only: solver adapters may rely on it (PiqpQP.update_fast)
            mat = sp.csc_matrix((np.empty(len(perm)), indices, indptr), shape=shape, copy=False)
            mat.has_sorted_indices = True
            mat.has_canonical_format = True
            tmpl = self._csc_patterns[key] = (perm, mat)
        perm, mat = tmpl
        np.take(values, perm, out=mat.data, mode="clip")  # indices in range: no buffered copy (mode "raise" makes one)
        return mat

    def _g_matrix(self, drift_values: np.ndarray | None, half: np.ndarray | None, lin: np.ndarray | None) -> sp.csc_matrix:
        """G of :meth:`_build` (rows with constant coefficients, then the CBF rows when ``half`` and ``lin`` are
        given), the same matrix as :meth:`_csc` of the full COO values ``[gv with the drift entries set,
        half.ravel(), lin.ravel()]``: the first build of each pattern gathers them all; later builds write
        only the entries that change (drift gains, CBF rows) at their CSC positions, since the other values
        of the shared matrix are the constant ones that build wrote."""
        gr, gc, gv = self._g_coo
        key = "G" if half is None else "G_cbf"
        dynamic = self._g_dynamic.get(key)
        if dynamic is None:
            sel = self._drift_coo[0]
            values = gv.copy()
            if drift_values is not None:
                values[sel] = drift_values
            if half is None:
                mat = self._csc(key, (gr, gc), (self._n_g_static, self._nz), values)
            else:
                values = np.concatenate([values, half.ravel(), lin.ravel()])
                mat = self._csc(key, (np.concatenate([gr, self._cbf_rows]), np.concatenate([gc, self._cbf_cols])),
                                (self._n_g_static + 2 * self._n_cbf, self._nz), values)
            perm = self._csc_patterns[key][0]
            at = np.empty_like(perm)
            at[perm] = np.arange(len(perm))  # CSC position of every COO entry
            n_half = 3 * self._n_cbf
            self._g_dynamic[key] = (at[sel], at[len(gv):len(gv) + n_half], at[len(gv) + n_half:])
            return mat
        mat = self._csc_patterns[key][1]
        at_drift, at_half, at_lin = dynamic
        if drift_values is not None:
            mat.data[at_drift] = drift_values
        if half is not None:
            mat.data[at_half] = half.ravel()
            mat.data[at_lin] = lin.ravel()
        return mat

    def _row_bounds(self, i: int, x: np.ndarray, relax: int, fN: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bounds (g_lo, g_hi) of the rows with constant coefficients at node ``i`` (scaled units) and the
        constant part of a . p at node 0 and every hop end (m: the prediction a . (Phi(t_j - t_i) x)[:3] for a node
        ahead, else the recorded value, else a . p now), one jitted call on the
        index maps of :meth:`_layout` (:func:`_row_bounds_kernel`): the brake box (29d), hop rows
        (29l)-(29m), drift and hold rows, hop distances, (29n)-(29o) and the budget (29g); rows of past
        nodes or relaxed rows are switched off to +-OFF."""
        c = self.cfg
        nodes = self._boundaries
        ax = float(self.a @ x[:3])  # a . p now: the value of a past node without a record
        rx_past = np.array([self.rx_hist.get(int(j), ax) if j <= i else 0.0 for j in nodes])
        drift = (math.nan, math.nan)
        d_rows, d_js = self._row_sets.get("drift", (_NO_ROWS, _NO_ROWS))
        if relax < 3 and d_js.size and self._drift_js_max >= i:  # the same estimate for every drift row of this node
            v = self.drift_estimate(float(self.sched.times[i]), x)[0]
            c_lo, c_hi = self.drift_band()
            drift = (c_lo - v, c_hi - v)
        budget = max(c.u_budget_mps - self.used_l1, 0.0) if self._budget_row is not None else math.nan
        tol = np.array([c.r_tol_m, c.w_tol_mps, *drift,
                        c.drift_free_tol_mps if c.drift_free_tol_mps is not None else math.nan,
                        c.h_min_m, c.h_max_m, c.epsilon_m, budget, c.terminal_vel_tol_mps])
        return _row_bounds_kernel(self._phi, i, np.ascontiguousarray(x, dtype=float), relax, self.a, self.b, fN,
                                  rx_past, nodes, *self._row_args, tol, self._n_rows_static, OFF)

    def _build(self, i: int, x: np.ndarray, u_ref: np.ndarray | None, relax: int, with_cbf: bool = True) -> _Qp:
        c, N, nu, nz = self.cfg, self.sched.n, self._nu, self._nz
        um = c.u_max_mps
        fN = self._phi[N, i] @ x
        # equalities: terminal error rows (static) and w = z+_i - z-_i (values depend on i only)
        wr, wc = self._wsel_coo
        er, ec, ev = self._eq_coo
        eq_values = self._per_node.get(("eq", i))
        if eq_values is None:  # [ev, w-selection row values]: 1 on w, -1 on z+_i, +1 on z-_i, 0 elsewhere
            base, minus, plus = self._eq_template
            eq_values = base.copy()
            eq_values[minus[i]] = -1.0
            eq_values[plus[i]] = 1.0
            self._per_node[("eq", i)] = eq_values
        A_eq = self._csc("A_eq", lambda: (np.concatenate([er, wr]), np.concatenate([ec, wc])), (self._n_eq, nz),
                         eq_values)
        g_lo, g_hi, rxv = self._row_bounds(i, x, relax, fN)
        r_rhs = rxv[1:] / KM if self._n_r else []
        b_eq = np.concatenate([(self.p_d - fN[:3]) / KM, r_rhs, np.zeros(3)])
        drift_values = None
        if len(self._drift_coo[0]):
            _sel, node, comp, sign = self._drift_coo
            gains = self._drift_gains(i, x)
            drift_values = sign * gains[node, comp]
        n_cbf = self._n_cbf if with_cbf else 0
        half = lin = None
        if n_cbf:  # (29j) about the reference drift, one jitted pass (_cbf_rows_kernel)
            ur = np.zeros(3) if u_ref is None else u_ref
            koz = self.koz
            cx = self._phi_tau @ x  # (F, 6) drift without impulse
            xr = cx + self._phi_tau[:, :, 3:6] @ ur
            half, half_lo, lin, gu, g_ref, scale, n_hat, ok = _cbf_rows_kernel(
                self._phi_tau, cx, xr, koz.center_m, float(koz.radius_m), float(c.cbf_alpha_per_s), float(um),
                1e-12 * max(1.0, koz.radius_m))
            if not ok:  # a reference point at the KOZ centre: KeepOutSphere.halfspace's one-line error
                koz.halfspace(xr[:, :3])
            if self._koz_off_centre:  # b = r + n . c with numpy's sum (the kernel's is for c = 0)
                half_lo = (koz.radius_m + n_hat @ koz.center_m - np.einsum("fk,fk->f", n_hat, cx[:, :3])) / KM
            lin_lo = (gu @ ur - g_ref) / scale
            g_lo = np.concatenate([g_lo, half_lo, lin_lo])
            g_hi = np.concatenate([g_hi, self._inf_tail])
        boxed = relax < 2 and i < N
        bounds = self._per_node.get(("bounds", i, boxed))
        if bounds is None:  # depend on (i, boxed) only: made once, read-only
            lb = np.zeros(nz)
            ub = np.ones(nz)
            ub[:3 * i] = 0.0
            ub[nu:nu + 3 * i] = 0.0
            lb[self._iw:self._iw + 3], ub[self._iw:self._iw + 3] = -1.0, 1.0
            lb[self._ie:], ub[self._ie:] = -np.inf, np.inf
            if boxed:
                tol = c.terminal_pos_tol_m / KM
                lb[self._ie:self._ie + 3], ub[self._ie:self._ie + 3] = -tol, tol
            lb.flags.writeable = ub.flags.writeable = False
            bounds = self._per_node[("bounds", i, boxed)] = (lb, ub)
        lb, ub = bounds
        G = self._g_matrix(drift_values, half, lin)
        return _Qp(self._P, self._c, A_eq, b_eq, G, g_lo, g_hi, lb, ub, N - i + 1)
    def _run_solver(self, qp: _Qp, i: int, persistent: bool = True):
        """Solve with the persistent adapter of ``cfg.solver`` (``setup(problem)`` once, ``update``
        in place: the same calls for PIQP, Clarabel or DAQP; a one-shot solve for other sparsity
        patterns); Clarabel when the solver fails for any reason but a certified infeasibility.
        Returns (result, seconds)."""
        t0 = time.perf_counter()
        if persistent:
            if self._solver is None:
                # PIQP: normal solves take 20-35 iterations (at most 30 over the 4 730 solves of the three 50-run
                # srf campaigns, seed 1). On an infeasible problem PIQP 0.7 runs to max_iter; after 40
                # iterations its duals are checked as a Farkas certificate: a problem whose every point within
                # the bounds violates a row by more than feasibility_tol is reported infeasible without the
                # rest of the iterations and the Clarabel solve (no answer within the bounds could pass the check below).
                # The impulses of past nodes are fixed to 0 by their bounds: PIQP gets only the free
                # ones (drop_fixed; 4x faster on average over the shrinking horizon).
                settings = {"max_iter": 80, "certify_after": 40, "certify_margin": self.cfg.feasibility_tol,
                            "drop_fixed": True}
                self._solver = make_solver(qp.as_form(), self.cfg.solver,
                                           **(settings if self.cfg.solver == "piqp" else {}))
            elif self.cfg.solver == "piqp":  # PIQP's trusted path: this layout's fixed patterns, fresh vectors
                self._solver.update_fast(A=qp.A_eq, b=qp.b_eq, G=qp.G, h_l=qp.g_lo, h_u=qp.g_hi, x_lb=qp.lb, x_ub=qp.ub)
            else:
                self._solver.update(A_eq=qp.A_eq, b_eq=qp.b_eq, A=qp.G, bl=qp.g_lo, bu=qp.g_hi, lb=qp.lb, ub=qp.ub)
            res = self._solver.solve()
        else:
            res = solve_qp(qp.as_program(), self.cfg.solver)
        if (res.x is None or not res.ok) and res.status != SolveStatus.INFEASIBLE:
            fb = solve_qp(qp.as_program(), "clarabel")
            fb.info["primary"] = str(res.status)
            res = fb
        return res, time.perf_counter() - t0

    def _solve_node(self, i: int, x: np.ndarray) -> _Solve:
        """SCP on the CBF linearisation inside a relaxation ladder (see module doc)."""
        c = self.cfg
        self._clock = [0.0, 0]  # solver seconds, iterations
        events = []
        first_ref = self.plan[i].copy()
        if self.cfg.drift_free_tol_mps is not None and not np.any(first_ref):
            # no plan yet: the drift-free hold is much nearer the drift-free solution than a drifting
            # zero impulse, whose half-spaces gave 1.5 m/s detours from a dispersed start
            first_ref = self.hold_impulse(x)
        ref_safe = self._n_cbf == 0 or self.check_drift(x, first_ref)[0]
        if not ref_safe:
            hold = self.hold_impulse(x)
            if self.check_drift(x, hold)[0]:
                first_ref, ref_safe = hold, True  # linearise about a safe drift: half-spaces face the right way

        def attempt(relax: int) -> tuple[_Solve | None, Status]:
            sol, status = self._scp(i, x, first_ref, relax)
            # A reference whose drift is safe gives CBF rows that the reference itself satisfies, so an
            # infeasible problem is then blamed on the other rows (relax them); otherwise check without
            # the CBF rows and retry from better references.
            suspect_cbf = status is Status.CBF_VIOLATION or (status in (Status.INFEASIBLE, Status.INFEASIBLE_SOLUTION) and not ref_safe)
            if sol is None and self._n_cbf and suspect_cbf:
                # Is it the CBF linearisation? Solve without the CBF rows once.
                qp = self._build(i, x, None, relax, with_cbf=False)
                res, t_solve = self._run_solver(qp, i, persistent=False)
                self._clock[0] += t_solve
                self._clock[1] += res.iterations
                if res.x is not None and res.ok:
                    u_free = (res.x[:self._nu] - res.x[self._nu:2 * self._nu]).reshape(-1, 3)[i] * c.u_max_mps
                    for u_ref in (self.hold_impulse(x), u_free):
                        sol, status = self._scp(i, x, u_ref, relax)
                        if sol is not None:
                            break
            if sol is None and self._n_cbf and not np.allclose(first_ref, hold := self.hold_impulse(x)) \
                    and self.check_drift(x, hold)[0]:
                # half-spaces on a safe but far-off reference (e.g. no plan yet and a drifting start) can cut
                # off every drift-free impulse: retry about the hold drift before relaxing anything
                sol, status = self._scp(i, x, hold, relax)
            return sol, status

        def note(relax: int, _rung, status: Status) -> None:
            events.append(("relaxed", ["design_rows_relaxed", "terminal_set_relaxed", "hops_relaxed"][relax]
                           + f" at node {i} ({status})"))

        out = climb(range(4), attempt, note)  # the shared ladder (proxops.control.relaxation)
        if out.solved:
            out.result.events = events
            return out.result
        return _Solve(None, out.status, self._clock[0], self._clock[1], out.level, events=events)

    def _scp(self, i: int, x: np.ndarray, u_ref: np.ndarray, relax: int) -> tuple[_Solve | None, Status]:
        """Solve, check the true (29j), re-linearise about the solution; at most cbf_iterations solves
        (:func:`proxops.solvers.successive_convexification`, no trust region)."""
        c = self.cfg
        ref = [u_ref]
        checked = {}

        def solve():
            qp = self._build(i, x, ref[0], relax)
            res, t_solve = self._run_solver(qp, i)
            self._clock[0] += t_solve
            self._clock[1] += res.iterations
            if res.x is None or not res.ok:
                return None, res.status
            if qp.max_violation(res.x) > c.feasibility_tol:
                return None, Status.INFEASIBLE_SOLUTION
            z = res.x
            return (z[:self._nu] - z[self._nu:2 * self._nu]).reshape(-1, 3)[i:] * c.u_max_mps, None

        def converged(u, _prev):
            checked["drift"] = self.check_drift(x, u[0])
            return checked["drift"][0]

        def relinearize(u, _radius):
            ref[0] = u[0]

        out = successive_convexification(solve, converged, relinearize,
                                         max_iter=max(1, c.cbf_iterations) if self._n_cbf else 1)
        if out.converged:
            _, gmin, rmin = checked["drift"]
            return _Solve(out.iterate, Status.OPTIMAL, self._clock[0], self._clock[1], relax, gmin, rmin), Status.OPTIMAL
        if out.status is Status.FAILED:  # the subproblem's status (solve() above returns Status members)
            return None, out.failure
        return None, Status.CBF_VIOLATION

    # ------------------------------------------------------------------ safety
    def drift_states(self, x: np.ndarray, u0: np.ndarray) -> np.ndarray:
        """Unforced CW states x_u(tau) (F, 6) after impulse u0 at state x (29h-i)."""
        x1 = np.asarray(x, dtype=float).copy()
        x1[3:6] += u0
        return self._phi_tau @ x1

    def check_drift(self, x: np.ndarray, u0: np.ndarray) -> tuple[bool, float, float]:
        """True (29j) and KOZ check on the free drift: (ok, min g, min range to the KOZ centre)."""
        xs = self.drift_states(x, u0)
        self.last_drift = xs
        if self.koz is None:
            return True, math.nan, float(np.min(np.linalg.norm(xs[:, :3], axis=1)))
        r = float(self.koz.radius_m)
        alpha = float(self.cfg.cbf_alpha_per_s)
        ok, g_min, d_min = _drift_verdict_kernel(xs, self.koz.center_m, r, alpha, r * (1 - 1e-9), -(1e-6 * alpha * r**2))
        return (bool(ok) if self.cfg.cbf else True), g_min, d_min

    def hold_impulse(self, x: np.ndarray) -> np.ndarray:
        """Impulse that leaves a drift-free CW state (closed ellipse about the current along-track
        position): v_after = [0, -2 n x, 0] in Hill."""
        return np.array([0.0, -2.0 * self.n_orb * x[0], 0.0]) - x[3:6]

    def _fallback(self, i: int, x: np.ndarray) -> np.ndarray:
        """Previous plan's impulse, else the hold impulse, else nothing -- the first whose free drift
        passes the true KOZ/CBF check (nothing if none does)."""
        for u in (self.plan[i].copy(), self.hold_impulse(x)):
            if np.all(np.abs(u) <= self.cfg.u_max_mps) and np.any(u) and self.check_drift(x, u)[0]:
                return u
        return np.zeros(3)
