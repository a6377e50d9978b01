"""DAQP adapter: dense QP with a persistent, warm-started active set.

Problem (DAQP's native form)::

    minimize    1/2 x' H x + f' x
    subject to  bl <= A x <= bu        (general rows; bl == bu makes an equality)
                lb <= x <= ub          (simple bounds, optional)

``setup`` builds one ``daqp.Model`` (memory allocated once); ``update`` changes data
in place and keeps DAQP's working set, so the next ``solve`` starts from the previous
active set (warm start). ``update_fast(f=, bu=, bl=)`` is the same for trusted per-step
data (no input checks; see its docstring), for MPC loops where checking costs more than
DAQP's own update. This is the solver for condensed linear MPC (issue #2 item 7:
0.09 ms per step at N = 40). H must be positive definite or semidefinite; DAQP's
default automatic proximal regularisation (``eps_prox < 0``) handles singular H, so
LPs (H = 0) also solve: with ``settings={"eps_prox": e}``, e > 0, DAQP runs proximal-point
iterations to an LP optimum, and a sequence of small LPs differing only in f re-solves from the
last working set in a few iterations (the support LPs of geometry/polytope.ConvexSection: ~0.02 ms
each against HiGHS's ~0.15-0.3 ms per hot-started ``run()``). For large or sparse LPs prefer
HiGHS or PIQP.
"""

from __future__ import annotations

import math
import time

import numpy as np

from proxops.errors import input_error
from proxops.solvers import _util
from proxops.solvers.base import HAS_X, SolverAdapter
from proxops.solvers.forms import QuadraticProgram
from proxops.solvers.result import SolverResult, SolveStatus, error_message, failed_result

DAQP_INF = 1e30  # DAQP treats |bound| >= 1e30 as absent (DAQP_INF in constants.h)

# Exit flags from daqp include/constants.h (DAQP_EXIT_*).
STATUS_MAP = {
    2: SolveStatus.OPTIMAL,  # SOFT_OPTIMAL: optimal with some soft rows relaxed
    1: SolveStatus.OPTIMAL,
    -1: SolveStatus.INFEASIBLE,
    -2: SolveStatus.NUMERICAL_ERROR,  # CYCLE
    -3: SolveStatus.UNBOUNDED,
    -4: SolveStatus.MAX_ITER,
    -5: SolveStatus.NUMERICAL_ERROR,  # NONCONVEX (H not positive (semi)definite)
    -6: SolveStatus.NUMERICAL_ERROR,  # OVERDETERMINED_INITIAL working set
    -7: SolveStatus.TIME_LIMIT,
    -8: SolveStatus.NUMERICAL_ERROR,  # UNSUPPORTED
}
RAW_NAMES = {
    2: "soft_optimal", 1: "optimal", -1: "infeasible", -2: "cycle", -3: "unbounded",
    -4: "iterlimit", -5: "nonconvex", -6: "overdetermined_initial", -7: "timelimit",
    -8: "unsupported",
}
RAW_STATUS = {flag: f"{flag} ({name})" for flag, name in RAW_NAMES.items()}
_OPTIMAL = SolveStatus.OPTIMAL
SENSE_EQUALITY = 5  # DAQP: ACTIVE | IMMUTABLE
SENSE_SOFT = 8


