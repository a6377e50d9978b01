"""HiGHS adapter: pure LP by the dual simplex method, hot-started from the last basis.

Problem::

    minimize    c' x
    subject to  rl <= A x <= ru
                lb <= x <= ub

``setup`` passes the model once; ``update`` changes costs and bounds through
``changeColsCost`` / ``changeColsBounds`` / ``changeRowsBounds``, which keep HiGHS's
basis, so the next ``run`` hot-starts from the previous optimal basis (a cost change
that leaves the basis optimal takes 0 simplex iterations). A matrix update re-passes
the model and restores the saved basis.

LP only on purpose: issue #4 measured HiGHS returning "optimal" with a cost 34x too
high on the QP form of the fuel problem, so quadratic problems go to DAQP, PIQP or
Clarabel.
"""

from __future__ import annotations

import math
import time

import numpy as np

from proxops.errors import input_error
from proxops.solvers import _util
from proxops.solvers.base import SolverAdapter
from proxops.solvers.forms import LinearProgram
from proxops.solvers.result import SolverResult, SolveStatus, error_message, failed_result

# highspy.HighsModelStatus names.
STATUS_MAP = {
    "kOptimal": SolveStatus.OPTIMAL,
    "kInfeasible": SolveStatus.INFEASIBLE,
    "kUnbounded": SolveStatus.UNBOUNDED,
    "kUnboundedOrInfeasible": SolveStatus.INFEASIBLE,  # only after the presolve-off re-run below
    "kTimeLimit": SolveStatus.TIME_LIMIT,
    "kIterationLimit": SolveStatus.MAX_ITER,
    "kNotset": SolveStatus.NUMERICAL_ERROR,
    "kLoadError": SolveStatus.NUMERICAL_ERROR,
    "kModelError": SolveStatus.NUMERICAL_ERROR,
    "kPresolveError": SolveStatus.NUMERICAL_ERROR,
    "kSolveError": SolveStatus.NUMERICAL_ERROR,
    "kPostsolveError": SolveStatus.NUMERICAL_ERROR,
    "kModelEmpty": SolveStatus.NUMERICAL_ERROR,
    "kObjectiveBound": SolveStatus.NUMERICAL_ERROR,
    "kObjectiveTarget": SolveStatus.NUMERICAL_ERROR,
    "kUnknown": SolveStatus.NUMERICAL_ERROR,
    "kSolutionLimit": SolveStatus.NUMERICAL_ERROR,
    "kInterrupt": SolveStatus.NUMERICAL_ERROR,
    "kMemoryLimit": SolveStatus.NUMERICAL_ERROR,
    "kHighsInterrupt": SolveStatus.NUMERICAL_ERROR,
}


def _quiet_highs(highspy):
    """``highspy.Highs()`` with its start-up banner kept off stdout: HiGHS 1.16 prints "Running HiGHS ..."
    from C++ on the first construction, before ``output_flag`` can be set, which broke ``--json`` output
    (exactly one JSON object on stdout). The process-level stdout (fd 1) is pointed at /dev/null for the
    construction only."""
    import os
    import sys

    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):  # no real fd 1 (e.g. captured stdout)
        return highspy.Highs()
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, 1)
            return highspy.Highs()
        finally:
            os.dup2(saved, 1)
            os.close(devnull)
    finally:
        os.close(saved)


