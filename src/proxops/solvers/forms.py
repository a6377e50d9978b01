"""Canonical problem forms shared by every solver adapter.

Each adapter's ``setup(problem)`` takes one of these (the same object whichever solver
is chosen), ``update(...)`` takes the form's field names, and ``solve()`` returns a
:class:`proxops.solvers.SolverResult`:

- :class:`QuadraticProgram` (QP, LP when P is None): DAQP, PIQP, Clarabel, (HiGHS for P = 0)
- :class:`ConicProblem` (second-order cone program): Clarabel
- :class:`LinearProgram` ((mixed-integer) LP): HiGHS (:class:`HighsLP`, :class:`HighsMILP`)
- :class:`proxops.solvers.casadi_nlp.NonlinearProgram` (NLP): CasADi (IPOPT, fatrop)

Units are the caller's; every form is plain data (numpy / scipy.sparse), no solver import.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from proxops.errors import input_error
from proxops.solvers import _util


@dataclass
class QuadraticProgram:
    """``min 1/2 x'Px + q'x  s.t.  A_eq x = b_eq,  bl <= A x <= bu,  lb <= x <= ub``.

    P: (n, n) PSD or None (LP); A: (m, n) or None; bl/bu/lb/ub may hold +-inf or be None.
    A_eq/b_eq (optional): explicit equality rows. When they are given, the rows of A are
    kept as inequality rows whatever their bounds (a fixed row structure, so the data
    can be updated in place); without them, :func:`solve_qp` treats rows with bl == bu
    as equalities.
    """

    P: object
    q: np.ndarray
    A: object = None
    bl: np.ndarray | None = None
    bu: np.ndarray | None = None
    lb: np.ndarray | None = None
    ub: np.ndarray | None = None
    A_eq: object = None
    b_eq: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(np.size(self.q))

    def stacked(self) -> "QuadraticProgram":
        """The same problem with the equality rows stacked on top of A (bl = bu = b_eq), no A_eq."""
        if self.A_eq is None:
            return self
        n = self.n
        p = _util.rows_of("A_eq", self.A_eq)
        m = _util.rows_of("A", self.A)
        b_eq = _util.vector("b_eq", self.b_eq, p)
        A = sp.vstack([_util.csc_matrix("A_eq", self.A_eq, (p, n)), _util.csc_matrix("A", self.A, (m, n))],
                      format="csc")
        bl = np.concatenate([b_eq, _util.vector("bl", self.bl, m, fill=-np.inf, allow_inf=True)])
        bu = np.concatenate([b_eq, _util.vector("bu", self.bu, m, fill=np.inf, allow_inf=True)])
        return replace(self, A=A, bl=bl, bu=bu, A_eq=None, b_eq=None)

    def split_equalities(self) -> "QuadraticProgram":
        """The same problem with the rows of A that have bl == bu moved to A_eq (no-op when A_eq is set)."""
        if self.A_eq is not None or self.A is None:
            return self
        n = self.n
        m = _util.rows_of("A", self.A)
        A = _util.csc_matrix("A", self.A, (m, n)).tocsr()
        bl = _util.vector("bl", self.bl, m, fill=-np.inf, allow_inf=True)
        bu = _util.vector("bu", self.bu, m, fill=np.inf, allow_inf=True)
        eq = bl == bu
        if not eq.any():
            return self
        return replace(self, A=A[~eq] if (~eq).any() else None, bl=bl[~eq] if (~eq).any() else None,
                       bu=bu[~eq] if (~eq).any() else None, A_eq=A[eq], b_eq=bu[eq])


@dataclass
class LinearProgram:
    """``min c'x  s.t.  rl <= A x <= ru,  lb <= x <= ub``, x_j integer where ``integrality[j]``.

    A: (m, n) dense/sparse or None; rl/ru/lb/ub default to -inf/+inf (free variables);
    integrality: None (pure LP) or (n,) bool / 0-1 mask of integer variables (MILP,
    solved by :class:`proxops.solvers.HighsMILP`).
    """

    c: np.ndarray
    A: object = None
    rl: np.ndarray | None = None
    ru: np.ndarray | None = None
    lb: np.ndarray | None = None
    ub: np.ndarray | None = None
    integrality: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(np.size(self.c))

@dataclass
class ConicProblem:
    """``min 1/2 x'Px + q'x s.t. A x + s = b, s in cones`` with named row blocks.

    blocks maps "eq", "ineq", "lb", "ub", "soc0", "soc1", ... to row slices of A/b,
    so callers can update parts of ``b`` (e.g. ``b[prob.blocks["ineq"]] = h_new``).
    """

    P: sp.csc_matrix | None
    q: np.ndarray
    A: sp.csc_matrix
    b: np.ndarray
    cones: list[tuple[str, int]]
    blocks: dict[str, slice] = field(default_factory=dict)


def soc_rows(row0: int, head_cols, head_vals, tail_rows, tail_cols, tail_vals):
    """COO entries ``(rows, cols, vals)`` of A for one second-order cone block of the conic form
    ``A z + s = b``, ``s_0 >= ||(s_1, ..., s_k)||``, with ``s_0 = head . z + b_0`` and
    ``s_i = tail_i . z + b_i``: A holds the negated coefficients. The head row is ``row0``; entry
    ``e`` of the tail is in row ``row0 + tail_rows[e]`` (1..k), column ``tail_cols[e]``."""
    head_cols = np.atleast_1d(head_cols)
    rows = np.concatenate([np.full(head_cols.size, row0), row0 + np.atleast_1d(tail_rows)])
    cols = np.concatenate([head_cols, np.atleast_1d(tail_cols)])
    vals = -np.concatenate([np.atleast_1d(np.asarray(head_vals, float)), np.atleast_1d(np.asarray(tail_vals, float))])
    return rows, cols, vals


def build_conic_problem(q, P=None, *, eq=None, ineq=None, lb=None, ub=None, soc=()) -> ConicProblem:
    """Assemble a :class:`ConicProblem`.

    q: (n,) cost; P: (n, n) PSD or None;
    eq: (A_eq, b_eq) for A_eq x = b_eq;
    ineq: (G, h) for G x <= h (h may hold +inf: no constraint on that row);
    lb, ub: (n,) variable bounds (+-inf allowed);
    soc: sequence of (F, g, c, d) for ||F x + g||_2 <= c'x + d with F (k, n), g (k,),
    c (n,), d scalar. As a cone row block: s = [c'x + d; F x + g] = b - A x, so
    A = -[c'; F] and b = [d; g] (Clarabel form).
    """
    q = _util.vector("q", q, np.size(q))
    n = q.shape[0]
    rows, rhs, cones, blocks = [], [], [], {}
    start = 0

    def add(name, M, v, kind):
        nonlocal start
        k = M.shape[0]
        if k == 0:
            return
        rows.append(sp.csc_matrix(M))
        rhs.append(v)
        if cones and cones[-1][0] == kind and kind != "soc":
            cones[-1] = (kind, cones[-1][1] + k)
        else:
            cones.append((kind, k))
        blocks[name] = slice(start, start + k)
        start += k

    if eq is not None:
        A_eq, b_eq = eq
        m = _util.rows_of("eq[0]", A_eq)
        add("eq", _util.csc_matrix("eq[0]", A_eq, (m, n)), _util.vector("eq[1]", b_eq, m), "zero")
    if ineq is not None:
        G, h = ineq
        m = _util.rows_of("ineq[0]", G)
        add("ineq", _util.csc_matrix("ineq[0]", G, (m, n)), _util.vector("ineq[1]", h, m, allow_inf=True), "nonneg")
    if lb is not None:  # -x <= -lb
        add("lb", -sp.identity(n, format="csc"), -_util.vector("lb", lb, n, allow_inf=True), "nonneg")
    if ub is not None:  # x <= ub
        add("ub", sp.identity(n, format="csc"), _util.vector("ub", ub, n, allow_inf=True), "nonneg")
    for i, cone in enumerate(soc):
        if len(cone) != 4:
            raise input_error(f"soc[{i}]", f"{len(cone)} items", "must be (F, g, c, d) for ||F x + g|| <= c'x + d")
        F, g, c, d = cone
        k = _util.rows_of(f"soc[{i}].F", F)
        F = _util.csc_matrix(f"soc[{i}].F", F, (k, n))
        c = _util.vector(f"soc[{i}].c", c, n)
        M = sp.vstack([-sp.csc_matrix(c.reshape(1, n)), -F], format="csc")
        v = np.concatenate([[float(d)], _util.vector(f"soc[{i}].g", g, k)])
        add(f"soc{i}", M, v, "soc")
    A = sp.vstack(rows, format="csc") if rows else sp.csc_matrix((0, n))
    b = np.concatenate(rhs) if rhs else np.zeros(0)
    P_mat = None if P is None else _util.csc_matrix("P", P, (n, n))
    return ConicProblem(P=P_mat, q=q, A=A, b=b, cones=cones, blocks=blocks)


def conic_from_qp(P, q, A=None, bl=None, bu=None, lb=None, ub=None) -> ConicProblem:
    """Conic form of ``min 1/2 x'Px + q'x s.t. bl <= A x <= bu, lb <= x <= ub``.

    Rows with bl == bu become equalities; the others give ``A x <= bu`` and
    ``-A x <= -bl`` rows (infinite sides become ignored +inf rows).
    """
    q = _util.vector("q", q, np.size(q))
    n = q.shape[0]
    m = _util.rows_of("A", A)
    A = _util.csc_matrix("A", A, (m, n))
    bl = _util.vector("bl", bl, m, fill=-np.inf, allow_inf=True)
    bu = _util.vector("bu", bu, m, fill=np.inf, allow_inf=True)
    is_eq = bl == bu
    A_csr = A.tocsr()
    eq = (A_csr[is_eq], bu[is_eq]) if is_eq.any() else None
    rest = ~is_eq
    G = sp.vstack([A_csr[rest], -A_csr[rest]], format="csc")
    h = np.concatenate([bu[rest], -bl[rest]])
    return build_conic_problem(q, P, eq=eq, ineq=(G, h) if G.shape[0] else None, lb=lb, ub=ub)




def conic_from_program(problem: QuadraticProgram) -> ConicProblem:
    """Conic form of a :class:`QuadraticProgram` (A_eq rows as equalities; see :func:`conic_from_qp`)."""
    if problem.A_eq is None:
        return conic_from_qp(problem.P, problem.q, problem.A, problem.bl, problem.bu, problem.lb, problem.ub)
    q = _util.vector("q", problem.q, np.size(problem.q))
    n = q.shape[0]
    p = _util.rows_of("A_eq", problem.A_eq)
    m = _util.rows_of("A", problem.A)
    A = _util.csc_matrix("A", problem.A, (m, n))
    bl = _util.vector("bl", problem.bl, m, fill=-np.inf, allow_inf=True)
    bu = _util.vector("bu", problem.bu, m, fill=np.inf, allow_inf=True)
    G = sp.vstack([A, -A], format="csc")
    h = np.concatenate([bu, -bl])
    return build_conic_problem(q, problem.P, eq=(problem.A_eq, _util.vector("b_eq", problem.b_eq, p)),
                               ineq=(G, h) if G.shape[0] else None, lb=problem.lb, ub=problem.ub)
