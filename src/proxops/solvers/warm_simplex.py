"""Warm primal simplex for small dense LPs whose cost vector changes between solves.

Problem (the form of :class:`proxops.solvers.highs_lp.HighsLP`)::

    minimize c'x   subject to   rl <= A x <= ru,   lb <= x <= ub

Use case: support functions of 2-D sections (:class:`proxops.geometry.polytope.ConvexSection`),
dozens of LPs that differ only in c, each one or two pivots away from the previous optimum.
HiGHS re-solves them from its last basis but pays ~0.2 ms of fixed overhead per run; this keeps
the basis and its inverse (m x m, dense) between calls and pivots in one jitted kernel
(bounded primal simplex on z = [x; r], [A, -I] z = 0, Dantzig pricing, ratio test with bound
flips; Bland's rule after a degenerate pivot). It starts from a primal-feasible basis supplied by
the caller - an optimal HiGHS basis - and only takes cost changes. Anything it cannot settle
(iteration limit, an unbounded ray, a singular or drifting basis) is returned as a non-OPTIMAL
status: the caller re-solves with HiGHS and restarts from that basis.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from proxops.solvers.result import SolveStatus

LOWER, BASIC, UPPER, FREE = 0, 1, 2, 3  # HighsBasisStatus codes (kZero = free nonbasic)
REFACTOR_PIVOTS = 60  # the basis inverse is recomputed after this many eta updates


class WarmPrimalSimplex:
    """Bounded primal simplex warm-started from a primal-feasible basis (see module doc).

    ``A`` (m, n) dense, ``rl``/``ru`` (m,) and ``lb``/``ub`` (n,) bounds (+-inf allowed);
    ``col_status`` (n,), ``row_status`` (m,) HighsBasisStatus codes of a feasible basis and ``x``
    its primal point (n,). ``solve(c)`` -> (SolveStatus, x or None)."""

    def __init__(self, A, rl, ru, lb, ub, col_status, row_status, x, tol: float = 1e-9, max_iter: int = 200):
        A = np.ascontiguousarray(A, dtype=float)
        m, n = A.shape
        self.n, self.m = n, m
        self.K = np.ascontiguousarray(np.hstack([A, -np.eye(m)]))  # [A, -I] z = 0, z = [x; r]
        self.KT = np.ascontiguousarray(self.K.T)  # columns of K as rows (the kernel reads columns)
        self.lo = np.concatenate([np.asarray(lb, float), np.asarray(rl, float)])
        self.hi = np.concatenate([np.asarray(ub, float), np.asarray(ru, float)])
        state = np.concatenate([np.asarray(col_status), np.asarray(row_status)]).astype(np.int64)
        if np.any(state > FREE) or int(np.count_nonzero(state == BASIC)) != m:
            raise ValueError("not a basis: need m basic variables and no nonbasic status beyond 'zero'")
        self.state = state
        self.basis = np.flatnonzero(state == BASIC).astype(np.int64)
        x = np.asarray(x, float)
        self.z = np.concatenate([x, A @ x])
        at_lo, at_hi = state == LOWER, state == UPPER  # nonbasic at a bound (free nonbasic: their value)
        self.z[at_lo] = self.lo[at_lo]
        self.z[at_hi] = self.hi[at_hi]
        if not np.all(np.isfinite(self.z[state != BASIC])):
            raise ValueError("a nonbasic variable sits at an infinite bound")
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        self.scale = 1.0 + float(np.abs(self.K).max())
        self._cz = np.zeros(n + m)  # cost on z (rows cost nothing)
        self._refactor()

    def _refactor(self) -> None:
        """Basis inverse from scratch and the basic values from the nonbasic ones (K z = 0)."""
        B = self.K[:, self.basis]
        self.Binv = np.ascontiguousarray(np.linalg.inv(B))
        nb = self.state != BASIC
        self.z[self.basis] = -self.Binv @ (self.K[:, nb] @ self.z[nb])
        self.pivots = 0

    def solve(self, c: np.ndarray) -> tuple[SolveStatus, np.ndarray | None]:
        """Minimise c'x from the current basis; the basis is kept for the next call."""
        cz = self._cz
        cz[: self.n] = c
        try:
            if self.pivots >= REFACTOR_PIVOTS:
                self._refactor()
        except np.linalg.LinAlgError:
            return SolveStatus.NUMERICAL_ERROR, None
        code, pivots = _simplex(self.KT, self.lo, self.hi, cz, self.basis, self.state, self.Binv, self.z,
                                self.max_iter, self.tol)
        self.pivots += pivots
        if code != 0:
            return (SolveStatus.UNBOUNDED if code == 1 else SolveStatus.MAX_ITER), None
        # drift guard: the rows recomputed from x must hold their bounds (the kernel's check)
        if _row_excess(self.K, self.lo, self.hi, self.z) > self.tol * self.scale * (1.0 + float(np.abs(self.z).max())):
            return SolveStatus.NUMERICAL_ERROR, None
        return SolveStatus.OPTIMAL, self.z[: self.n].copy()


