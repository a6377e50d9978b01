"""Front end over the adapters: a persistent QP solver by name, and one-shot ``solve_qp``.

Controllers keep one persistent adapter (:func:`make_qp_solver`, or a class such as
``DaqpQP``) and call ``setup(problem)`` once, ``update(...)`` each step and ``solve()``:
the same calls whichever solver the scenario names. ``solve_qp`` is for one-off
problems, cross-checks and fallbacks (e.g. Clarabel after a PIQP failure).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from proxops.errors import input_error
from proxops.solvers.forms import LinearProgram, QuadraticProgram
from proxops.solvers.result import SolverResult

SOLVERS = ("daqp", "piqp", "clarabel", "highs")
QP_SOLVERS = ("daqp", "piqp", "clarabel")


def make_qp_solver(solver: str, **settings):
    """A persistent adapter for :class:`QuadraticProgram` problems: ``solver`` in
    {"daqp", "piqp", "clarabel"}; ``settings`` go to the adapter's constructor."""
    if solver == "daqp":
        from proxops.solvers.daqp_qp import DaqpQP

        return DaqpQP(**settings)
    if solver == "piqp":
        from proxops.solvers.piqp_qp import PiqpQP

        return PiqpQP(**settings)
    if solver == "clarabel":
        from proxops.solvers.clarabel_socp import ClarabelSOCP

        return ClarabelSOCP(**settings)
    raise input_error("solver", solver, f"allowed for QPs: {', '.join(QP_SOLVERS)}")


def solve_qp(problem: QuadraticProgram, solver: str = "daqp", **settings) -> SolverResult:
    """Solve ``problem`` once with ``solver`` in {"daqp", "piqp", "clarabel", "highs"}.

    ``settings`` go to the adapter's constructor (e.g. ``max_iter=...``). "highs" only
    accepts LPs (P None or zero). Without A_eq, rows with bl == bu are equalities (PIQP
    gets them as its equality rows). Returns the adapter's :class:`SolverResult`.
    """
    if solver == "highs":
        from proxops.solvers.highs_lp import HighsLP

        if problem.P is not None:
            P = problem.P
            nnz = P.count_nonzero() if sp.issparse(P) else np.count_nonzero(np.asarray(P))
            if nnz:
                raise input_error("solver", "highs", "HiGHS is used for LPs only (P must be None or zero); "
                                  "use daqp, piqp or clarabel for QPs")
        lp = problem.stacked()
        adapter = HighsLP(**settings)
        adapter.setup(LinearProgram(lp.q, lp.A, lp.bl, lp.bu, lp.lb, lp.ub))
        return adapter.solve()
    if solver not in SOLVERS:
        raise input_error("solver", solver, f"allowed: {', '.join(SOLVERS)}")
    adapter = make_qp_solver(solver, **settings)
    adapter.setup(problem.split_equalities() if solver == "piqp" else problem)
    return adapter.solve()
