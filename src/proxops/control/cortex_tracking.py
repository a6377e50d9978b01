"""CORTEX convex tracking guidance CP_g (cortex-convex-guidance.md §3.2.1, eq. 27).

One guidance interval of ``N_sub = dt_g / delta_t_g`` impulses::

    min  sum_j s_j + eps_P eps_xf                                   (27a)
    s.t. x_1 = x_k                                                   (27b)
         x_{j+1} = Phi(delta_t_g) (x_j + [0; dv_j]),  j = 1..N_sub   (27c, eq. 2)
         ||dv_j|| <= s_j                                             (27d)
         ||dv_j|| <= a_max delta_t_g                                 (27e, corrected, see below)
         ||x_{N_sub+1} - x_T|| <= eps_xf                             (27f, soft terminal)
         ||r_j|| cos(alpha_c) <= e . r_j,  j = 2..N_sub+1            (27g, final approach only)

Corrections and choices (stated in the report):

* (27e) prints ``a_max Delta t_g`` (30 s) although consecutive impulses are delta_t_g (2 s)
  apart: with that bound the N_sub impulses of one interval could deliver N_sub = 15 times
  what the thrusters can in 30 s. The physical bound of an impulse that stands for
  delta_t_g seconds of thrust is ``a_max delta_t_g``; that is implemented.
* (27g) is imposed from j = 2: x_1 is the measured state, fixed by (27b); a cone row on it
  would make the problem infeasible whenever the measurement lies outside the cone, a
  situation the supervisor handles (abort / recompute), not the solver.
* The terminal norm (27f) is the 2-norm of the 6-vector [m, m/s] as printed (mixed units).

The problem is built once per (N_sub, cone) structure and only its right-hand side changes
between calls (x_k and x_T enter ``b`` only): :class:`proxops.solvers.ClarabelSOCP` ``update``
keeps Clarabel's factorisation pattern (no rebuild; ``bench_cortex_tracking`` measures both).
Variables are scaled: velocities and impulses by V = a_max delta_t_g.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from proxops.core.cw import cw_stm
from proxops.errors import input_error
from proxops.solvers import ClarabelSOCP, SolveStatus


def substeps(dt_g_s: float, substep_s: float) -> int:
    """N_sub = dt_g / delta_t_g; raises a clear error unless delta_t_g divides dt_g."""
    for name, v in (("guidance.dt_g_s", dt_g_s), ("guidance.substep_s", substep_s)):
        if not (math.isfinite(v) and v > 0):
            raise input_error(name, v, "must be a finite number > 0", "s")
    ratio = dt_g_s / substep_s
    n = int(round(ratio))
    if n < 1 or abs(ratio - n) > 1e-9 * max(1.0, ratio):
        raise input_error("guidance.substep_s", substep_s,
                          f"must divide guidance.dt_g_s = {dt_g_s:g} s into a whole number of impulses", "s")
    return n


class TrackingSOCP:
    """CP_g for a fixed number of impulses ``n_sub`` spaced ``substep_s`` apart (eq. 27).

    ``cone`` (an :class:`proxops.constraints.approach_cone.ApproachCone`) adds (27g); ``plume`` adds
    soft plume half-spaces (not in the paper, see :meth:`set_plume`)."""

    def __init__(self, n_rad_s: float, n_sub: int, substep_s: float, a_max_mps2: float, terminal_penalty: float,
                 cone=None, plume: bool = False, plume_weight: float = 100.0, solver_settings: dict | None = None):
        if not (math.isfinite(terminal_penalty) and terminal_penalty > 0):
            raise input_error("guidance.terminal_penalty", terminal_penalty, "must be a finite number > 0")
        if not (math.isfinite(a_max_mps2) and a_max_mps2 > 0):
            raise input_error("servicer.a_max_mps2", a_max_mps2, "must be a finite number > 0", "m/s^2")
        self.n_sub = N = int(n_sub)
        self.substep_s = float(substep_s)
        self.a_max = float(a_max_mps2)
        self.dv_max = self.a_max * self.substep_s
        V = self.V = self.dv_max
        D = self.D = np.array([1.0, 1.0, 1.0, V, V, V])
        self.nx = 6 * (N + 1)
        self.iv = self.nx
        self.isv = self.nx + 3 * N
        self.ie = self.isv + N
        self.isig = self.ie + 1  # plume slacks (only with plume)
        nz = self.ie + 1 + (N if plume else 0)
        phi = self.phi = cw_stm(n_rad_s, self.substep_s)
        Ad = phi / D[:, None] * D[None, :]
        Bd = phi[:, 3:6] / D[:, None] * V
        rows, cols, vals, b, cones = [], [], [], [], []

        def put(r, c, v):
            rows.append(np.atleast_1d(r)); cols.append(np.atleast_1d(c)); vals.append(np.atleast_1d(np.asarray(v, float)))  # noqa: E702

        # (27b) x_1 = x_k  (rows 0..5, b updated each call)
        put(np.arange(6), np.arange(6), np.ones(6))
        b.append(np.zeros(6))
        r = 6
        for j in range(N):  # (27c)
            rr = r + np.arange(6)
            put(rr, 6 * (j + 1) + np.arange(6), np.ones(6))
            ii, jj = np.meshgrid(rr, 6 * j + np.arange(6), indexing="ij")
            put(ii.ravel(), jj.ravel(), -Ad.ravel())
            ii, jj = np.meshgrid(rr, self.iv + 3 * j + np.arange(3), indexing="ij")
            put(ii.ravel(), jj.ravel(), -Bd.ravel())
            b.append(np.zeros(6))
            r += 6
        cones.append(("zero", r))
        # (27e) s_j <= a_max delta_t_g (scaled: 1)
        put(r + np.arange(N), self.isv + np.arange(N), np.ones(N))
        b.append(np.ones(N))
        r += N
        n_nonneg = N
        # optional soft plume half-spaces g_j . dv_j - sig_j <= 0, sig_j >= 0 (see set_plume)
        self.plume_row0 = r
        self.has_plume = bool(plume)
        if plume:
            for j in range(N):
                put(np.full(3, r + j), self.iv + 3 * j + np.arange(3), np.zeros(3))
                put(r + j, self.isig + j, -1.0)
            b.append(np.zeros(N))
            r += N
            put(r + np.arange(N), self.isig + np.arange(N), -np.ones(N))
            b.append(np.zeros(N))
            r += N
            n_nonneg += 2 * N
        cones.append(("nonneg", n_nonneg))
        # (27d) ||dv_j|| <= s_j
        for j in range(N):
            put(r, self.isv + j, -1.0)
            put(r + 1 + np.arange(3), self.iv + 3 * j + np.arange(3), -np.ones(3))
            b.append(np.zeros(4))
            cones.append(("soc", 4))
            r += 4
        # (27f) ||D (x_{N+1} - x_T)|| <= eps_xf: s = [e; D x_{N+1} - D x_T] -> A = -[1; D], b = [0; -D x_T]
        self.term_row = r
        put(r, self.ie, -1.0)
        put(r + 1 + np.arange(6), 6 * N + np.arange(6), -D)
        b.append(np.zeros(7))
        cones.append(("soc", 7))
        r += 7
        if cone is not None:  # (27g) at j = 2..N+1
            c = cone.axis / math.cos(cone.half_angle_rad)
            for j in range(1, N + 1):
                put(np.full(3, r), 6 * j + np.arange(3), -c)
                put(r + 1 + np.arange(3), 6 * j + np.arange(3), -np.ones(3))
                b.append(np.zeros(4))
                cones.append(("soc", 4))
                r += 4
        self.m = r
        A = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(r, nz))
        self.b = np.concatenate(b)
        q = np.zeros(nz)
        q[self.isv : self.isv + N] = 1.0
        q[self.ie] = float(terminal_penalty) / V  # objective divided by V (Delta-v in units of V)
        if plume:
            q[self.isig :] = plume_weight
        self.q = q
        self.A = A
        self.cones = cones
        self.solver_settings = solver_settings or {}
        self.solver = ClarabelSOCP(**self.solver_settings)
        self.solver.setup(None, q, A, self.b, cones)
        if plume:  # entry index of each plume-row coefficient in A.data (column order = dv_j x, y, z)
            A.sort_indices()
            self._plume_idx = np.empty((N, 3), dtype=int)
            for j in range(N):
                for c in range(3):
                    col = self.iv + 3 * j + c
                    lo, hi = A.indptr[col], A.indptr[col + 1]
                    k = lo + int(np.flatnonzero(A.indices[lo:hi] == self.plume_row0 + j)[0])
                    self._plume_idx[j, c] = k
        self._A_dirty = False

    def set_plume(self, g_rows) -> None:
        """Soft plume rows g_j . dv_j <= sig_j, cost ``plume_weight`` sig_j (g_j (N, 3), physical units;
        normalised here, sig in units of a_max delta_t_g): the
        dv-linearisation of eq. (21) about the reference (r_ref_j, dv_ref_j), a half-space inside the
        allowed thrust set at r = r_ref_j (:meth:`PlumeConstraint.linearization`)."""
        g = np.asarray(g_rows, float)
        scale = np.maximum(np.abs(g).max(axis=1), 1e-300)
        self.A.data[self._plume_idx.ravel()] = (g / scale[:, None]).ravel()
        self._A_dirty = True

    def _set_rhs(self, x_k, x_T) -> None:
        x_k = np.asarray(x_k, float)
        x_T = np.asarray(x_T, float)
        self.b[:6] = x_k / self.D
        self.b[self.term_row + 1 : self.term_row + 7] = -x_T  # D (x_T / D) = x_T in the D-scaled norm

    def solve(self, x_k, x_T, rebuild: bool = False):
        """Impulses (n_sub, 3) m/s from the state x_k towards x_T after n_sub substeps.

        Returns (dv or None, SolverResult). ``rebuild=True`` sets the solver up from scratch
        (for the update-vs-rebuild measurement)."""
        self._set_rhs(x_k, x_T)
        if rebuild:
            self.solver = ClarabelSOCP(**self.solver_settings)
            self.solver.setup(None, self.q, self.A, self.b, self.cones)
        else:
            self.solver.update(b=self.b, A=self.A if self._A_dirty else None)
        self._A_dirty = False
        res = self.solver.solve()
        if res.x is None or res.status not in (SolveStatus.OPTIMAL, SolveStatus.OPTIMAL_INACCURATE):
            return None, res
        dv = res.x[self.iv : self.isv].reshape(self.n_sub, 3) * self.V
        # the bound (27e) holds to the solver tolerance; clip the tiny excess so the command is physical
        norm = np.linalg.norm(dv, axis=1)
        over = norm > self.dv_max
        if over.any():
            dv[over] *= (self.dv_max / norm[over])[:, None]
        return dv, res

    def predicted_states(self, x_k, dv) -> np.ndarray:
        """States x_1..x_{N+1} under the CW model (eq. 2) from x_k with impulses dv (independent of the solver)."""
        phi = self.phi
        x = np.empty((self.n_sub + 1, 6))
        x[0] = x_k
        for j in range(self.n_sub):
            xj = x[j].copy()
            xj[3:] += dv[j]
            x[j + 1] = phi @ xj
        return x

