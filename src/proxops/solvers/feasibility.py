"""Check a solver's answer instead of trusting its status.

``check_feasibility`` measures how far ``x`` is from satisfying
``bl <= A x <= bu`` (and optional ``lb <= x <= ub``); ``check_conic_feasibility``
does the same for ``A x + s = b, s in K`` with the cones of
:mod:`proxops.solvers.clarabel_socp`. Violations are absolute, in the units of the
constraint rows.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from proxops.errors import input_error


class FeasibilityReport(NamedTuple):
    """feasible: max_violation <= tol; worst_index: row (A rows first, then bounds) or -1."""

    feasible: bool
    max_violation: float
    worst_index: int


def _matvec(A, x: np.ndarray) -> np.ndarray:
    if A is None:
        return np.zeros(0)
    return np.asarray(A @ x, dtype=float).reshape(-1)


def row_violations(A, bl, bu, x, lb=None, ub=None) -> np.ndarray:
    """Per-row violation max(bl - Ax, Ax - bu, 0) (then the bound rows); inf for NaN in x.

    ``bl``/``bu`` may be None (no side) and contain +-inf (no constraint on that side).
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    parts = []
    for M, lo, hi in ((A, bl, bu), (None, lb, ub)):
        if M is None and lo is None and hi is None:
            continue
        v = _matvec(M, x) if M is not None else x
        lo = np.full(v.shape, -np.inf) if lo is None else np.broadcast_to(np.asarray(lo, float), v.shape)
        hi = np.full(v.shape, np.inf) if hi is None else np.broadcast_to(np.asarray(hi, float), v.shape)
        with np.errstate(invalid="ignore"):
            viol = np.maximum(np.maximum(lo - v, v - hi), 0.0)
        viol[np.isnan(v)] = np.inf
        parts.append(viol)
    return np.concatenate(parts) if parts else np.zeros(0)


def max_violation(A, bl, bu, x, lb=None, ub=None) -> float:
    """Largest violation of ``bl <= A x <= bu`` and ``lb <= x <= ub`` (0 when satisfied)."""
    if x is None:
        return float("inf")
    viol = row_violations(A, bl, bu, x, lb, ub)
    return float(viol.max()) if viol.size else 0.0


def check_feasibility(A, bl, bu, x, tol: float = 1e-6, *, lb=None, ub=None) -> FeasibilityReport:
    """Check ``bl - tol <= A x <= bu + tol`` and ``lb - tol <= x <= ub + tol``.

    A: dense or sparse (m, n) or None; bl, bu: (m,) with +-inf allowed, or None;
    x: (n,) candidate (None counts as infeasible). Returns a :class:`FeasibilityReport`
    whose ``max_violation`` is in the units of the rows.
    """
    if x is None:
        return FeasibilityReport(False, float("inf"), -1)
    viol = row_violations(A, bl, bu, x, lb, ub)
    if viol.size == 0:
        return FeasibilityReport(True, 0.0, -1)
    worst = int(np.argmax(viol))
    worst_value = float(viol[worst])
    return FeasibilityReport(worst_value <= tol, worst_value, worst if worst_value > 0 else -1)


def check_conic_feasibility(A, b, cones, x, tol: float = 1e-6) -> FeasibilityReport:
    """Check ``s = b - A x`` lies in the product cone ``cones`` to within ``tol``.

    cones: sequence of ``(kind, dim)`` with kind "zero" (s = 0), "nonneg" (s >= 0) or
    "soc" (s[0] >= ||s[1:]||). Rows with b = +inf in a "nonneg" block are ignored.
    The violation of a "soc" block is ``max(||s[1:]|| - s[0], 0)`` and is reported
    at the block's first row.
    """
    if x is None:
        return FeasibilityReport(False, float("inf"), -1)
    x = np.asarray(x, dtype=float).reshape(-1)
    b = np.asarray(b, dtype=float).reshape(-1)
    Ax = _matvec(A, x)
    with np.errstate(invalid="ignore"):
        s = b - Ax
    viol = np.zeros(b.shape[0])
    row = 0
    for kind, dim in cones:
        block = s[row : row + dim]
        if kind == "zero":
            viol[row : row + dim] = np.abs(block)
        elif kind == "nonneg":
            with np.errstate(invalid="ignore"):
                v = np.maximum(-block, 0.0)
            v[np.isposinf(b[row : row + dim])] = 0.0
            viol[row : row + dim] = v
        elif kind == "soc":
            viol[row] = max(float(np.linalg.norm(block[1:])) - float(block[0]), 0.0)
        else:
            raise input_error("cone kind", kind, "allowed: zero, nonneg, soc")
        row += dim
    viol[np.isnan(viol)] = np.inf
    if viol.size == 0:
        return FeasibilityReport(True, 0.0, -1)
    worst = int(np.argmax(viol))
    worst_value = float(viol[worst])
    return FeasibilityReport(worst_value <= tol, worst_value, worst if worst_value > 0 else -1)