@njit(cache=True)
def _row_excess(K, lo, hi, z):  # pragma: no cover - compiled
    """Largest bound excess of x = z[:n] and of the rows r = A x recomputed from x (not z[n:])."""
    m, nz = K.shape
    n = nz - m
    worst = 0.0
    for j in range(n):
        worst = max(worst, lo[j] - z[j], z[j] - hi[j])
    for i in range(m):
        r = 0.0
        for j in range(n):
            r += K[i, j] * z[j]
        worst = max(worst, lo[n + i] - r, r - hi[n + i])
    return worst


@njit(cache=True)
def _simplex(KT, lo, hi, cz, basis, state, Binv, z, max_iter, tol):  # pragma: no cover - compiled
    """Bounded primal simplex iterations in place (KT = K^T, K = [A, -I]). Returns (code, pivots):
    code 0 optimal, 1 unbounded, 2 iteration limit. ``state``: 0 at lower, 1 basic, 2 at upper, 3 free."""
    nz, m = KT.shape
    y = np.empty(m)
    alpha = np.empty(m)
    bland = False
    pivots = 0
    for it in range(max_iter):
        # duals y = B^-T c_B (row sweeps over the basic variables with a cost)
        for i in range(m):
            y[i] = 0.0
        for k in range(m):
            ck = cz[basis[k]]
            if ck != 0.0:
                for i in range(m):
                    y[i] += Binv[k, i] * ck
        # pricing: d_j = c_j - K_j' y; Dantzig (largest violation), Bland (first) after a degenerate step
        q = -1
        best = 0.0
        direction = 0.0
        for j in range(nz):
            s = state[j]
            if s == 1 or not lo[j] < hi[j]:
                continue
            d = cz[j]
            for i in range(m):
                d -= KT[j, i] * y[i]
            if (s == 0 or s == 3) and -d > tol:
                score, cand = -d, 1.0  # increase z_j
            elif (s == 2 or s == 3) and d > tol:
                score, cand = d, -1.0  # decrease z_j
            else:
                continue
            if bland:
                q, direction = j, cand
                break
            if score > best:
                q, best, direction = j, score, cand
        if q < 0:
            return 0, pivots
        # alpha = B^-1 K_q; basic values move by -alpha * direction * theta
        for k in range(m):
            acc = 0.0
            for i in range(m):
                acc += Binv[k, i] * KT[q, i]
            alpha[k] = acc
        theta = hi[q] - lo[q]  # bound flip of the entering variable
        leave = -1
        leave_upper = False
        for k in range(m):
            delta = -alpha[k] * direction
            v = basis[k]
            if delta < -1e-12:
                t = (z[v] - lo[v]) / (-delta)
                up = False
            elif delta > 1e-12:
                t = (hi[v] - z[v]) / delta
                up = True
            else:
                continue
            if t < 0.0:
                t = 0.0
            if t < theta or (t == theta and leave >= 0 and v < basis[leave]):
                theta, leave, leave_upper = t, k, up
        if not theta < np.inf:
            return 1, pivots
        bland = theta <= 0.0  # degenerate step: Bland's rule until progress is made
        z[q] += direction * theta
        for k in range(m):
            z[basis[k]] -= alpha[k] * direction * theta
        if leave < 0:  # bound flip, basis unchanged
            state[q] = 2 if direction > 0 else 0
            continue
        v = basis[leave]
        z[v] = hi[v] if leave_upper else lo[v]
        state[v] = 2 if leave_upper else 0
        state[q] = 1
        basis[leave] = q
        piv = alpha[leave]
        for i in range(m):
            Binv[leave, i] /= piv
        for k in range(m):
            if k != leave and alpha[k] != 0.0:
                f = alpha[k]
                for i in range(m):
                    Binv[k, i] -= f * Binv[leave, i]
        pivots += 1
    return 2, pivots
