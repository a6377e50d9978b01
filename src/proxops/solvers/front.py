"""Front end over the adapters: a persistent solver by form and name, and one-shot ``solve_qp``.

Consumers keep one persistent adapter (:func:`make_solver`) and call ``setup(form)`` once,
``update(...)`` each step and ``solve()``: the same calls whichever solver the scenario names.
``solve_qp`` is for one-off problems, cross-checks and fallbacks (e.g. Clarabel after a PIQP
failure).
"""

from __future__ import annotations

import importlib

import numpy as np
import scipy.sparse as sp

from proxops.errors import input_error
from proxops.solvers.forms import ConicProblem, LinearProgram, QuadraticProgram
from proxops.solvers.result import SolverResult

# form kind -> {solver name: (module, adapter class)}; the first name is the default of the kind
SOLVERS_FOR = {
    "QP": {"daqp": ("daqp_qp", "DaqpQP"), "piqp": ("piqp_qp", "PiqpQP"), "clarabel": ("clarabel_socp", "ClarabelSOCP")},
    "SOCP": {"clarabel": ("clarabel_socp", "ClarabelSOCP"), "ipopt": ("ipopt_socp", "IpoptSOCP")},
    "LP": {"highs": ("highs_lp", "HighsLP"), "daqp": ("daqp_qp", "DaqpQP"), "piqp": ("piqp_qp", "PiqpQP"),
           "clarabel": ("clarabel_socp", "ClarabelSOCP")},
    "MILP": {"highs": ("highs_lp", "HighsMILP")},
}
FORM_OF_KIND = {"QP": QuadraticProgram, "SOCP": ConicProblem, "LP": LinearProgram, "MILP": LinearProgram}
SOLVERS = ("daqp", "piqp", "clarabel", "highs")
QP_SOLVERS = tuple(SOLVERS_FOR["QP"])


def form_kind(form) -> str:
    """"QP", "SOCP", "LP" or "MILP" for a form instance, a form class or one of those names
    (a LinearProgram with an integer variable is a MILP)."""
    if isinstance(form, str):
        kind = form.upper()
        if kind not in SOLVERS_FOR:
            raise input_error("form", form, f"allowed: {', '.join(SOLVERS_FOR)} or a form object")
        return kind
    cls = form if isinstance(form, type) else type(form)
    if cls is LinearProgram:
        integ = None if isinstance(form, type) else form.integrality
        return "MILP" if integ is not None and np.any(np.asarray(integ, bool)) else "LP"
    for kind, form_cls in FORM_OF_KIND.items():
        if cls is form_cls:
            return kind
    raise input_error("form", cls.__name__, "must be a QuadraticProgram, ConicProblem or LinearProgram "
                      "(or the name QP, SOCP, LP, MILP)")


def make_solver(form, name: str, **settings):
    """A persistent adapter (:class:`proxops.solvers.base.SolverAdapter`) named ``name`` for ``form``.

    form: a form instance (the adapter is also set up with it), a form class, or "QP", "SOCP", "LP",
    "MILP". Solvers by form: QP daqp, piqp, clarabel; SOCP clarabel, ipopt (the cone rows as smooth NLP
constraints, for cross-checks: :mod:`proxops.solvers.ipopt_socp`); LP highs, daqp (give
    ``settings={"eps_prox": e}``, e > 0), piqp, clarabel; MILP highs. ``settings`` go to the adapter's
    constructor. A name the form does not allow raises a one-line ProxopsInputError."""
    kind = form_kind(form)
    allowed = SOLVERS_FOR[kind]
    if name not in allowed:
        raise input_error(f"solver for a {kind} ({FORM_OF_KIND[kind].__name__})", name,
                          f"allowed: {', '.join(allowed)}")
    module, cls = allowed[name]
    adapter = getattr(importlib.import_module(f"proxops.solvers.{module}"), cls)(**settings)
    if not isinstance(form, (str, type)):
        adapter.setup(form)
    return adapter


def solve_qp(problem: QuadraticProgram, solver: str = "daqp", **settings) -> SolverResult:
    """Solve ``problem`` once with ``solver`` in {"daqp", "piqp", "clarabel", "highs"}.

    ``settings`` go to the adapter's constructor (e.g. ``max_iter=...``). "highs" only
    accepts LPs (P None or zero). Without A_eq, rows with bl == bu are equalities (PIQP
    gets them as its equality rows). Returns the adapter's :class:`SolverResult`.
    """
    if solver == "highs":
        if problem.P is not None:
            P = problem.P
            nnz = P.count_nonzero() if sp.issparse(P) else np.count_nonzero(np.asarray(P))
            if nnz:
                raise input_error("solver", "highs", "HiGHS is used for LPs only (P must be None or zero); "
                                  "use daqp, piqp or clarabel for QPs")
        lp = problem.stacked()
        return make_solver(LinearProgram(lp.q, lp.A, lp.bl, lp.bu, lp.lb, lp.ub), "highs", **settings).solve()
    if solver not in SOLVERS:
        raise input_error("solver", solver, f"allowed: {', '.join(SOLVERS)}")
    return make_solver(problem.split_equalities() if solver == "piqp" else problem, solver, **settings).solve()