class DaqpQP(SolverAdapter):
    """Persistent DAQP solver for ``min 1/2 x'Hx + f'x s.t. bl <= Ax <= bu, lb <= x <= ub``.

    Settings: ``max_iter`` (DAQP iter_limit), ``time_limit_s``, ``primal_tol``;
    ``warm_start=False`` resets the working set before every solve (for comparisons);
    ``settings`` passes native DAQP settings (keys of ``daqp.Model().settings``, e.g.
    ``dual_tol``, ``eps_prox``, ``rho_soft``, ``w_soft``).
    """

    name = "daqp"
    forms = (QuadraticProgram,)
    _finite_x = False  # DAQP returns x only with an exit flag that has one (finite)

    def __init__(self, *, max_iter: int | None = None, time_limit_s: float | None = None,
                 primal_tol: float | None = None, warm_start: bool = True,
                 settings: dict | None = None):
        self._daqp = _util.import_solver("daqp", "daqp")
        native = dict(settings or {})
        if max_iter is not None:
            native["iter_limit"] = int(max_iter)
        if time_limit_s is not None:
            native["time_limit"] = float(time_limit_s)
        if primal_tol is not None:
            native["primal_tol"] = float(primal_tol)
        self._native = self._native_settings(native, self._daqp.Model().settings, "daqp")
        self.warm_start_enabled = bool(warm_start)
        self._model = None
        self._p_eq = 0
        self._views_of = None  # the upper bound vector the per-field views point into (bound_vectors)

    # ------------------------------------------------------------------ set-up
    def _setup_form(self, problem: QuadraticProgram) -> None:
        """Allocate the DAQP workspace for a :class:`QuadraticProgram`: equality rows A_eq come
        first in DAQP's rows (bl = bu); P = None is an LP (H = 0; ``settings={"eps_prox": e}``, e > 0,
        selects DAQP's proximal-point LP iterations, see the module doc)."""
        p = _util.rows_of("A_eq", problem.A_eq)
        stacked = problem.stacked()
        n = stacked.n
        self.setup_native(np.zeros((n, n)) if stacked.P is None else stacked.P, stacked.q, stacked.A,
                          stacked.bl, stacked.bu, stacked.lb, stacked.ub)
        self._p_eq = p

    def setup_native(self, H, f, A=None, bl=None, bu=None, lb=None, ub=None, *, soft_rows=None) -> None:
        """Allocate the DAQP workspace for this problem (DAQP's native form).

        H: (n, n) dense/sparse, symmetric PSD; f: (n,); A: (m, n) or None;
        bl, bu: (m,) row bounds (default -inf / +inf); lb, ub: (n,) variable bounds
        (give at least one of them, possibly infinite, if you want to ``update`` bounds later);
        soft_rows: optional (m,) bool mask of general rows DAQP may relax (DAQP soft
        constraints, penalised by the ``rho_soft`` / ``w_soft`` settings; the result's
        ``info["soft_relaxed"]`` tells when one was relaxed).
        Shape errors raise ProxopsInputError; NaN data makes ``solve`` return NUMERICAL_ERROR.
        ``update`` then takes these names (H, f, A, bl, bu, lb, ub).
        """
        self._native_setup_done()
        self._p_eq = 0
        if f is None:  # no linear term (see update_fast): DAQP keeps no v, bound updates cost O(m)
            if H is None:
                raise input_error("H", None, "give H when f is None (the problem needs a size)")
            n = int(np.shape(H)[0])
        else:
            f = _util.vector("f", f, np.size(f), allow_nan=True)
            n = f.shape[0]
        if n == 0:
            raise input_error("f", "empty", "the problem needs at least one variable")
        self.n = n
        self._bad = _util.BadData()
        self._H = _util.dense_matrix("H", H, (n, n), allow_nonfinite=True)
        self._f = f
        m = _util.rows_of("A", A)
        self.m = m
        self._A = _util.dense_matrix("A", A, (m, n), allow_nonfinite=True) if m else np.zeros((0, n))
        self._bl = _util.vector("bl", bl, m, fill=-np.inf, allow_inf=True, allow_nan=True)
        self._bu = _util.vector("bu", bu, m, fill=np.inf, allow_inf=True, allow_nan=True)
        self.has_bounds = lb is not None or ub is not None
        self._lb = _util.vector("lb", lb, n, fill=-np.inf, allow_inf=True, allow_nan=True)
        self._ub = _util.vector("ub", ub, n, fill=np.inf, allow_inf=True, allow_nan=True)
        for name in ("H", "f", "A"):
            if getattr(self, "_" + name) is not None:
                self._bad.check(name, getattr(self, "_" + name))
        for name in ("bl", "bu", "lb", "ub"):
            self._bad.check(name, getattr(self, "_" + name), allow_inf=True)
        soft = np.zeros(m, bool) if soft_rows is None else np.asarray(soft_rows, bool).reshape(-1)
        if soft.shape != (m,):
            raise input_error("soft_rows.shape", soft.shape, f"must be ({m},) like the rows of A")
        self._soft = soft
        self._build()

    def _build(self) -> None:
        """(Re)create the DAQP model from the stored data (NaN replaced by 0 until updated)."""
        self._assemble_bounds()
        self._sense = self._base_sense()
        self._model = self._daqp.Model()
        self._model.settings = self._native
        self._solver_error = None
        self._solver_flag = 0
        # copies (DAQP keeps pointers to what it is given); NaN/inf only where BadData saw them
        bad = self._bad.fields
        clean = lambda a: (np.nan_to_num(a, nan=0.0, posinf=DAQP_INF, neginf=-DAQP_INF) if bad  # noqa: E731
                           else np.array(a, dtype=float))
        try:
            flag, _ = self._model.setup(clean(self._H), None if self._f is None else clean(self._f), clean(self._A),
                                        clean(self._upper), clean(self._lower), self._sense.copy())
        except Exception as exc:  # solver failure -> status at solve time, never a crash
            self._solver_error = error_message(exc)
            return
        self._solver_flag = int(flag)

    def _assemble_bounds(self) -> None:
        """Full DAQP bound vectors [variable bounds; row bounds], clipped to +-DAQP_INF."""
        if self.has_bounds:
            upper = np.concatenate([self._ub, self._bu])
            lower = np.concatenate([self._lb, self._bl])
        else:
            upper, lower = self._bu.copy(), self._bl.copy()
        self._upper = np.clip(upper, -DAQP_INF, DAQP_INF)
        self._lower = np.clip(lower, -DAQP_INF, DAQP_INF)
        self._check_crossed()

    def _set_bounds(self, name: str, arr: np.ndarray) -> None:
        """Write one of bl/bu/lb/ub into the full bound vectors in place (fast path of update)."""
        off = self.n if self.has_bounds else 0
        target = self._lower if name in ("bl", "lb") else self._upper
        part = target[off:] if name in ("bl", "bu") else target[:off]
        np.clip(arr, -DAQP_INF, DAQP_INF, out=part)

    def _check_crossed(self) -> None:
        crossed = self._lower > self._upper
        self._crossed = int(np.argmax(crossed)) if crossed.any() else None

    def _base_sense(self) -> np.ndarray:
        sense = np.zeros(self._upper.shape[0], dtype=np.intc)
        sense[(self._lower == self._upper) & (np.abs(self._upper) < DAQP_INF)] = SENSE_EQUALITY
        offset = self.n if self.has_bounds else 0
        sense[offset:][self._soft] |= SENSE_SOFT
        return sense

    # ------------------------------------------------------------------ update
    def _native_fields(self) -> dict:
        # the rows of A are DAQP's rows only without A_eq (those are stacked on top)
        same = {"P": "H", "q": "f", "lb": "lb", "ub": "ub"}
        return same if self._p_eq else {**same, "A": "A", "bl": "bl", "bu": "bu"}

    def _update_form(self, *, P=None, q=None, A=None, bl=None, bu=None, lb=None, ub=None, A_eq=None,
                     b_eq=None) -> None:
        """:meth:`update` after ``setup(QuadraticProgram)``: ``A``, ``bl``, ``bu`` are the rows of the
        problem's A (after the A_eq rows). Changing which rows are equalities (bl == bu) resets the
        working set; after a failed set-up (e.g. crossed bounds or NaN data) the model is rebuilt."""
        p = self._p_eq
        if p:
            if A is not None or A_eq is not None:
                top = self._A[:p] if A_eq is None else _util.dense_matrix("A_eq", A_eq, (p, self.n), True)
                rest = self._A[p:] if A is None else _util.dense_matrix("A", A, (self.m - p, self.n), True)
                A = np.vstack([top, rest])
            if bl is not None or bu is not None or b_eq is not None:
                eq = self._bl[:p] if b_eq is None else _util.vector("b_eq", b_eq, p, allow_nan=True)
                bl = np.concatenate([eq, self._bl[p:] if bl is None else
                                     _util.vector("bl", bl, self.m - p, allow_inf=True, allow_nan=True)])
                bu = np.concatenate([eq, self._bu[p:] if bu is None else
                                     _util.vector("bu", bu, self.m - p, allow_inf=True, allow_nan=True)])
        elif A_eq is not None or b_eq is not None:
            raise input_error("A_eq/b_eq", "update without equality rows at setup", "set them up in the problem")
        self.update_native(H=P, f=q, A=A, bl=bl, bu=bu, lb=lb, ub=ub)

    def warm_start(self, x=None, y=None) -> bool:
        """DAQP warm-starts from the previous working set by itself (unless ``warm_start=False``);
        a primal/dual guess is not used. Returns True when the next solve is warm."""
        return self.warm_start_enabled

    def update_native(self, *, H=None, f=None, A=None, bl=None, bu=None, lb=None, ub=None) -> None:
        """Change data in place in DAQP's names (the rows of A include the A_eq rows of a form set-up);
        the working set is kept (warm start)."""
        if self._model is None:
            raise input_error("DaqpQP.update", "called before setup", "call setup() first")
        kwargs = {}
        if H is not None:
            self._H = _util.dense_matrix("H", H, (self.n, self.n), allow_nonfinite=True)
            if self._bad.check("H", self._H):
                kwargs["H"] = self._H
        if f is not None:
            if self._f is None:
                raise input_error("f", "update", "the problem was set up without a linear term (f=None)")
            self._f = _util.vector("f", f, self.n, allow_nan=True)
            if self._bad.check("f", self._f):
                kwargs["f"] = self._f
        if A is not None:
            self._A = _util.dense_matrix("A", A, (self.m, self.n), allow_nonfinite=True)
            if self._bad.check("A", self._A):
                kwargs["A"] = self._A
        if (lb is not None or ub is not None) and not self.has_bounds:
            raise input_error("lb/ub", "update without bounds at setup",
                              "pass lb and/or ub (may be infinite) to setup() to update them later")
        if bl is not None or bu is not None or lb is not None or ub is not None:
            for name, value, size in (("bl", bl, self.m), ("bu", bu, self.m), ("lb", lb, self.n), ("ub", ub, self.n)):
                if value is not None:
                    arr = _util.vector(name, value, size, allow_inf=True, allow_nan=True)
                    setattr(self, "_" + name, arr)
                    self._bad.check(name, arr, allow_inf=True)
                    self._set_bounds(name, arr)
            self._check_crossed()
            if not ({"bl", "bu", "lb", "ub"} & self._bad.fields):
                # copies: DAQP keeps pointers to the arrays it is given
                kwargs["bupper"] = self._upper.copy()
                kwargs["blower"] = self._lower.copy()
                sense = self._base_sense()
                if not np.array_equal(sense, self._sense):
                    self._sense = sense
                    kwargs["sense"] = sense.copy()
        if self._solver_error is not None or self._solver_flag < 0:
            if not self._bad.fields:
                self._build()
            return
        if not kwargs:
            return
        try:
            self._solver_flag = int(self._model.update(**kwargs))
        except Exception as exc:
            self._solver_error = error_message(exc)

    def update_fast(self, *, H: np.ndarray | None = None, f: np.ndarray | None = None, A: np.ndarray | None = None,
                    bu: np.ndarray | None = None, bl: np.ndarray | None = None, lb: np.ndarray | None = None,
                    ub: np.ndarray | None = None) -> None:
        """Lean :meth:`update_native` of the Hessian ``H``, ``f``, the rows ``A``, the row bounds and the
        variable bounds for trusted data (per-step MPC use; DAQP's names, whichever way the problem was
        set up).

        The caller guarantees: C-contiguous float64 arrays of the set-up sizes (H: (n, n) symmetric
        positive definite, A: (m, n), f, lb, ub: (n,), bu/bl: (m,)), no NaN or inf in H, f, A, no
        bound beyond +-1e30, and no row or variable turning into or out of an equality
        (lower == upper) - so DAQP's senses stay as they are and its working set is kept (warm
        start). Crossed bounds (lower > upper) are rejected by DAQP's own check: the next solve
        reports INFEASIBLE. Nothing is checked (``H``, ``f`` and ``A`` are handed to DAQP, which keeps
        pointers to them: do not modify them afterwards; the bounds are copied into the full bound
        vectors). Saves the ~50 us (f, bounds) to ~120 us (H, A of a 60-variable QP with 30 rows)
        of input checking of :meth:`update`. After a failed set-up/update it falls back to
        :meth:`update_native`.

        Changing the linear term makes DAQP recompute its LDP data (v = R^-T f and
        d = b + M v: O(m n), ~40 us at n = 120, m = 360). A problem set up with ``f=None``
        keeps no v, and a bound-only update costs O(m): a caller whose linear term changes
        every step can instead shift the variable to the unconstrained minimiser x_c = -H^-1 f
        (x = x_c + w: objective 1/2 w'Hw + const, bounds lb - x_c, ub - x_c, rows bl - A x_c,
        bu - A x_c). DAQP then solves the same LDP (its u = R (x - x_c) either way)."""
        if (self._model is None or self._solver_error is not None or self._solver_flag < 0 or self._bad.fields
                or self._crossed is not None or self._p_eq or ((lb is not None or ub is not None) and not self.has_bounds)):
            self.update_native(H=H, f=f, A=A, bu=bu, bl=bl, lb=lb, ub=ub)
            return
        kwargs = {}
        if H is not None:
            self._H = kwargs["H"] = H
        if A is not None:
            self._A = kwargs["A"] = A
        if f is not None:
            if self._f is None:
                raise input_error("f", "update_fast", "the problem was set up without a linear term (f=None)")
            self._f = kwargs["f"] = f
        if bu is not None or bl is not None or lb is not None or ub is not None:
            off = self.n if self.has_bounds else 0
            # written into the full bound vectors in place (DAQP re-reads them on update)
            if bu is not None:
                self._bu = bu
                self._upper[off:] = bu
            if ub is not None:
                self._ub = ub
                self._upper[:off] = ub
            if bl is not None:
                self._bl = bl
                self._lower[off:] = bl
            if lb is not None:
                self._lb = lb
                self._lower[:off] = lb
            if bu is not None or ub is not None:
                kwargs["bupper"] = self._upper
            if bl is not None or lb is not None:
                kwargs["blower"] = self._lower
            # no crossing check here: DAQP checks lower <= upper itself and rejects crossed data
            # (update flag -1: the next solve reports INFEASIBLE, the next update rebuilds)
        if kwargs:
            try:
                self._solver_flag = int(self._model.update(**kwargs))
            except Exception as exc:
                self._solver_error = error_message(exc)

    # ------------------------------------------------------------------ solve
    def solve(self) -> SolverResult:
        """Solve from the current working set and return a :class:`SolverResult`."""
        if self._model is None:
            raise input_error("DaqpQP.solve", "called before setup", "call setup() first")
        if (self._bad.fields or self._crossed is not None or self._solver_error is not None or self._solver_flag < 0
                or not self.warm_start_enabled):
            return self._solve_checked()
        return self._run_model()

    def solve_fast(self) -> tuple:
        """:meth:`solve` for per-step loops fed through :meth:`update_fast`, without building a
        :class:`SolverResult`: (status, x, iterations, wall_s, info). On the lean path (healthy model,
        warm start) x is DAQP's fresh array when the status carries an iterate (:data:`HAS_X`: OPTIMAL,
        MAX_ITER, TIME_LIMIT; else None) and ``info`` is None after DAQP's plain "optimal" exit (else
        ``{"raw_status", "soft_relaxed"}``); otherwise these are the fields of :meth:`solve`'s result. Saves the
        ~2-4 us of SolverResult assembly of a warm DAQP step (issue 32 item 2)."""
        if (self._bad.fields or self._crossed is not None or self._solver_error is not None or self._solver_flag < 0
                or not self.warm_start_enabled):
            res = self.solve()
            return res.status, res.x, res.iterations, res.solve_time_s, res.info
        return self._solve_lean()

    def _solve_lean(self) -> tuple:
        """The lean path of :meth:`solve_fast` (healthy model, warm start): one DAQP solve, timed."""
        try:
            t0 = time.perf_counter()
            x, _, flag, info = self._model.solve()
            wall = time.perf_counter() - t0
        except Exception as exc:
            res = failed_result(self.name, error_message(exc))
            return res.status, None, 0, 0.0, res.info
        if flag == 1:
            return _OPTIMAL, x, info["iterations"], wall, None
        status = STATUS_MAP.get(flag, SolveStatus.NUMERICAL_ERROR)
        raw = {"raw_status": RAW_STATUS.get(flag) or f"{flag} (unknown)", "soft_relaxed": flag == 2}
        return status, (x if status in HAS_X else None), info["iterations"], wall, raw

    def bound_vectors(self) -> tuple[np.ndarray, np.ndarray]:
        """(upper, lower): the full bound vectors DAQP reads, [ub (n); bu (m)] and [lb (n); bl (m)]
        (without variable bounds at set-up: [bu], [bl]), for a caller that writes its per-step bounds
        into them in place and then calls :meth:`solve_bounds_fast` (no copies, no keyword update).
        Ask for them before every write: a rebuild after a failed set-up/update makes new ones. The
        per-field bounds (lb, ub, bl, bu) are views of them from here on."""
        upper, lower = self._upper, self._lower
        if self._views_of is not upper:  # once per set of vectors (a rebuild replaces them)
            off = self.n if self.has_bounds else 0
            self._ub, self._bu, self._lb, self._bl = upper[:off], upper[off:], lower[:off], lower[off:]
            self._views_of = upper
        return upper, lower

    def solve_bounds_fast(self) -> tuple:
        """:meth:`update_fast` of the bounds written in place into :meth:`bound_vectors` (finite, the
        same conditions as update_fast: no row or variable turning into or out of an equality),
        then :meth:`solve_fast` (one call, one health check); the same (status, x, iterations, wall_s, info).
        DAQP re-reads the vectors in its update (O(m) without a linear term). After a failed set-up/update the bounds
        go through :meth:`update_native` (copies; it rebuilds the model)."""
        if (self._model is None or self._solver_error is not None or self._solver_flag < 0 or self._bad.fields
                or self._crossed is not None or self._p_eq):
            off = self.n if self.has_bounds else 0
            upper, lower = self._upper, self._lower
            self.update_native(bu=upper[off:].copy(), bl=lower[off:].copy(),
                               **({"ub": upper[:off].copy(), "lb": lower[:off].copy()} if off else {}))
            return self.solve_fast()
        try:
            self._solver_flag = int(self._model.update(bupper=self._upper, blower=self._lower))
        except Exception as exc:
            self._solver_error = error_message(exc)
            return self.solve_fast()
        if self._solver_flag < 0 or not self.warm_start_enabled:
            return self.solve_fast()
        return self._solve_lean()

    def _solve_checked(self) -> SolverResult:
        """:meth:`solve` when something is off (bad data, crossed bounds, a failed set-up) or the
        working set is reset before every solve."""
        bad = self._bad.message()
        if bad is not None:
            return failed_result(self.name, bad)
        if self._crossed is not None:
            index, n_bounds = self._crossed, self.n if self.has_bounds else 0
            what = f"bound of x[{index}]" if index < n_bounds else f"row {index - n_bounds}"
            return self._infeasible_data("crossed_bounds", f"lower > upper on {what}")
        if self._solver_error is not None:
            return failed_result(self.name, self._solver_error)
        if self._solver_flag < 0:
            flag = self._solver_flag
            return self._result(STATUS_MAP.get(flag, SolveStatus.NUMERICAL_ERROR), None, math.nan, 0, 0.0,
                                {"raw_status": f"{flag} ({RAW_NAMES.get(flag, 'unknown')})",
                                 "error": "daqp rejected the problem data at setup/update"})
        if not self.warm_start_enabled:
            try:
                self._model.update(sense=self._sense.copy())
            except Exception as exc:
                return failed_result(self.name, error_message(exc))
        return self._run_model()

    def _run_model(self) -> SolverResult:
        """One call of DAQP's solve on the current model, timed; an exception is a failed result."""
        try:
            t0 = time.perf_counter()
            x, fval, flag, info = self._model.solve()
            wall = time.perf_counter() - t0
        except Exception as exc:
            return failed_result(self.name, error_message(exc))
        return self._flag_result(x, fval, flag, info, wall)

    def _flag_result(self, x, fval, flag, info, wall: float) -> SolverResult:
        flag = int(flag)
        return self._result(STATUS_MAP.get(flag, SolveStatus.NUMERICAL_ERROR), x, fval, info["iterations"], wall,
                            {"raw_status": RAW_STATUS.get(flag) or f"{flag} (unknown)",
                             "solver_time_s": float(info.get("solve_time", math.nan)),
                             "dual": info.get("lam"), "soft_relaxed": flag == 2})
