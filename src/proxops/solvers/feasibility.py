"""Check a solver's answer instead of trusting its status.

``check_feasibility`` measures how far ``x`` is from satisfying
``bl <= A x <= bu`` (and optional ``lb <= x <= ub``); ``check_conic_feasibility``
does the same for ``A x + s = b, s in K`` with the cones of
:mod:`proxops.solvers.clarabel_socp`. Violations are absolute, in the units of the
constraint rows.
"""

from __future__ import annotations

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
