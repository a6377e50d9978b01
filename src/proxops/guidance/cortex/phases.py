"""The two convex phases of CORTEX reference generation (Wijayatunga et al. §3.1.1-3.1.2).

Both are second-order cone programs on the impulsive CW discretisation (eq. 2,
:func:`proxops.core.cw.cw_discretize_impulsive`), solved with Clarabel
(:class:`proxops.solvers.ClarabelSOCP`)::

    min  sum_k s_k                                        (17a / 20a)
    s.t. x_0 = x_i,  x_N = x_f                            (17b / 20b)
         x_{k+1} = Phi(dt_k) (x_k + [0; dv_k])            (17c / 20c, eq. 2)
         ||dv_k|| <= s_k,  s_k <= a_bar dt_k              (17d-e / 20d-e)

Node times ``t = [0 : dt : tau, tau]`` (eq. 17), N intervals, impulses at nodes
0..N-1 as in eq. (2), plus a terminal burn at node N: ``x_N + [0; dv_N] = x_f``.
Without it the last coast is fixed by the end state (at rest), and for CP1 ending at
rest on the inflated KOS that coast starts inside the sphere whenever the CW
acceleration at r_bar e points inwards (3 e_x^2 < e_z^2): CP1 would be infeasible for
every tau (found on a third of the Fibonacci axes). The terminal burn is bounded like
the others (a_bar dt). The bound (17e) uses each interval's own length (the last one
may be shorter than dt; the paper writes dt_CP1 for every node).

* CP1 (fly-around): keep-out sphere by supporting planes ``l_k . r_k >= rho_bar`` at
  nodes that violate it (eq. 18), re-solved until no node violates; every node gets
  at most one plane, so the loop ends after at most N solves (cap ``kos_max_iter``).
* CP2 (final approach): approach cone (20f) as second-order cones at every free node
  and the plume constraint (19d, impulse form of eq. 21) by successive convexification
  (eq. 22) with an infinity-norm trust region on the impulses and slacks on the
  linearised rows (exact penalty, so a poor linearisation is never an artificial
  infeasibility); converged when the true plume constraint holds at every thrusting node
  and the solution stops changing: impulses by less than ``scp_tol_mps`` or, because
  the fuel-optimal problem is degenerate (many impulse distributions with one cost, so
  the impulses can drift at constant cost), the cost by less than ``scp_cost_rtol``.
  The rows are linearised in dv with r frozen at the previous iterate (the dv part of
  grad h in eq. 22) plus, by default, the r part (``linearize_position``; faster and more often
  converged on the Fibonacci axes than the dv part alone).

The problem structure is built once per phase and duration; planes, linearised plume
rows and trust-region bounds are changed in place (fixed sparsity pattern, explicit
zeros for inactive rows), so Clarabel keeps its symbolic factorisation.

Variables are scaled for conditioning: positions by L (the start range), velocities
and impulses by V = a_bar dt (the largest impulse of a node).
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from proxops.constraints.approach_cone import ApproachCone
from proxops.constraints.plume import PlumeConstraint
from proxops.constraints.keep_out import KeepOutSphere
from proxops.core.cw import cw_discretize_impulsive, cw_stm
from proxops.solvers import ClarabelSOCP, ConicProblem, TrustRegion, soc_rows, successive_convexification
from proxops.status import Status

SLACK_WEIGHT = 1e3  # cost of the plume-row slacks (scaled units; the plan's cost is ~1-10)
# Clarabel settings of CP1 / CP2 (as CP_g's, proxops.control.cortex_tracking): iterative refinement of the KKT
# solves off, a solve that then ends inaccurate, failed or at the iteration limit solved again with it on.
# Measured on 25 Fibonacci axes (issue 32, CPU time alternated in one process): the plan 0.12 -> 0.065 s;
# same statuses, durations and SCP iteration counts, total delta-v within 6.5e-8 m/s, single CP2 impulses
# within 6.7e-6 m/s (the fuel-optimal CP2 is degenerate: equal-cost impulse distributions; its SCP stops on
# changes below scp_tol_mps = 1e-5 m/s), CP1 impulses within 7.7e-9 m/s.
DEFAULT_SOLVER_SETTINGS = {"settings": {"iterative_refinement_enable": False},
                           "retry_settings": {"iterative_refinement_enable": True}}
DV_ZERO_MPS = 1e-6  # impulses below this are "no thrust" for the plume linearisation and checks


def node_times(tau_s: float, dt_s: float) -> np.ndarray:
    """``[0 : dt : tau, tau]`` without a repeated last node (eq. 17 / 20 time vector), s."""
    m = int(math.floor(tau_s / dt_s + 1e-9))
    t = dt_s * np.arange(m + 1)
    if tau_s - t[-1] > 1e-9 * max(1.0, tau_s):
        t = np.append(t, tau_s)
    else:
        t[-1] = tau_s
    return t


@dataclass
class PhaseResult:
    """Outcome of one convex phase. ``status`` (:class:`proxops.status.Status`): OPTIMAL (converged),
    INFEASIBLE, MAX_ITER (iteration cap: KOS planes or plume SCP still changing) or the solver's failure
    status; ``x`` (N+1, 6) node states, ``dv`` (N, 3) impulses."""

    status: Status
    reason: str = ""
    t: np.ndarray | None = None
    x: np.ndarray | None = None
    dv: np.ndarray | None = None
    iterations: int = 0
    solve_times_s: list = field(default_factory=list)
    setup_time_s: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status is Status.OPTIMAL

    @property
    def dv_total_mps(self) -> float:
        return float(np.linalg.norm(self.dv, axis=1).sum()) if self.dv is not None else math.nan


class _PhaseSOCP:
    """Sparse SOCP of one phase for a fixed node grid; optional KOS planes, cone and plume rows."""

    def __init__(self, n_rad_s: float, t: np.ndarray, x0, xf, a_bar_mps2: float, *, kos: bool = False,
                 cone: ApproachCone | None = None, plume: bool = False, arc: bool = False,
                 solver_settings: dict | None = None, cone_half_angles_rad=None):
        self.t = t
        self.N = N = len(t) - 1
        self.M = M = N + 1  # impulses at nodes 0..N (the last one is the terminal burn)
        self.dt = np.diff(t)
        self.x0 = np.asarray(x0, float)
        self.xf = np.asarray(xf, float)
        self.L = max(float(np.linalg.norm(self.x0[:3])), float(np.linalg.norm(self.xf[:3])), 1e-3)
        self.V = a_bar_mps2 * float(self.dt.max())
        self.D = np.array([self.L] * 3 + [self.V] * 3)
        self.nx = 6 * (N + 1)
        self.iv = self.nx  # first impulse variable
        self.isv = self.nx + 3 * M  # first slack variable
        self.isig = self.nx + 4 * M  # plume-row slacks (virtual control, CP2 only)
        self.nz = self.nx + 4 * M + (M if plume else 0)
        self.smax = a_bar_mps2 * np.append(self.dt, self.dt.max()) / self.V

        rows, cols, vals, b = [], [], [], []

        def put(row, col, val):
            row, col = np.broadcast_arrays(np.asarray(row), np.asarray(col))
            rows.append(row.ravel())
            cols.append(col.ravel())
            vals.append(np.broadcast_to(np.asarray(val, float), row.shape).ravel())

        i3, i6 = np.arange(3), np.arange(6)
        k_n, k_m = np.arange(N), np.arange(M)
        # --- equalities: x_0 = x_i, dynamics, x_N = x_f (all blocks at once; explicit zeros kept in the pattern)
        put(i6, i6, 1.0)
        b.append(self.x0 / self.D)
        phis = {}
        for key in np.unique(np.round(self.dt, 9)):
            Ad, Bd = cw_discretize_impulsive(n_rad_s, float(self.dt[np.flatnonzero(np.round(self.dt, 9) == key)[0]]))
            phis[float(key)] = (Ad / self.D[:, None] * self.D[None, :], Bd / self.D[:, None] * self.V)
        keys = np.round(self.dt, 9)
        Ads = np.array([phis[float(kk)][0] for kk in keys]).reshape(N, 6, 6)
        Bds = np.array([phis[float(kk)][1] for kk in keys]).reshape(N, 6, 3)
        rr = 6 + 6 * k_n[:, None] + i6[None, :]  # (N, 6) row of each dynamics equation
        put(rr, 6 * (k_n[:, None] + 1) + i6[None, :], 1.0)
        put(rr[:, :, None], (6 * k_n[:, None] + i6[None, :])[:, None, :], -Ads)
        put(rr[:, :, None], (self.iv + 3 * k_n[:, None] + i3[None, :])[:, None, :], -Bds)
        b.append(np.zeros(6 * N))
        r = 6 + 6 * N
        # x_N + [0; dv_N] = x_f: the end state is the state after the terminal burn
        put(r + i6, 6 * N + i6, 1.0)
        put(r + 3 + i3, self.iv + 3 * N + i3, 1.0)
        b.append(self.xf / self.D)
        r += 6
        cones = [("zero", r)]
        n_nonneg = 0
        # --- s_k <= a_bar dt_k (17e)
        put(r + k_m, self.isv + k_m, 1.0)
        b.append(self.smax.copy())
        r += M
        n_nonneg += M
        # --- KOS planes at free nodes 1..N-1 (eq. 18): -l . r_k <= -rho/L, inactive: 0 <= 1
        self.kos_row0 = r
        if kos:
            nk = N - 1
            put(r + np.arange(nk)[:, None], 6 * (np.arange(nk)[:, None] + 1) + i3[None, :], 0.0)
            b.append(np.ones(nk))
            r += nk
            n_nonneg += nk
        # --- optional arc planes, one per interval k: l . r_k(s) >= rho on the coast after node k,
        # r_k(s) linear in (x_k, dv_k); inactive: 0 <= 1
        self.arc_row0 = r
        if arc:
            put(r + k_n[:, None], np.concatenate([6 * k_n[:, None] + i6[None, :], self.iv + 3 * k_n[:, None] + i3[None, :]],
                                                 axis=1), 0.0)
            b.append(np.ones(N))
            r += N
            n_nonneg += N
        # --- plume rows at nodes 0..N: a . r_k + g . dv_k <= b (eq. 22), inactive: 0 <= 1
        self.plume_row0 = r
        if plume:
            put(r + k_m[:, None], np.concatenate([6 * k_m[:, None] + i3[None, :], self.iv + 3 * k_m[:, None] + i3[None, :]],
                                                 axis=1), 0.0)
            put(r + k_m, self.isig + k_m, -1.0)
            b.append(np.ones(M))
            r += M
            # slacks sigma_k >= 0
            put(r + k_m, self.isig + k_m, -1.0)
            b.append(np.zeros(M))
            r += M
            n_nonneg += M
            # trust region |dv - dv_m|_inf <= delta (as two rows per component)
            self.trust_row0 = r
            put(r + np.arange(3 * M), self.iv + np.arange(3 * M), 1.0)
            put(r + 3 * M + np.arange(3 * M), self.iv + np.arange(3 * M), -1.0)
            b.append(np.full(6 * M, 10.0))
            r += 6 * M
            n_nonneg += 7 * M
        cones.append(("nonneg", n_nonneg))
        # --- ||dv_k|| <= s_k (17d): head row r + 4k on s_k, tail rows r + 4k + 1..3 on dv_k (A holds -coefficients)
        head = r + 4 * k_m
        put(head, self.isv + k_m, -1.0)
        put(head[:, None] + 1 + i3[None, :], self.iv + 3 * k_m[:, None] + i3[None, :], -1.0)
        b.append(np.zeros(4 * M))
        cones += [("soc", 4)] * M
        r += 4 * M
        # --- approach cone (20f) at free nodes 1..N-1: ||r|| <= e . r / cos(alpha)
        if cone is not None and N > 1:
            angles = (np.full(N + 1, cone.half_angle_rad) if cone_half_angles_rad is None
                      else np.asarray(cone_half_angles_rad, float))
            kk = np.arange(1, N)
            c = cone.axis[None, :] / np.cos(angles[kk])[:, None]  # (N-1, 3)
            head = r + 4 * (kk - 1)
            pos = 6 * kk[:, None] + i3[None, :]
            cone_at = sum(len(v) for v in vals)  # offset of these entries before sorting
            put(head[:, None], pos, -c)
            put(head[:, None] + 1 + i3[None, :], pos, -1.0)
            b.append(np.zeros(4 * (N - 1)))
            cones += [("soc", 4)] * (N - 1)
            r += 4 * (N - 1)
        self.m = r
        rows, cols, vals = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
        # entries in the order of the canonical CSC matrix (by column, then row; no duplicates), so the
        # edited values are handed to the solver as they are (ClarabelSOCP.update_fast)
        order = np.lexsort((rows, cols))
        self._cone_entries = None
        if cone is not None and N > 1:  # where the cone coefficients -e/cos(alpha_k) went (for _reset)
            where = np.empty(len(order), np.int64)
            where[order] = np.arange(len(order))
            self._cone_entries = where[cone_at : cone_at + 3 * (N - 1)]
        self.rows, self.cols, self.vals = rows[order], cols[order], vals[order]
        if np.any((np.diff(self.cols) == 0) & (np.diff(self.rows) == 0)):
            raise RuntimeError("duplicate entries in the phase SOCP pattern")  # a construction bug, not bad input
        self._indptr = np.concatenate([[0], np.cumsum(np.bincount(self.cols, minlength=self.nz))])
        self.b = np.concatenate(b)
        self.cones = cones
        q = np.zeros(self.nz)
        q[self.isv : self.isv + M] = 1.0
        if plume:
            q[self.isig :] = SLACK_WEIGHT
        self.q = q
        self.solver = ClarabelSOCP(**(DEFAULT_SOLVER_SETTINGS if solver_settings is None else solver_settings))
        t0 = time.perf_counter()
        self.solver.setup(ConicProblem(None, q, self._A(), self.b, cones))
        self.setup_time_s = time.perf_counter() - t0
        self._kos_entries = self._row_entries(self.kos_row0, N - 1) if kos else None
        self._arc_entries = self._row_entries(self.arc_row0, N) if arc else None
        self._plume_entries = self._row_entries(self.plume_row0, M) if plume else None
        self._vals0, self._b0 = self.vals.copy(), self.b.copy()  # as set up: no planes, no plume rows
        self._xf_row = 6 + 6 * N

    def _reset(self, x0, xf, cone: ApproachCone | None, cone_half_angles_rad=None) -> None:
        """The problem for new end states and cone axis on this node grid (same n, a_bar and position
        scale L), as :meth:`__init__` would build it: values and b from the set-up copies, then a fresh
        solver set-up (ClarabelSOCP.rebuild: the same equilibration and solve as a new set-up)."""
        t0 = time.perf_counter()
        self.x0, self.xf = np.asarray(x0, float), np.asarray(xf, float)
        self.vals[:] = self._vals0
        self.b[:] = self._b0
        self.b[0:6] = self.x0 / self.D
        self.b[self._xf_row : self._xf_row + 6] = self.xf / self.D
        if self._cone_entries is not None:
            N = self.N
            angles = (np.full(N + 1, cone.half_angle_rad) if cone_half_angles_rad is None
                      else np.asarray(cone_half_angles_rad, float))
            kk = np.arange(1, N)
            c = cone.axis[None, :] / np.cos(angles[kk])[:, None]
            self.vals[self._cone_entries] = -c.ravel()
        self.solver.rebuild(b=self.b, A_values=self.vals)
        self.setup_time_s = time.perf_counter() - t0

    def _A(self) -> sp.csc_matrix:
        return sp.csc_matrix((self.vals.copy(), self.rows.copy(), self._indptr), shape=(self.m, self.nz))

    def _row_entries(self, row0: int, count: int) -> np.ndarray:
        """Indices into self.vals of the entries of rows row0..row0+count-1, (count, k) in column order."""
        idx = np.flatnonzero((self.rows >= row0) & (self.rows < row0 + count) & (self.cols < self.isv))
        idx = idx[np.lexsort((self.cols[idx], self.rows[idx]))]
        return idx.reshape(count, -1)

    # ------------------------------------------------------------------ edits
    def set_plane(self, j: int, normal) -> None:
        """KOS plane at free node j+1: l . r >= rho (normal l unit, rho in m)."""
        self.vals[self._kos_entries[j]] = -np.asarray(normal, float)

    def set_kos_rhs(self, j: int, rho_m: float) -> None:
        self.b[self.kos_row0 + j] = -rho_m / self.L

    def set_arc_plane(self, k: int, normal, pos_rows: np.ndarray, rho_m: float) -> None:
        """Plane l . r(s) >= rho on the coast of interval k, r(s) = pos_rows @ (x_k + [0; dv_k]) with
        pos_rows = Phi(s)[0:3, :] (physical units); row scaled by 1/L."""
        c = np.asarray(normal, float) @ pos_rows  # (6,): on [r_k, v_k + dv_k]
        coef = np.concatenate([-c[:3], -c[3:] * self.V / self.L, -c[3:] * self.V / self.L])
        self.vals[self._arc_entries[k]] = coef
        self.b[self.arc_row0 + k] = -rho_m / self.L

    def set_plume(self, a_s, g_s, b_s) -> None:
        """Plume rows a'_k . r'_k + g'_k . dv'_k <= b'_k for all nodes in this problem's units (r = L r',
        dv = V dv'), as :meth:`PlumeConstraint.rows` gives them (eq. 22, each row normalised)."""
        coef = np.concatenate([a_s, g_s], axis=1)
        self.vals[self._plume_entries.ravel()] = coef.ravel()
        self.b[self.plume_row0 : self.plume_row0 + self.M] = b_s

    def set_trust(self, dv_ref, delta_mps: float) -> None:
        ref = np.asarray(dv_ref, float).ravel() / self.V
        d = delta_mps / self.V
        n3 = 3 * self.M
        self.b[self.trust_row0 : self.trust_row0 + n3] = ref + d
        self.b[self.trust_row0 + n3 : self.trust_row0 + 2 * n3] = -ref + d

    def push(self, A: bool = True) -> None:
        self.solver.update_fast(b=self.b, A_values=self.vals if A else None)

    def solve(self):
        res = self.solver.solve()
        if res.x is None:
            return res, None, None
        z = res.x
        x = z[: self.nx].reshape(self.N + 1, 6) * self.D
        dv = z[self.iv : self.isv].reshape(self.M, 3) * self.V
        return res, x, dv


_SET_UPS: OrderedDict = OrderedDict()  # set-up phase problems of this process, least recently used first
SET_UPS_KEPT = 32  # node grids kept (a campaign of plans uses a few: the durations tried)


def _phase_problem(n_rad_s: float, t: np.ndarray, x0, xf, a_bar_mps2: float, *, kos: bool = False,
                   cone: ApproachCone | None = None, plume: bool = False, arc: bool = False,
                   solver_settings: dict | None = None, cone_half_angles_rad=None) -> _PhaseSOCP:
    """A :class:`_PhaseSOCP` for these data: one set up earlier in this process on the same node grid
    (same n, a_bar, position scale L, rows and solver settings) reset to these end states and cone axis
    (:meth:`_PhaseSOCP._reset`), else a new one. Saves the pattern assembly and the adapter's checks on
    every plan after the first of a grid (a Fibonacci campaign plans the same durations for every axis)."""
    x0, xf = np.asarray(x0, float), np.asarray(xf, float)
    L = max(float(np.linalg.norm(x0[:3])), float(np.linalg.norm(xf[:3])), 1e-3)
    key = (float(n_rad_s), np.asarray(t, float).tobytes(), float(a_bar_mps2), L, kos, cone is not None, plume, arc,
           repr(solver_settings))
    prob = _SET_UPS.pop(key, None)
    if prob is None:
        prob = _PhaseSOCP(n_rad_s, t, x0, xf, a_bar_mps2, kos=kos, cone=cone, plume=plume, arc=arc,
                          solver_settings=solver_settings, cone_half_angles_rad=cone_half_angles_rad)
    else:
        prob._reset(x0, xf, cone, cone_half_angles_rad)
    _SET_UPS[key] = prob
    while len(_SET_UPS) > SET_UPS_KEPT:
        _SET_UPS.popitem(last=False)
    return prob


def _status_of(res) -> tuple[Status, str]:
    if res.status is Status.INFEASIBLE:
        return Status.INFEASIBLE, f"SOCP infeasible ({res.info.get('raw_status', '')})"
    if res.status is Status.UNBOUNDED:
        return Status.UNBOUNDED, "SOCP reported unbounded"
    status = res.status if res.status.failed else Status.NUMERICAL_ERROR
    return status, f"solver status {res.status.value} ({res.info.get('raw_status', res.info.get('error', ''))})"


def solve_flyaround(n_rad_s: float, tau_s: float, dt_s: float, x0, xf, a_bar_mps2: float, rho_bar_m: float,
                    kos_max_iter: int = 50, arc_planes: bool = False, solver_settings: dict | None = None) -> PhaseResult:
    """CP1 (eqs. 17-18): fuel-optimal fly-around in ``tau_s`` outside the inflated KOS at the nodes.

    ``arc_planes`` (not in the paper): once no node violates, also add one static plane per
    coast interval at its deepest point inside the sphere (a linear constraint on x_k, dv_k),
    re-solved until no node and no interval with a free plane row violates; an interval whose
    coast still dips in after its plane keeps that (reported) penetration."""
    t = node_times(tau_s, dt_s)
    prob = _phase_problem(n_rad_s, t, x0, xf, a_bar_mps2, kos=True, arc=arc_planes, solver_settings=solver_settings)
    has_arc = np.zeros(prob.N, bool)
    out = PhaseResult(status=Status.MAX_ITER, t=t, setup_time_s=prob.setup_time_s)
    sphere = KeepOutSphere(rho_bar_m)
    has_plane = np.zeros(prob.N - 1, bool)
    for it in range(1, kos_max_iter + 1):
        res, x, dv = prob.solve()
        out.iterations = it
        out.solve_times_s.append(res.solve_time_s)
        if x is None or not res.status.ok:
            out.status, out.reason = _status_of(res)
            if it > 1 and out.status is Status.INFEASIBLE:
                out.reason += f" after {int(has_plane.sum())} KOS planes"
            return out
        out.x, out.dv = x, dv
        dist = sphere.distance_to_surface(x[1:-1, :3])  # free nodes 1..N-1
        bad = np.flatnonzero((dist < -1e-6 * rho_bar_m) & ~has_plane)
        if bad.size == 0 and arc_planes:
            rmin, s_min = arc_min_per_interval(n_rad_s, t, x, dv)
            arc_bad = np.flatnonzero((rmin < rho_bar_m * (1 - 1e-6)) & ~has_arc)
            if arc_bad.size:
                for k in arc_bad:
                    M = _stm_pos_rows(n_rad_s, np.array([s_min[k]]))[0]
                    xk = x[k].copy()
                    xk[3:] += dv[k]
                    p = M @ xk
                    prob.set_arc_plane(k, p / max(np.linalg.norm(p), 1e-12), M, rho_bar_m)
                    has_arc[k] = True
                prob.push()
                continue
        if bad.size == 0:
            out.status, out.reason = Status.OPTIMAL, ""
            return out
        normals, _ = sphere.halfspace(np.where(np.linalg.norm(x[1 + bad, :3], axis=1)[:, None] > 1e-9,
                                               x[1 + bad, :3], np.asarray(x0, float)[:3]))
        for j, nrm in zip(bad, normals):
            prob.set_plane(j, nrm)
            prob.set_kos_rhs(j, rho_bar_m)
            has_plane[j] = True
        prob.push()
    out.reason = f"KOS planes still added after {kos_max_iter} solves (iteration cap)"
    return out


def solve_final_approach(n_rad_s: float, tau_s: float, dt_s: float, x0, xf, a_bar_mps2: float,
                         cone: ApproachCone, plume: PlumeConstraint, scp_max_iter: int = 30,
                         scp_tol_mps: float = 1e-5, plume_tol_rad: float = 1e-4,
                         scp_cost_rtol: float = 1e-4, linearize_position: bool = True,
                         solver_settings: dict | None = None, cone_half_angle_at=None) -> PhaseResult:
    """CP2 (eqs. 20-22): fuel-optimal final approach inside the cone with the plume constraint
    by successive convexification with a trust region. ``cone_half_angle_at``: optional function of the
    node time (s from the phase start) giving that node's cone half-angle (rad) about ``cone.axis``
    (a regeneration's funnel back into the planning cone); None: ``cone.half_angle_rad`` at every node."""
    t = node_times(tau_s, dt_s)
    angles = None if cone_half_angle_at is None else np.array([cone_half_angle_at(float(tk)) for tk in t])
    prob = _phase_problem(n_rad_s, t, x0, xf, a_bar_mps2, cone=cone, plume=True, solver_settings=solver_settings,
                          cone_half_angles_rad=angles)
    out = PhaseResult(status=Status.MAX_ITER, t=t, setup_time_s=prob.setup_time_s)
    # the largest impulse: no restriction at first; halved when the plume violation grows
    trust = TrustRegion(a_bar_mps2 * float(prob.dt.max()))

    def relinearize(prev, delta):
        if linearize_position:
            a, g, bb = plume.rows(prev["x"][:, :3], prev["dv"], DV_ZERO_MPS, prob.L, prob.V)
        else:  # the dv part of grad h only (r frozen at the previous iterate)
            _, g, _ = plume.rows(prev["x"][:, :3], prev["dv"], DV_ZERO_MPS, None, prob.V)
            a, bb = np.zeros_like(g), np.zeros(len(g))
        prob.set_plume(a, g, bb)
        prob.set_trust(prev["dv"], delta)
        prob.push()

    def solve():
        res, x, dv = prob.solve()
        out.iterations += 1
        out.solve_times_s.append(res.solve_time_s)
        if x is None or not res.status.ok:
            out.status, out.reason = _status_of(res)
            if out.iterations > 1:
                out.reason += f" at successive-convexification iteration {out.iterations}"
            return None, out.status
        margin = plume.margin_rad(x[:, :3], dv, DV_ZERO_MPS)
        out.x, out.dv = x, dv
        return {"x": x, "dv": dv, "viol": float(max(0.0, -margin.min())) if margin.size else 0.0,
                "cost": float(np.linalg.norm(dv, axis=1).sum())}, None

    def converged(it, prev):
        if prev is None:
            return False
        change = float(np.abs(it["dv"] - prev["dv"]).max())
        cost_change = abs(it["cost"] - prev["cost"]) / max(it["cost"], 1e-12)
        return it["viol"] <= plume_tol_rad and (change <= scp_tol_mps or cost_change <= scp_cost_rtol)

    scp = successive_convexification(solve, converged, relinearize, max_iter=scp_max_iter, trust=trust,
                                     merit=lambda it: it["viol"], merit_tol=plume_tol_rad)
    if scp.converged:
        out.status, out.reason = Status.OPTIMAL, ""
    elif scp.status == "max_iter":
        out.reason = f"plume successive convexification not converged in {scp_max_iter} iterations"
    return out


def propagate_impulses(n_rad_s: float, t: np.ndarray, x0, dv) -> np.ndarray:
    """Node states (before each node's impulse) from x0 and the impulses dv (N or N+1 rows) by the
    closed-form STM (independent of the solver)."""
    x = np.empty((len(t), 6))
    x[0] = x0
    for k in range(len(t) - 1):
        xk = x[k].copy()
        xk[3:] += dv[k]
        x[k + 1] = cw_stm(n_rad_s, float(t[k + 1] - t[k])) @ xk
    return x


def final_state(x, dv) -> np.ndarray:
    """State after the terminal burn: x_N + [0; dv_N]."""
    xf = np.array(x[-1], float)
    xf[3:] += dv[-1]
    return xf


def _stm_pos_rows(n: float, s: np.ndarray) -> np.ndarray:
    """Position rows Phi[0:3, :](s) of the CW STM for an array of times s: (len(s), 3, 6)."""
    sn, cs = np.sin(n * s), np.cos(n * s)
    z, o = np.zeros_like(s), np.ones_like(s)
    rows = [
        [4 - 3 * cs, z, z, sn / n, 2 * (1 - cs) / n, z],
        [6 * (sn - n * s), o, z, -2 * (1 - cs) / n, (4 * sn - 3 * n * s) / n, z],
        [z, z, cs, z, z, sn / n],
    ]
    return np.moveaxis(np.array(rows), -1, 0)


def arc_min_per_interval(n_rad_s: float, t: np.ndarray, x, dv, samples: int = 61) -> tuple[np.ndarray, np.ndarray]:
    """Sampled smallest range on each coast interval and the offset s (from the node) where it occurs."""
    x = np.asarray(x, float)
    xp = x[:-1].copy()
    xp[:, 3:] += np.asarray(dv, float)[: len(xp)]
    h = np.diff(t)
    frac = np.linspace(0.0, 1.0, samples)
    rmin, smin = np.empty(len(h)), np.empty(len(h))
    for hk in np.unique(np.round(h, 9)):
        ks = np.flatnonzero(np.isclose(h, hk))
        M = _stm_pos_rows(n_rad_s, frac * hk)
        rng = np.linalg.norm(np.einsum("sij,kj->ksi", M, xp[ks]), axis=2)
        j = np.argmin(rng, axis=1)
        rmin[ks] = rng[np.arange(len(ks)), j]
        smin[ks] = frac[j] * hk
    return rmin, smin


def arc_min_distance(n_rad_s: float, t: np.ndarray, x, dv, samples: int = 61) -> tuple[float, float]:
    """Smallest range ||r(t)|| on the continuous coast arcs between nodes (after each impulse):
    ``samples`` points per interval, then Newton's method on d/ds ||r(s)||^2 / 2 = r . v (CW coast:
    derivative v . v + r . a with a = [3 n^2 x + 2 n v_y, -2 n v_x, -n^2 z]) between the neighbours of
    the worst sample. Returns (min range m, time s)."""
    x = np.asarray(x, float)
    xp = x[:-1].copy()
    xp[:, 3:] += np.asarray(dv, float)[: len(xp)]
    h = np.diff(t)
    frac = np.linspace(0.0, 1.0, samples)
    best = (math.inf, 0.0, 0, 0.0, 0.0)
    for hk in np.unique(np.round(h, 9)):
        ks = np.flatnonzero(np.isclose(h, hk))
        M = _stm_pos_rows(n_rad_s, frac * hk)  # (S, 3, 6)
        rng = np.linalg.norm(np.einsum("sij,kj->ksi", M, xp[ks]), axis=2)  # (K, S)
        kk, j = np.unravel_index(int(np.argmin(rng)), rng.shape)
        if rng[kk, j] < best[0]:
            best = (float(rng[kk, j]), float(frac[j] * hk), int(ks[kk]), float(frac[max(j - 1, 0)] * hk),
                    float(frac[min(j + 1, samples - 1)] * hk))
    val, at, k, lo, hi = best
    if hi > lo:
        s_opt, r_opt = coast_min_range(n_rad_s, xp[k], at, lo, hi)
        if r_opt < val:
            val, at = r_opt, s_opt
    return val, float(t[k]) + at


def coast_min_range(n_rad_s: float, x0, s0: float, lo: float, hi: float, tol_s: float = 1e-9,
                    max_iter: int = 30) -> tuple[float, float]:
    """Local minimum of ||r(s)|| on a CW coast from state ``x0`` (Hill, m and m/s) for s in [lo, hi] (s),
    from the guess s0: Newton's method on f(s) = r . v (half the derivative of ||r||^2),
    f'(s) = v . v + r . a with the CW acceleration a = [3 n^2 x + 2 n v_y, -2 n v_x, -n^2 z] (Vallado
    eq. 6-64), each step kept in the bracket (bisection where f' <= 0 or the step leaves it).
    Returns (s, ||r(s)||)."""
    n = n_rad_s
    x0 = np.asarray(x0, float)
    s = min(max(float(s0), lo), hi)
    for _ in range(max_iter):
        xs = cw_stm(n, s) @ x0
        r, v = xs[:3], xs[3:]
        f = float(r @ v)
        a = np.array([3 * n * n * r[0] + 2 * n * v[1], -2 * n * v[0], -n * n * r[2]])
        fp = float(v @ v + r @ a)
        if f > 0:
            hi = s
        else:
            lo = s
        step = f / fp if fp > 0 else math.inf
        s_new = s - step
        if not lo <= s_new <= hi:
            s_new = 0.5 * (lo + hi)
        done = abs(s_new - s) <= tol_s
        s = s_new
        if done:
            break
    return s, float(np.linalg.norm((cw_stm(n, s) @ x0)[:3]))
