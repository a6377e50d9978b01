"""CORTEX convex tracking guidance CP_g (Wijayatunga et al. §3.2.1, eq. 27).

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

Formulation handed to the solver (the same problem, fewer variables). (27b)-(27c) are
eliminated by a change of variables: the decision variables are the position deviations
``d_j = r_j - r_j^free`` (j = 2..N+1) from the thrust-free CW response ``x_j^free = Phi^(j-1) x_k``.
With ``Phi = [[P_rr, P_rv], [P_vr, P_vv]]`` (P_rv invertible for delta_t_g well below an orbit)
each impulse is a fixed combination of three neighbouring deviations (d_1 = 0)::

    dv_j = P_rv^-1 d_{j+1} - (P_rv^-1 P_rr + P_vv P_rv^-1) d_j + (P_vv P_rv^-1 P_rr - P_vr) d_{j-1}

and the terminal velocity deviation is ``P_vv P_rv^-1 d_{N+1} + (P_vr - P_vv P_rv^-1 P_rr) d_N``.
The map (dv_1..dv_N) <-> (d_2..d_{N+1}) is linear and invertible, so the feasible set and
the optimum are those of eq. 27; every row stays sparse (banded in j) and x_k, x_T enter the
right-hand side only (the cone and terminal rows). Against the stacked form (states and
impulses as variables, 96 dynamics rows) the KKT system of Clarabel shrinks from 335 to
143 rows without the cone (from 440 to 248 with cone and plume rows); ``bench_cortex_tracking``
measures the solve times. Variables are scaled so that every cost coefficient is 1: impulses in
units of V = a_max delta_t_g, deviations in V delta_t_g, eps_xf by eps_P / V, plume slacks by
their weight.

The problem is built once per (N_sub, cone, plume) structure; each call writes x_k, x_T into
``b`` and (with plume rows) the row values into the fixed sparsity pattern of ``A``, handed to
the solver's ``update_fast`` (:meth:`proxops.solvers.ClarabelSOCP.update_fast`: no scipy.sparse
construction per call). The solver is made by name (:func:`proxops.solvers.make_solver`, ``solver``)
from a :class:`proxops.solvers.ConicProblem`; Clarabel is the one SOCP solver shipped.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from proxops.core.cw import cw_stm
from proxops.constraints.plume import scaled_rows
from proxops.errors import input_error
from proxops.solvers import ConicProblem, SolveStatus, make_solver, soc_rows

# Clarabel settings of CP_g (measured in benchmarks/bench_cortex_tracking.py): iterative refinement of
# the KKT solves off (about 30 % less time per solve); a solve that then ends inaccurate, failed or at
# the iteration limit is solved again with Clarabel's defaults (refinement on). Measured on the 1672 CP_g
# calls of 32 runs (cortex-nominal, cortex-abort, 10 cortex-low-mc, 20 cortex-high-mc): 12 first attempts
# ended inaccurate or failed, all 12 retries optimal.
DEFAULT_SOLVER_SETTINGS = {"settings": {"iterative_refinement_enable": False},
                           "retry_settings": {"iterative_refinement_enable": True}}


def impulse_maps(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Blocks of the change of variables of the module doc for the STM ``phi`` of one substep:
    ``(R, S, T, W1, W0)`` with dv_j = R d_{j+1} + S d_j + T d_{j-1} and the terminal velocity
    deviation W1 d_{N+1} + W0 d_N (physical units: m -> m/s)."""
    p_rr, p_rv, p_vr, p_vv = phi[:3, :3], phi[:3, 3:], phi[3:, :3], phi[3:, 3:]
    R = np.linalg.inv(p_rv)
    S = -(R @ p_rr + p_vv @ R)
    T = p_vv @ R @ p_rr - p_vr
    return R, S, T, p_vv @ R, p_vr - p_vv @ R @ p_rr