class HighsLP(SolverAdapter):
    """Persistent HiGHS LP solver for ``min c'x s.t. rl <= Ax <= ru, lb <= x <= ub``.

    Settings: ``time_limit_s``, ``max_iter`` (simplex iteration limit), ``verbose``;
    ``settings`` passes native HiGHS options (e.g. ``{"solver": "ipm"}``,
    ``{"primal_feasibility_tolerance": 1e-9}``).
    """

    name = "highs"
    forms = (LinearProgram,)
    mip = False

    def __init__(self, *, time_limit_s: float | None = None, max_iter: int | None = None,
                 verbose: bool = False, settings: dict | None = None):
        self._highspy = _util.import_solver("highspy", "highspy")
        native = {"output_flag": bool(verbose)}
        if time_limit_s is not None:
            native["time_limit"] = float(time_limit_s)
        if max_iter is not None:
            native["simplex_iteration_limit"] = int(max_iter)
        native.update(settings or {})
        self._native = native
        self._h = None
        self._data: dict | None = None
        self._integrality = None

    # ------------------------------------------------------------------ set-up
    def _setup_form(self, problem: LinearProgram) -> None:
        """Pass a :class:`LinearProgram` to HiGHS (``update`` takes its names c, A, rl, ru, lb, ub)."""
        integ = None
        if problem.integrality is not None:
            integ = np.asarray(problem.integrality, dtype=bool).reshape(-1)
            if integ.shape != (np.size(problem.c),):
                raise input_error("integrality.shape", integ.shape, f"must be ({np.size(problem.c)},) like c")
            if not self.mip and integ.any():
                raise input_error("integrality", "integer variables", "HighsLP solves LPs; use HighsMILP")
        self._setup(problem.c, problem.A, problem.rl, problem.ru, problem.lb, problem.ub, integ if self.mip else None)

    def _native_fields(self) -> dict:
        return {k: k for k in ("c", "A", "rl", "ru", "lb", "ub")}

    def warm_start(self, x=None, y=None) -> bool:
        """Hand HiGHS a starting point ``x`` (n,) (``setSolution``; for a MILP a first incumbent);
        without ``x`` the last basis is kept (hot start). Returns True when HiGHS accepted it."""
        if self._data is None:
            raise input_error(f"{type(self).__name__}.warm_start", "called before setup", "call setup() first")
        if x is None:
            return True
        sol = self._highspy.HighsSolution()
        sol.col_value = list(_util.vector("x", x, self.n))
        sol.value_valid = True
        try:
            status = self._h.setSolution(sol)
        except Exception:  # noqa: BLE001 - an unusable guess is just not used
            return False
        return getattr(status, "name", "") != "kError"

    def setup_native(self, c, A=None, rl=None, ru=None, lb=None, ub=None) -> None:
        """Pass the LP to HiGHS. A dense or sparse (m, n) or None; rl/ru default -inf/+inf,
        lb/ub default -inf/+inf (note: HiGHS's own default lb is 0, ours is free). The names are those
        of :class:`LinearProgram`; a MILP needs ``setup(LinearProgram(..., integrality=...))``."""
        self._native_setup_done()
        self._setup(c, A, rl, ru, lb, ub, None)

    def _setup(self, c, A, rl, ru, lb, ub, integrality) -> None:
        self._integrality = integrality
        c = _util.vector("c", c, np.size(c), allow_nan=True)
        n = c.shape[0]
        if n == 0:
            raise input_error("c", "empty", "the problem needs at least one variable")
        m = _util.rows_of("A", A)
        self.n, self.m = n, m
        self._bad = _util.BadData()
        self._data = {
            "c": c,
            "A": _util.csc_matrix("A", A, (m, n), allow_nonfinite=True),
            "rl": _util.vector("rl", rl, m, fill=-np.inf, allow_inf=True, allow_nan=True),
            "ru": _util.vector("ru", ru, m, fill=np.inf, allow_inf=True, allow_nan=True),
            "lb": _util.vector("lb", lb, n, fill=-np.inf, allow_inf=True, allow_nan=True),
            "ub": _util.vector("ub", ub, n, fill=np.inf, allow_inf=True, allow_nan=True),
        }
        for key, value in self._data.items():
            self._bad.check(key, value, allow_inf=key not in ("c", "A"))
        self._check_crossed()
        self._cols = np.arange(n, dtype=np.int32)
        self._rows = np.arange(m, dtype=np.int32)
        self._h = _quiet_highs(self._highspy) if not self._native.get("output_flag", False) else self._highspy.Highs()
        self._solver_error = None
        for key, value in self._native.items():
            try:
                status = self._h.setOptionValue(key, value)
            except Exception as exc:  # e.g. wrong value type
                raise input_error("highs settings", {key: value}, f"rejected by HiGHS ({exc})") from exc
            if getattr(status, "name", "") == "kError":
                raise input_error("highs settings", {key: value}, "not a valid HiGHS option/value")
        self._pass_model(keep_basis=False)

    def _pass_model(self, keep_basis: bool) -> None:
        hs, d = self._highspy, self._data
        clean = lambda a: np.nan_to_num(a, nan=0.0)  # noqa: E731  (bad data is reported at solve)
        try:
            basis = self._h.getBasis() if keep_basis else None
            lp = hs.HighsLp()
            lp.num_col_, lp.num_row_ = self.n, self.m
            lp.col_cost_ = clean(d["c"])
            lp.col_lower_, lp.col_upper_ = clean(d["lb"]), clean(d["ub"])
            lp.row_lower_, lp.row_upper_ = clean(d["rl"]), clean(d["ru"])
            A = d["A"]
            lp.a_matrix_.format_ = hs.MatrixFormat.kColwise
            lp.a_matrix_.num_col_, lp.a_matrix_.num_row_ = self.n, self.m
            lp.a_matrix_.start_ = A.indptr.astype(np.int32)
            lp.a_matrix_.index_ = A.indices.astype(np.int32)
            lp.a_matrix_.value_ = clean(A.data)
            if self._integrality is not None:
                kinds = (hs.HighsVarType.kContinuous, hs.HighsVarType.kInteger)
                lp.integrality_ = [kinds[int(v)] for v in self._integrality]
            status = self._h.passModel(lp)
            if getattr(status, "name", "") == "kError":
                self._solver_error = "highs rejected the model (passModel returned kError)"
                return
            if basis is not None and basis.valid:
                self._h.setBasis(basis)
        except Exception as exc:
            self._solver_error = error_message(exc)

    def _check_crossed(self) -> None:
        self._check_crossed_pairs((("rl", "ru", "row"), ("lb", "ub", "bound of x")))

    # ------------------------------------------------------------------ update
    def update_native(self, *, c=None, rl=None, ru=None, lb=None, ub=None, A=None) -> None:
        """Change costs/bounds (kept basis: hot start) or A (model re-passed, basis restored); the
        names of :class:`LinearProgram` (``update`` after ``setup``)."""
        if self._data is None:
            raise input_error("HighsLP.update", "called before setup", "call setup() first")
        d = self._data
        sizes = {"c": self.n, "rl": self.m, "ru": self.m, "lb": self.n, "ub": self.n}
        given = {"c": c, "rl": rl, "ru": ru, "lb": lb, "ub": ub}
        for key, value in given.items():
            if value is not None:
                d[key] = _util.vector(key, value, sizes[key], allow_inf=key != "c", allow_nan=True)
                self._bad.check(key, d[key], allow_inf=key != "c")
        if A is not None:
            d["A"] = _util.csc_matrix("A", A, (self.m, self.n), allow_nonfinite=True)
            self._bad.check("A", d["A"])
        self._check_crossed()
        if self._bad.fields or self._solver_error is not None:
            return
        try:
            if A is not None:
                self._pass_model(keep_basis=True)
                return
            if c is not None:
                self._h.changeColsCost(self.n, self._cols, d["c"])
            if lb is not None or ub is not None:
                self._h.changeColsBounds(self.n, self._cols, d["lb"], d["ub"])
            if (rl is not None or ru is not None) and self.m:
                self._h.changeRowsBounds(self.m, self._rows, d["rl"], d["ru"])
        except Exception as exc:
            self._solver_error = error_message(exc)

    # ------------------------------------------------------------------ solve
    def solve(self) -> SolverResult:
        """Run HiGHS (hot-started when a basis is available) and return a :class:`SolverResult`."""
        blocked = self._blocked("crossed_bounds")
        if blocked is not None:
            return blocked
        h = self._h
        info_extra = {}
        try:
            t0 = time.perf_counter()
            h.run()
            raw = h.getModelStatus().name
            if raw == "kUnboundedOrInfeasible":
                # presolve could not tell which; the simplex without presolve can.
                h.setOptionValue("presolve", "off")
                h.run()
                h.setOptionValue("presolve", self._native.get("presolve", "choose"))
                raw = h.getModelStatus().name
                info_extra["presolve_off_rerun"] = True
            wall = time.perf_counter() - t0
            info = h.getInfo()
            iterations = int(info.simplex_iteration_count) + max(int(info.ipm_iteration_count), 0)
            objective = float(info.objective_function_value)
            sol = h.getSolution()
            x = np.array(sol.col_value, dtype=float) if sol.value_valid else None
            dual = np.array(sol.row_dual, dtype=float) if sol.dual_valid else None
            primal_feasible = int(info.primal_solution_status) == 2
            if self.mip:
                iterations = int(info.mip_node_count)
                info_extra.update(mip_gap=float(info.mip_gap), mip_dual_bound=float(info.mip_dual_bound),
                                  simplex_iterations=int(info.simplex_iteration_count))
        except Exception as exc:
            return failed_result(self.name, error_message(exc))
        status = STATUS_MAP.get(raw, SolveStatus.NUMERICAL_ERROR)
        if status is SolveStatus.OPTIMAL and (x is None or not primal_feasible):
            status = SolveStatus.NUMERICAL_ERROR
        return self._result(status, x, objective, iterations, wall, {"raw_status": raw, "dual": dual, **info_extra})


class HighsMILP(HighsLP):
    """Persistent HiGHS branch-and-cut solver for a :class:`LinearProgram` with integer variables
    (``integrality``); same settings, ``update`` and status map as :class:`HighsLP`.

    ``iterations`` is the branch-and-bound node count; ``info`` adds ``mip_gap`` (relative
    primal-dual gap at exit), ``mip_dual_bound`` and ``simplex_iterations``; ``dual`` is None
    (a MILP has no LP duals). ``warm_start(x)`` gives HiGHS a first incumbent. Setting
    ``settings={"mip_rel_gap": ...}`` changes HiGHS's optimality gap (default 1e-4).
    """

    name = "highs_mip"
    mip = True