def farkas_margin(A_eq, b_eq, G, h_l, h_u, lb, ub, y, z_l, z_u) -> float:
    """Infeasibility margin proved by dual multipliers (a Farkas certificate, checked in full).

    Problem: ``A_eq x = b_eq``, ``h_l <= G x <= h_u``, ``lb <= x <= ub`` (sparse or dense matrices,
    +-inf sides allowed). Multipliers: ``y`` on the equalities, ``z_l, z_u >= 0`` on the lower/upper
    sides of the G rows (PIQP's sign convention; negative entries and entries on infinite sides are
    set to 0, and every row touching a column with an infinite bound is dropped so that column's
    coefficient is exactly 0). With ``s = A_eq' y + G' (z_u - z_l)`` and
    ``Phi = min_{lb<=x<=ub} s'x - y'b_eq - z_u'h_u + z_l'h_l``, every x within the bounds satisfies
    ``Phi <= (|y|_1 + |z_l|_1 + |z_u|_1) * v(x)`` with ``v(x)`` the largest violation of any row at x
    (the weighted sum of the row residuals equals ``s'x - y'b_eq - ...`` >= Phi). Returns
    ``(Phi - rounding bound) / (|y|_1 + |z_l|_1 + |z_u|_1)``: when positive, NO x within the bounds
    comes within that distance (row units) of satisfying every row, so the problem is infeasible.
    Returns -inf when the multipliers prove nothing (or are not finite)."""
    import scipy.sparse as sp

    lb = np.asarray(lb, dtype=float)
    ub = np.asarray(ub, dtype=float)
    A = sp.csc_matrix((0, len(lb))) if A_eq is None else sp.csc_matrix(A_eq)
    Gm = sp.csc_matrix((0, len(lb))) if G is None else sp.csc_matrix(G)
    b = np.zeros(0) if b_eq is None else np.asarray(b_eq, dtype=float)
    h_l = np.full(Gm.shape[0], -np.inf) if h_l is None else np.asarray(h_l, dtype=float)
    h_u = np.full(Gm.shape[0], np.inf) if h_u is None else np.asarray(h_u, dtype=float)
    y = np.array(y, dtype=float).reshape(-1)
    z_l = np.where(np.isfinite(h_l), np.maximum(np.asarray(z_l, dtype=float), 0.0), 0.0)
    z_u = np.where(np.isfinite(h_u), np.maximum(np.asarray(z_u, dtype=float), 0.0), 0.0)
    if not (np.isfinite(y).all() and np.isfinite(z_l).all() and np.isfinite(z_u).all()):
        return -math.inf
    unbounded = ~(np.isfinite(lb) & np.isfinite(ub))
    if unbounded.any():
        cols = np.flatnonzero(unbounded)
        y[np.unique(A[:, cols].nonzero()[0])] = 0.0
        rows = np.unique(Gm[:, cols].nonzero()[0])
        z_l[rows] = 0.0
        z_u[rows] = 0.0
    z = z_u - z_l
    s = A.T @ y + Gm.T @ z
    if np.any(s[unbounded] != 0.0):
        return -math.inf
    bounded = ~unbounded
    sb, lo, hi = s[bounded], lb[bounded], ub[bounded]
    box_min = np.minimum(sb * lo, sb * hi)
    gl, gu = np.isfinite(h_l), np.isfinite(h_u)
    terms = np.concatenate([box_min, -y * b, -z_u[gu] * h_u[gu], z_l[gl] * h_l[gl]])
    phi = float(terms.sum())
    # rounding: every sum above has fewer than k terms of the magnitudes below (gamma_k bound, doubled)
    k = A.shape[0] + Gm.shape[0] + len(lb) + 4
    s_abs = abs(A).T @ np.abs(y) + abs(Gm).T @ (z_u + z_l)
    size = float(s_abs[bounded] @ np.maximum(np.abs(lo), np.abs(hi)) + np.abs(terms).sum())
    phi -= 2.0 * k * np.finfo(float).eps * size
    norm = float(np.abs(y).sum() + z_l.sum() + z_u.sum())
    if not (phi > 0.0 and norm > 0.0 and math.isfinite(phi)):
        return -math.inf
    return phi / norm
