"""Clarabel adapter: conic QP / SOCP by an interior-point method.

Problem (Clarabel's native form)::

    minimize    1/2 x' P x + q' x
    subject to  A x + s = b,   s in K = K_1 x ... x K_p

with cones given as ``(kind, dim)``: ``("zero", m)`` (s = 0, equalities),
``("nonneg", m)`` (s >= 0, i.e. A x <= b) and ``("soc", m)`` (s[0] >= ||s[1:]||).
:func:`build_conic_problem` assembles (A, b, cones) from equalities, inequalities,
bounds and second-order cones ``||F x + g|| <= c'x + d``.

Clarabel's presolve is switched off so data can be updated in place (its
``update`` keeps the symbolic factorisation); Clarabel has no warm start. Rows of a
``nonneg`` cone with ``b = +inf`` (no constraint) are removed before Clarabel sees
them (with presolve off Clarabel mis-reports such problems as dual infeasible);
an update that makes such a row finite again, or changes a matrix's sparsity
pattern, sets the solver up again (``info["rebuilt"] = True``).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import scipy.sparse as sp

from proxops.errors import input_error
from proxops.solvers import _util
from proxops.solvers.forms import (  # noqa: F401 (build_conic_problem, conic_from_qp re-exported)
    ConicProblem,
    QuadraticProgram,
    build_conic_problem,
    conic_from_program,
    conic_from_qp,
)
from proxops.solvers.base import SolverAdapter
from proxops.solvers.result import SolverResult, SolveStatus, error_message, failed_result

CONE_KINDS = ("zero", "nonneg", "soc")

# clarabel.SolverStatus names.
STATUS_MAP = {
    "Solved": SolveStatus.OPTIMAL,
    "AlmostSolved": SolveStatus.OPTIMAL_INACCURATE,
    "PrimalInfeasible": SolveStatus.INFEASIBLE,
    "AlmostPrimalInfeasible": SolveStatus.INFEASIBLE,
    "DualInfeasible": SolveStatus.UNBOUNDED,
    "AlmostDualInfeasible": SolveStatus.UNBOUNDED,
    "MaxIterations": SolveStatus.MAX_ITER,
    "MaxTime": SolveStatus.TIME_LIMIT,
    "NumericalError": SolveStatus.NUMERICAL_ERROR,
    "InsufficientProgress": SolveStatus.NUMERICAL_ERROR,
    "Unsolved": SolveStatus.NUMERICAL_ERROR,
    "CallbackTerminated": SolveStatus.NUMERICAL_ERROR,
}

# first-attempt statuses that a solver with ``retry_settings`` solves again
RETRY_STATUSES = (SolveStatus.OPTIMAL_INACCURATE, SolveStatus.NUMERICAL_ERROR, SolveStatus.MAX_ITER)


class ClarabelSOCP(SolverAdapter):
    """Persistent Clarabel solver for ``min 1/2 x'Px + q'x s.t. A x + s = b, s in K``.

    Settings: ``max_iter``, ``time_limit_s``, ``tol_gap_rel``, ``tol_feas``, ``verbose``;
    ``settings`` passes native ``clarabel.DefaultSettings`` attributes. ``retry_settings``
    (native attributes overriding those): when a solve ends OPTIMAL_INACCURATE, NUMERICAL_ERROR
    or MAX_ITER, the same data are solved once more by a solver set up with them (e.g. lean
    settings for speed, Clarabel's defaults as the fallback); the result reports both attempts
    (``info["first_attempt"]``, times and iterations added up).
    """

    name = "clarabel"
    forms = (ConicProblem, QuadraticProgram)

    def __init__(self, *, max_iter: int | None = None, time_limit_s: float | None = None,
                 tol_gap_rel: float | None = None, tol_feas: float | None = None,
                 verbose: bool = False, settings: dict | None = None, retry_settings: dict | None = None):
        self._clarabel = _util.import_solver("clarabel", "clarabel")
        native = {"verbose": bool(verbose), "presolve_enable": False, "input_sparse_dropzeros": False}
        if max_iter is not None:
            native["max_iter"] = int(max_iter)
        if time_limit_s is not None:
            native["time_limit"] = float(time_limit_s)
        if tol_gap_rel is not None:
            native["tol_gap_rel"] = float(tol_gap_rel)
        if tol_feas is not None:
            native["tol_feas"] = float(tol_feas)
        native.update(settings or {})
        allowed = {k for k in dir(self._clarabel.DefaultSettings()) if not k.startswith("_")}
        self._native_settings({**native, **(retry_settings or {})}, allowed, "clarabel")
        self._native = native
        self._retry_native = {**native, **retry_settings} if retry_settings is not None else None
        self._solver = None
        self._data: dict | None = None
        self._qp: QuadraticProgram | None = None  # the QP form set up (update re-converts it)

    # ------------------------------------------------------------------ set-up
    def _setup_form(self, problem) -> None:
        """Set up a :class:`ConicProblem` (``update`` takes P, q, A, b) or a :class:`QuadraticProgram`
        (converted by :func:`conic_from_program`; ``update`` then takes the QP's names and re-converts)."""
        qp = None
        if isinstance(problem, QuadraticProgram):
            qp = dataclasses.replace(problem)
            problem = conic_from_program(problem)
        self.setup_native(problem.P, problem.q, problem.A, problem.b, problem.cones)
        self._qp = qp

    def warm_start(self, x=None, y=None) -> bool:
        """Clarabel (an interior-point method) has no warm start: nothing is used; returns False."""
        return False

    def setup_native(self, P, q, A, b, cones) -> None:
        """Set up the problem; cones is a sequence of (kind, dim), kind in zero/nonneg/soc,
        dims summing to the rows of A. P may be None (LP/SOCP); only its upper triangle is used.
        ``update`` then takes these names (P, q, A, b)."""
        self._native_setup_done()
        self._qp = None
        q = _util.cost_vector("q", q)
        n = q.shape[0]
        m = _util.rows_of("A", A)
        cones = [(str(kind), int(dim)) for kind, dim in cones]
        for kind, dim in cones:
            if kind not in CONE_KINDS:
                raise input_error("cone kind", kind, f"allowed: {', '.join(CONE_KINDS)}")
            if dim < 1 or (kind == "soc" and dim < 2):
                raise input_error(f"{kind} cone dim", dim, "must be >= 1 (>= 2 for soc)")
        if sum(dim for _, dim in cones) != m:
            raise input_error("cones", cones, f"dimensions must add up to the {m} rows of A")
        self.n, self.m, self.cones = n, m, cones
        self._bad = _util.BadData()
        kind_of_row = np.concatenate([[kind] * dim for kind, dim in cones]) if cones else np.zeros(0, str)
        self._nonneg_row = kind_of_row == "nonneg"
        self._data = {
            "P": _util.csc_matrix("P", P, (n, n), upper=True, allow_nonfinite=True),
            "q": q,
            "A": _util.csc_matrix("A", A, (m, n), allow_nonfinite=True),
            "b": _util.vector("b", b, m, allow_inf=True, allow_nan=True),
        }
        for key in ("P", "q", "A"):
            self._bad.check(key, self._data[key])
        self._check_b()
        self._build()
        self._rebuilt = False

    def _check_b(self) -> None:
        """Validate b: NaN anywhere or inf in zero/soc rows is bad data; -inf in a nonneg row is infeasible."""
        b = self._data["b"]
        bad = np.isnan(b) | (np.isinf(b) & ~self._nonneg_row)
        if bad.any():
            self._bad.fields.add("b")
        else:
            self._bad.fields.discard("b")
        neg = np.flatnonzero(np.isneginf(b) & self._nonneg_row)
        self._crossed = f"b[{int(neg[0])}] = -inf in a nonneg row (A x <= -inf)" if neg.size else None

    def _row_mask(self) -> np.ndarray:
        return ~(np.isposinf(self._data["b"]) & self._nonneg_row)

    def _reduced(self):
        """Data with the +inf nonneg rows removed, and the matching cone list."""
        keep = self._row_mask()
        A = self._data["A"][np.flatnonzero(keep)] if not keep.all() else self._data["A"]
        A = sp.csc_matrix(A)
        A.sort_indices()
        if keep.all():  # every row kept: the cones as set up
            return keep, A, self._data["b"], list(self.cones)
        cones, row = [], 0
        for kind, dim in self.cones:
            kept = int(keep[row : row + dim].sum())
            if kept:
                cones.append((kind, kept))
            row += dim
        return keep, A, self._data["b"][keep], cones

    def _build(self) -> None:
        """(Re)create the Clarabel solver from the stored data."""
        self._solver_error = None
        self._rebuilt = True
        self._solver = None
        if self._bad.fields or self._crossed is not None:
            self._keep = None  # built once the data are usable
            return
        reduced = self._reduced()
        self._keep, self._A_red = reduced[0], reduced[1]
        try:
            self._solver = self._new_solver(self._native, reduced)
        except Exception as exc:
            self._solver_error = error_message(exc)

    def _new_solver(self, native: dict, reduced=None):
        """A Clarabel solver for the stored data (+inf nonneg rows removed; ``reduced``: that data from
        :meth:`_reduced` when at hand) with the native settings."""
        cl = self._clarabel
        _, A, b, cones = self._reduced() if reduced is None else reduced
        makers = {"zero": cl.ZeroConeT, "nonneg": cl.NonnegativeConeT, "soc": cl.SecondOrderConeT}
        settings = cl.DefaultSettings()
        for key, value in native.items():
            setattr(settings, key, value)
        return cl.DefaultSolver(self._data["P"], self._data["q"], A, b, [makers[k](d) for k, d in cones], settings)

    # ------------------------------------------------------------------ update
    def _native_fields(self) -> dict:
        # a QP set-up keeps P and q as they are; its rows become cone rows (no one-to-one field)
        return {k: k for k in (("P", "q") if self._qp is not None else ("P", "q", "A", "b"))}

    def _update_form(self, **fields) -> None:
        """:meth:`update` after ``setup(form)``: a ConicProblem's P, q, A, b in place; a
        QuadraticProgram's fields re-converted (set up again when the equality split changes the cones)."""
        if self._qp is None:
            if "cones" in fields or "blocks" in fields:
                raise input_error("ClarabelSOCP.update", "cones/blocks", "the cone structure is fixed; set up again")
            self.update_native(**fields)
            return
        qp = dataclasses.replace(self._qp, **fields)
        conic = conic_from_program(qp)
        if conic.cones != self.cones:
            self.setup(qp)
            return
        self._qp = qp
        self.update_native(P=conic.P if "P" in fields else None, q=conic.q, A=conic.A, b=conic.b)

    def update_native(self, *, P=None, q=None, A=None, b=None) -> None:
        """Change data in place (same sizes and cones). A new sparsity pattern in P or A,
        or a nonneg row switching between finite and +inf b, sets the solver up again."""
        if self._data is None:
            raise input_error("ClarabelSOCP.update", "called before setup", "call setup() first")
        d = self._data
        rebuild = self._solver is None or self._solver_error is not None
        changed = {}
        if P is not None:
            new = _util.csc_matrix("P", P, (self.n, self.n), upper=True, allow_nonfinite=True)
            rebuild |= not _util.same_pattern(new, d["P"])
            d["P"] = new
            if self._bad.check("P", new):
                changed["P"] = new.data
        if q is not None:
            d["q"] = _util.vector("q", q, self.n, allow_nan=True)
            if self._bad.check("q", d["q"]):
                changed["q"] = d["q"]
        if A is not None:
            new = _util.csc_matrix("A", A, (self.m, self.n), allow_nonfinite=True)
            d["A"] = new
            self._bad.check("A", new)
        if b is not None:
            d["b"] = _util.vector("b", b, self.m, allow_inf=True, allow_nan=True)
            self._check_b()
        if self._bad.fields or self._crossed is not None:
            return  # solve() reports the problem; the solver is rebuilt once data are usable
        keep = self._row_mask()
        if self._keep is None or not np.array_equal(keep, self._keep):
            rebuild = True
        if not rebuild and A is not None:
            A_red = sp.csc_matrix(d["A"][np.flatnonzero(keep)]) if not keep.all() else d["A"]
            A_red.sort_indices()
            if _util.same_pattern(A_red, self._A_red):
                self._A_red = A_red
                changed["A"] = A_red.data
            else:
                rebuild = True
        if b is not None:
            changed["b"] = d["b"][keep]
        if rebuild or not self._solver.is_data_update_allowed():
            self._build()
            return
        if changed:
            try:
                self._solver.update(**changed)
            except Exception as exc:
                self._solver_error = error_message(exc)

    def update_fast(self, *, b: np.ndarray | None = None, A_values: np.ndarray | None = None, **others) -> None:
        """Lean :meth:`update_native` of ``b`` and the values of ``A`` for trusted data (per-step use).

        ``A_values``: the nonzero values of A in the set-up sparsity pattern, in the order of the
        canonical CSC matrix (sorted row indices, no duplicates; ``A.data`` of a matrix built that
        way). The caller guarantees finite values, b of the set-up size with no NaN, no inf in
        zero/soc rows and no nonneg row switching between finite and +inf b. Nothing is checked
        or converted (saves the ~0.1-0.4 ms of :meth:`update`'s checks and matrix copies);
        after a failed set-up, with rows removed (+inf b) or with a
        :class:`QuadraticProgram` set-up it falls back to :meth:`update_native`, as do the other
        native fields (``others``: P, q, A)."""
        d = self._data
        if others:
            self.update_native(**others)
        if (d is None or self._qp is not None or self._solver is None or self._solver_error is not None
                or self._bad.fields or self._crossed is not None or self._keep is None or not self._keep.all()):
            A = None
            if A_values is not None and d is not None:
                A = d["A"].copy()
                A.data[:] = A_values
            self.update_native(b=b, A=A)
            return
        changed = {}
        if A_values is not None:
            d["A"].data[:] = A_values
            changed["A"] = d["A"].data
        if b is not None:
            d["b"][:] = b
            changed["b"] = d["b"]
        if changed:
            try:
                self._solver.update(**changed)
            except Exception as exc:
                self._solver_error = error_message(exc)

    def rebuild(self, *, b: np.ndarray | None = None, A_values: np.ndarray | None = None) -> None:
        """Set ``b`` and the values of A like :meth:`update_fast` (trusted data, the same conditions) and set
        the native solver up again from them: a fresh equilibration and factorisation, so the next solve is
        the one of a new :meth:`setup` with these data (an in-place update keeps the scaling computed from
        the first data). For a problem reused with new data (the CORTEX phases reuse one set-up per node
        grid); after a failed set-up or with rows removed it is :meth:`update_native` then a set-up."""
        d = self._data
        if (d is None or self._qp is not None or self._bad.fields or self._crossed is not None or self._keep is None
                or not self._keep.all()):
            A = None
            if A_values is not None and d is not None:
                A = d["A"].copy()
                A.data[:] = A_values
            self.update_native(b=b, A=A)
            if self._data is not None and not self._bad.fields and self._crossed is None:
                self._build()
            return
        if A_values is not None:
            d["A"].data[:] = A_values
        if b is not None:
            d["b"][:] = b
        self._build()

    # ------------------------------------------------------------------ solve
    def solve(self) -> SolverResult:
        """Solve the current problem and return a :class:`SolverResult` (with ``retry_settings``, a
        second attempt after an inaccurate, failed or iteration-limited first one)."""
        blocked = self._blocked("infinite_rhs")
        if blocked is not None:
            return blocked
        if self._solver is None:
            return failed_result(self.name, "clarabel solver was not set up")
        rebuilt, self._rebuilt = self._rebuilt, False
        res = self._run(self._solver, rebuilt)
        if self._retry_native is None or res.status not in RETRY_STATUSES:
            return res
        try:
            retry_solver = self._new_solver(self._retry_native)
        except Exception as exc:
            res.info["retry_error"] = error_message(exc)
            return res
        second = self._run(retry_solver, rebuilt)
        second.iterations += res.iterations
        second.solve_time_s += res.solve_time_s
        second.info["first_attempt"] = {"raw_status": res.info.get("raw_status", ""), "iterations": res.iterations,
                                        "solve_time_s": res.solve_time_s}
        return second

    def _run(self, solver, rebuilt: bool) -> SolverResult:
        try:
            t0 = time.perf_counter()
            sol = solver.solve()
            wall = time.perf_counter() - t0
            raw = str(sol.status)
            x = np.array(sol.x, dtype=float)
            objective = float(sol.obj_val)
            iterations = int(sol.iterations)
            z = np.full(self.m, 0.0)
            z[self._keep] = np.asarray(sol.z, dtype=float)
            solver_time = float(sol.solve_time)
        except Exception as exc:
            return failed_result(self.name, error_message(exc), rebuilt=rebuilt)
        return self._result(STATUS_MAP.get(raw, SolveStatus.NUMERICAL_ERROR), x, objective, iterations, wall,
                            {"raw_status": raw, "rebuilt": rebuilt, "solver_time_s": solver_time, "dual": z})