class TrackingSOCP:
    """CP_g for a fixed number of impulses ``n_sub`` spaced ``substep_s`` apart (eq. 27).

    ``cone`` (an :class:`proxops.constraints.approach_cone.ApproachCone`) adds (27g); ``plume`` adds
    soft plume half-spaces (not in the paper, see :meth:`set_plume`)."""

    def __init__(self, n_rad_s: float, n_sub: int, substep_s: float, a_max_mps2: float, terminal_penalty: float,
                 cone=None, plume: bool = False, plume_weight: float = 100.0, solver_settings: dict | None = None,
                 solver: str = "clarabel"):
        if not (math.isfinite(terminal_penalty) and terminal_penalty > 0):
            raise input_error("guidance.terminal_penalty", terminal_penalty, "must be a finite number > 0")
        if not (math.isfinite(a_max_mps2) and a_max_mps2 > 0):
            raise input_error("servicer.a_max_mps2", a_max_mps2, "must be a finite number > 0", "m/s^2")
        if not (math.isfinite(plume_weight) and plume_weight > 0):
            raise input_error("guidance.plume_weight", plume_weight, "must be a finite number > 0")
        self.n_sub = N = int(n_sub)
        self.substep_s = float(substep_s)
        self.a_max = float(a_max_mps2)
        self.dv_max = self.a_max * self.substep_s
        self.V = V = self.dv_max  # impulse unit (m/s)
        self.L = L = V * self.substep_s  # deviation unit (m)
        self.phi = phi = cw_stm(n_rad_s, self.substep_s)
        if np.linalg.cond(phi[:3, 3:]) > 1e8:
            raise input_error("guidance.substep_s", substep_s,
                              "must be well below an orbital period (the CW position-velocity block is singular)", "s")
        R, S, T, W1, W0 = impulse_maps(phi)
        self._R, self._S, self._T = (M * (L / V) for M in (R, S, T))  # scaled: d' -> dv'
        self.has_plume = bool(plume)
        self.i_s = 3 * N  # s_j
        self.i_e = self.i_s + N  # eps'
        self.i_sig = self.i_e + 1  # plume slacks sigma'_j
        nz = self.i_e + 1 + (N if plume else 0)
        eps_scale = float(terminal_penalty) / V  # eps = eps' / eps_scale (cost 1)
        sig_scale = float(plume_weight)  # sigma = sigma' / sig_scale (cost 1)
        rows, cols, vals = [], [], []

        def put(r, c, v):
            rows.append(np.ravel(r))
            cols.append(np.ravel(c))
            vals.append(np.ravel(np.asarray(v, float)))

        def dcol(j):  # columns of d'_j (j = 2..N+1)
            return 3 * (j - 2) + np.arange(3)

        def impulse_terms(j):
            """dv'_j as (row 0..2, column, value): the nonzero entries of the blocks on d'_{j+1}, d'_j,
            d'_{j-1} that exist (d'_1 = 0 is not a variable)."""
            rows_, cols_, vals_ = [], [], []
            for M, jj in ((self._R, j + 1), (self._S, j), (self._T, j - 1)):
                if 2 <= jj <= N + 1:
                    ii, cc = np.nonzero(M)
                    rows_.append(ii); cols_.append(dcol(jj)[cc]); vals_.append(M[ii, cc])  # noqa: E702
            return np.concatenate(rows_), np.concatenate(cols_), np.concatenate(vals_)

        b = []
        # nonneg cone: (27e) s_j <= 1 (a_max delta_t_g in units of V)
        put(np.arange(N), self.i_s + np.arange(N), np.ones(N))
        b.append(np.ones(N))
        r = N
        self.plume_row0 = r
        if plume:  # soft plume rows g_j . dv'_j - sigma'_j / sig_scale <= 0 (values set by set_plume), sigma' >= 0
            plume_entries = {0: [], 1: [], 2: []}  # block R, S, T: (row, columns of d')
            for j in range(1, N + 1):
                for blk, jj in enumerate((j + 1, j, j - 1)):
                    if 2 <= jj <= N + 1:
                        plume_entries[blk].append((r + j - 1, dcol(jj)))
                        put(np.full(3, r + j - 1), dcol(jj), np.zeros(3))
            put(r + np.arange(N), self.i_sig + np.arange(N), np.full(N, -1.0 / sig_scale))
            b.append(np.zeros(N))
            r += N
            put(r + np.arange(N), self.i_sig + np.arange(N), -np.ones(N))
            b.append(np.zeros(N))
            r += N
        cones = [("nonneg", r)]
        # (27d) ||dv'_j|| <= s_j: s = [s_j; dv'_j]
        for j in range(1, N + 1):
            ii, cc, vv = impulse_terms(j)
            put(*soc_rows(r, self.i_s + j - 1, 1.0, 1 + ii, cc, vv))
            b.append(np.zeros(4))
            cones.append(("soc", 4))
            r += 4
        # (27f) ||x_{N+1} - x_T|| <= eps: s = [eps' / eps_scale; x^free_{N+1} - x_T + (d_{N+1}; w_{N+1})]
        self.term_row = r
        tail = [(1 + np.arange(3), dcol(N + 1), np.full(3, L))]  # position: L d'_{N+1}
        for M, jj in ((W1 * L, N + 1), (W0 * L, N)):  # velocity: w_{N+1}
            if jj >= 2:
                ii, cc = np.nonzero(M)
                tail.append((4 + ii, dcol(jj)[cc], M[ii, cc]))
        put(*soc_rows(r, self.i_e, 1.0 / eps_scale, *(np.concatenate(p) for p in zip(*tail))))
        b.append(np.zeros(7))
        cones.append(("soc", 7))
        r += 7
        # (27g) at j = 2..N+1: s = [c . r_j; r_j], r_j = r^free_j + L d'_j, c = e / cos(alpha_c)
        self.cone_row0 = r
        self.cone_c = None
        if cone is not None:
            self.cone_c = c = cone.axis / math.cos(cone.half_angle_rad)
            nzc = np.flatnonzero(c)
            for j in range(2, N + 2):
                put(*soc_rows(r, dcol(j)[nzc], L * c[nzc], 1 + np.arange(3), dcol(j), np.full(3, L)))
                b.append(np.zeros(4))
                cones.append(("soc", 4))
                r += 4
        self.m = r
        A = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(r, nz)).tocsc()
        A.sum_duplicates()
        A.sort_indices()  # canonical CSC: A.data is in the order update_fast expects
        self.A = A
        self.b = np.concatenate(b)
        self.q = np.ones(nz)
        self.q[: 3 * N] = 0.0
        self.cones = cones
        # thrust-free response: positions r^free_2..r^free_{N+1} (stacked) and x^free_{N+1}
        powers = [np.eye(6)]
        for _ in range(N):
            powers.append(phi @ powers[-1])
        self._free_r = np.vstack([powers[j - 1][:3] for j in range(2, N + 2)])
        self._free_end = powers[N]
        if plume:  # A.data index of the plume-row entries per block: R (rows 1..N), S (rows 2..N), T (rows 3..N)
            def position(row, col):
                lo, hi = A.indptr[col], A.indptr[col + 1]
                return int(lo + np.flatnonzero(A.indices[lo:hi] == row)[0])

            self._plume_idx = [np.array([[position(row, col) for col in cs] for row, cs in plume_entries[blk]],
                                        dtype=np.intp).reshape(-1, 3) for blk in range(3)]
        self.solver_name = solver
        self.solver_settings = ((DEFAULT_SOLVER_SETTINGS if solver == "clarabel" else {}) if solver_settings is None
                                else solver_settings)
        self.solver = make_solver(self.form(), solver, **self.solver_settings)
        self._A_dirty = False

    def form(self) -> ConicProblem:
        """The current problem (eq. 27 in the variables of the module doc) as a :class:`ConicProblem`."""
        return ConicProblem(None, self.q, self.A, self.b, self.cones)

    def set_plume(self, g_rows) -> None:
        """Soft plume rows g_j . dv_j <= sig_j, cost ``plume_weight`` sig_j (g_j (N, 3), physical units;
        normalised here, sig in units of a_max delta_t_g): the
        dv-linearisation of eq. (21) about the reference (r_ref_j, dv_ref_j), a half-space inside the
        allowed thrust set at r = r_ref_j (:meth:`PlumeConstraint.linearization`)."""
        _, g, _ = scaled_rows(None, g_rows, None, None)
        data = self.A.data
        iR, iS, iT = self._plume_idx  # g_j . dv'_j = (g_j R') d'_{j+1} + (g_j S') d'_j + (g_j T') d'_{j-1}
        data[iR] = g @ self._R
        data[iS] = g[1:] @ self._S
        data[iT] = g[2:] @ self._T
        self._A_dirty = True

    def _set_rhs(self, x_k, x_T) -> None:
        x_k = np.asarray(x_k, float)
        self.b[self.term_row + 1 : self.term_row + 7] = self._free_end @ x_k - np.asarray(x_T, float)
        if self.cone_c is not None:
            r_free = (self._free_r @ x_k).reshape(self.n_sub, 3)
            rows = self.b[self.cone_row0 : self.cone_row0 + 4 * self.n_sub].reshape(self.n_sub, 4)
            rows[:, 0] = r_free @ self.cone_c
            rows[:, 1:] = r_free

    def impulses(self, z) -> np.ndarray:
        """Impulses (n_sub, 3) m/s from the solver's variables (the change of variables of the module doc)."""
        d = z[: 3 * self.n_sub].reshape(self.n_sub, 3)  # d'_2..d'_{N+1}
        dv = d @ self._R.T
        dv[1:] += d[:-1] @ self._S.T
        dv[2:] += d[:-2] @ self._T.T
        return dv * self.V

    def solve(self, x_k, x_T, rebuild: bool = False):
        """Impulses (n_sub, 3) m/s from the state x_k towards x_T after n_sub substeps.

        Returns (dv or None, SolverResult). ``rebuild=True`` sets the solver up from scratch
        (for the update-vs-rebuild measurement)."""
        self._set_rhs(x_k, x_T)
        if rebuild:
            self.solver = make_solver(self.form(), self.solver_name, **self.solver_settings)
        elif self._A_dirty:
            self.solver.update_fast(b=self.b, A_values=self.A.data)
        else:
            self.solver.update_fast(b=self.b)
        self._A_dirty = False
        res = self.solver.solve()
        if res.x is None or res.status not in (SolveStatus.OPTIMAL, SolveStatus.OPTIMAL_INACCURATE):
            return None, res
        dv = self.impulses(res.x)
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
        xj = np.empty(6)  # x_j + [0; dv_j]
        for j in range(self.n_sub):
            xj[:] = x[j]
            xj[3:] += dv[j]
            np.matmul(phi, xj, out=x[j + 1])
        return x
