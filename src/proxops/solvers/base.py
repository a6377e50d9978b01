"""The one adapter interface every solver wrapper derives from (:class:`SolverAdapter`).

Calls, the same on every adapter::

    s = make_solver(form, "daqp")      # or DaqpQP(...), PiqpQP(...), ClarabelSOCP(...), HighsLP(...)
    s.setup(form)                      # a QuadraticProgram, ConicProblem or LinearProgram
    s.update(**fields)                 # in place, keyed by the form's field names (q=..., bu=...)
    s.warm_start(x=None, y=None)       # a hint; True when the next solve uses it
    res = s.solve()                    # SolverResult (statuses, never exceptions)

A :class:`LinearProgram` is also accepted by the QP adapters (DAQP, PIQP, Clarabel): it is set up
as the QuadraticProgram with P = None and ``update`` keeps the LP's names (c, rl, ru, lb, ub, A).

Fast paths, for callers that own their data layout (per-step MPC loops):

- ``setup_native(...)``: the solver's own argument list (DaqpQP: H, f, A, bl, bu, lb, ub;
  PiqpQP: P, c, A, b, G, h_l, h_u, x_lb, x_ub; ClarabelSOCP: P, q, A, b, cones; HighsLP:
  c, A, rl, ru, lb, ub). After it, ``update`` takes those native names.
- ``update_native(**native_fields)``: checked update in the native names, whatever the set-up.
- ``update_fast(**native_fields)``: trusted update in the native names (nothing checked; each
  adapter documents which fields take its lean path). The default is :meth:`update_native`.
- ``native_name(field)``: the native keyword of a form field in the current set-up, so a consumer
  set up from a form reaches the lean path of whichever solver it named.

Every ``solve`` ends in :meth:`SolverAdapter._result` (the one place a SolverResult of a run is
built: x and objective only for the statuses that carry an iterate), and refuses unusable data
through :meth:`SolverAdapter._blocked` (NaN data, crossed bounds, a failed set-up).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from proxops.errors import input_error
from proxops.solvers import _util
from proxops.solvers.forms import LinearProgram, QuadraticProgram
from proxops.solvers.result import SolverResult, SolveStatus, failed_result

# statuses whose result carries the solver's iterate (MAX_ITER / TIME_LIMIT: the last one, not to be trusted)
HAS_X = frozenset((SolveStatus.OPTIMAL, SolveStatus.OPTIMAL_INACCURATE, SolveStatus.MAX_ITER, SolveStatus.TIME_LIMIT))

# LinearProgram field -> QuadraticProgram field (an LP set up on a QP adapter)
LP_AS_QP = {"c": "q", "A": "A", "rl": "bl", "ru": "bu", "lb": "lb", "ub": "ub"}


def field_names(form_type: type) -> tuple[str, ...]:
    """The field names of a form dataclass (the names ``update`` takes after ``setup(form)``)."""
    return tuple(f.name for f in dataclasses.fields(form_type))


def lp_as_qp(lp: LinearProgram) -> QuadraticProgram:
    """The :class:`QuadraticProgram` (P = None) of a pure :class:`LinearProgram`; integer variables
    are refused (a QP adapter cannot honour them)."""
    if lp.integrality is not None and np.any(np.asarray(lp.integrality, bool)):
        raise input_error("integrality", "integer variables", "a QP solver takes pure LPs only; use make_solver('MILP', "
                          "'highs')")
    return QuadraticProgram(P=None, q=lp.c, A=lp.A, bl=lp.rl, bu=lp.ru, lb=lp.lb, ub=lp.ub)


class SolverAdapter:
    """Base of every persistent solver adapter (module doc: the calls and the fast paths).

    Subclasses set ``name`` (the ``make_solver`` name), ``forms`` (the form types ``setup`` takes
    natively) and implement ``_setup_form(form)``, ``_update_form(**fields)`` (form names),
    ``setup_native``, ``update_native`` and ``solve``; ``warm_start`` defaults to "not used".
    ``_finite_x``: check that an iterate is finite before returning it (False where the solver
    guarantees it, e.g. DAQP, saving ~1 us per solve).
    """

    name: str = ""
    forms: tuple[type, ...] = ()
    _finite_x: bool = True

    # set by setup(): field names update() takes (None: set up natively) and LP -> QP renames
    _form_fields: tuple[str, ...] | None = None
    _renames: dict | None = None

    # ------------------------------------------------------------------ the interface
    def setup(self, form) -> None:
        """Set up the solver for ``form`` (one of :attr:`forms`; a LinearProgram on a QP adapter is
        set up as its QuadraticProgram). Memory is allocated once; ``update`` changes data in place."""
        cls = type(self).__name__
        if isinstance(form, self.forms):
            renames, native_form = None, form
        elif isinstance(form, LinearProgram) and QuadraticProgram in self.forms:
            renames, native_form = LP_AS_QP, lp_as_qp(form)
        else:
            allowed = [f.__name__ for f in self.forms] + (["LinearProgram"] if QuadraticProgram in self.forms else [])
            raise input_error(f"{cls}.setup", type(form).__name__,
                              f"takes a {' or '.join(allowed)} (native arguments go to {cls}.setup_native)")
        self._setup_form(native_form)
        self._form_fields = field_names(type(form))
        self._renames = renames

    def update(self, **fields) -> None:
        """Change problem data in place (same sizes): the field names of the form given to
        ``setup`` (the native names after ``setup_native``)."""
        if self._form_fields is None:
            self.update_native(**fields)
            return
        unknown = sorted(set(fields) - set(self._form_fields))
        if unknown:
            raise input_error(f"{type(self).__name__}.update", unknown, f"allowed: {', '.join(self._form_fields)}")
        if self._renames is not None:
            if "integrality" in fields:
                raise input_error("integrality", "update", "a QP solver takes pure LPs only")
            fields = {self._renames[k]: v for k, v in fields.items()}
        self._update_form(**fields)

    def update_fast(self, **native_fields) -> None:
        """Trusted update in the solver's native names (nothing checked); adapters with a lean
        path override it. Default: :meth:`update_native`."""
        self.update_native(**native_fields)

    def native_name(self, field: str) -> str:
        """The keyword ``update_native`` / ``update_fast`` take for the form field ``field`` of this
        set-up (the same name after ``setup_native``), so a consumer can use an adapter's lean path
        whichever solver it named: ``s.update_fast(**{s.native_name("c"): c})``. Raises
        ProxopsInputError when the field has no in-place native counterpart in this set-up (e.g. the
        rows of a QP converted to Clarabel's cones)."""
        if self._form_fields is None:
            return field
        if field not in self._form_fields:
            raise input_error(f"{type(self).__name__}.native_name", field, f"allowed: {', '.join(self._form_fields)}")
        key = self._renames.get(field, field) if self._renames is not None else field
        native = self._native_fields().get(key)
        if native is None:
            raise input_error(f"{type(self).__name__}.native_name", field,
                              "has no in-place native counterpart in this set-up; use update()")
        return native

    def _native_fields(self) -> dict:
        """Form field -> native keyword for the current form set-up (fields that map one to one)."""
        return {}

    def warm_start(self, x=None, y=None) -> bool:
        """Give a primal (and dual) guess; True when the next solve uses it. Default: not used."""
        return False

    def solve(self) -> SolverResult:  # pragma: no cover - every adapter implements it
        raise NotImplementedError(f"{type(self).__name__}.solve")

    def setup_native(self, *args, **kwargs) -> None:  # pragma: no cover
        raise NotImplementedError(f"{type(self).__name__}.setup_native")

    def update_native(self, **fields) -> None:  # pragma: no cover
        raise NotImplementedError(f"{type(self).__name__}.update_native")

    def _setup_form(self, form) -> None:  # pragma: no cover
        raise NotImplementedError(f"{type(self).__name__}._setup_form")

    def _update_form(self, **fields) -> None:
        self.update_native(**fields)

    def _native_setup_done(self) -> None:
        """Called by ``setup_native``: ``update`` now takes the native names."""
        self._form_fields = None
        self._renames = None

    # ------------------------------------------------------------------ the shared result tail
    def _result(self, status: SolveStatus, x, objective: float, iterations: int, wall_s: float,
                info: dict) -> SolverResult:
        """The :class:`SolverResult` of one solver run: ``x`` and ``objective`` are kept for the
        statuses with an iterate (:data:`HAS_X`) when x is present (and finite, with ``_finite_x``),
        else None / nan."""
        has_x = status in HAS_X and x is not None and (not self._finite_x or bool(np.isfinite(x).all()))
        return SolverResult(status, x if has_x else None, float(objective) if has_x else math.nan,
                            int(iterations), wall_s, self.name, info)

    def _infeasible_data(self, raw_status: str, reason: str) -> SolverResult:
        """INFEASIBLE without calling the solver (crossed bounds, ``A x <= -inf``)."""
        return SolverResult(SolveStatus.INFEASIBLE, None, math.nan, 0, 0.0, self.name,
                            {"raw_status": raw_status, "reason": reason})

    def _blocked(self, crossed_raw_status: str = "crossed_bounds") -> SolverResult | None:
        """The result for data the solver must not be called with (NaN or inf where not allowed,
        crossed bounds, a failed set-up), or None when it may run; solving before ``setup`` is a
        usage error. Uses the ``_data``, ``_bad``, ``_crossed`` and ``_solver_error`` attributes."""
        if getattr(self, "_data", None) is None:
            raise input_error(f"{type(self).__name__}.solve", "called before setup", "call setup() first")
        bad = self._bad.message()
        if bad is not None:
            return failed_result(self.name, bad)
        if self._crossed is not None:
            return self._infeasible_data(crossed_raw_status, self._crossed)
        if self._solver_error is not None:
            return failed_result(self.name, self._solver_error)
        return None

    def _check_crossed_pairs(self, pairs) -> None:
        """Set ``_crossed`` to a message for the first entry with lower > upper among ``pairs`` of
        (lower key, upper key, what) in ``_data``, else None (reported as INFEASIBLE by ``solve``)."""
        d = self._data
        self._crossed = None
        for lo, hi, label in pairs:
            i = _util.first_crossed(d[lo], d[hi])
            if i is not None:
                self._crossed = f"{lo} > {hi} on {label} {i}"
                return

    @staticmethod
    def _native_settings(native: dict, allowed, what: str) -> dict:
        """``native`` after checking its keys against the solver's ``allowed`` settings."""
        unknown = sorted(set(native) - set(allowed))
        if unknown:
            raise input_error(f"{what} settings", unknown, f"allowed keys: {sorted(allowed)}")
        return native
