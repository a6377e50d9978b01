"""One-shot front end: solve a :class:`QuadraticProgram` with any adapter.

MPCs should keep a persistent adapter (``DaqpQP``, ``PiqpQP``, ``ClarabelSOCP``,
``HighsLP``) and ``update`` it each step; ``solve_qp`` is for one-off problems,
cross-checks and fallbacks (e.g. Clarabel after a DAQP failure).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from proxops.errors import input_error
from proxops.solvers import _util
from proxops.solvers.result import SolverResult

SOLVERS = ("daqp", "piqp", "clarabel", "highs")


@dataclass
class QuadraticProgram:
    """``min 1/2 x'Px + q'x  s.t.  bl <= A x <= bu,  lb <= x <= ub``.

    P: (n, n) PSD or None (LP); A: (m, n) or None; bl/bu/lb/ub may hold +-inf or be None.
    Rows with bl == bu are equalities.
    """

    P: object
    q: np.ndarray
    A: object = None
    bl: np.ndarray | None = None
    bu: np.ndarray | None = None
    lb: np.ndarray | None = None
    ub: np.ndarray | None = None


def solve_qp(problem: QuadraticProgram, solver: str = "daqp", **settings) -> SolverResult:
    """Solve ``problem`` once with ``solver`` in {"daqp", "piqp", "clarabel", "highs"}.

    ``settings`` go to the adapter's constructor (e.g. ``max_iter=...``). "highs" only
    accepts LPs (P None or zero). Returns the adapter's :class:`SolverResult`.
    """
    q = _util.vector("q", problem.q, np.size(problem.q))
    n = q.shape[0]
    m = _util.rows_of("A", problem.A)
    if solver == "daqp":
        from proxops.solvers.daqp_qp import DaqpQP

        P = np.zeros((n, n)) if problem.P is None else problem.P
        adapter = DaqpQP(**settings)
        adapter.setup(P, q, problem.A, problem.bl, problem.bu, problem.lb, problem.ub)
        return adapter.solve()
    if solver == "piqp":
        from proxops.solvers.piqp_qp import PiqpQP

        A = _util.csc_matrix("A", problem.A, (m, n)).tocsr()
        bl = _util.vector("bl", problem.bl, m, fill=-np.inf, allow_inf=True)
        bu = _util.vector("bu", problem.bu, m, fill=np.inf, allow_inf=True)
        is_eq = bl == bu
        adapter = PiqpQP(**settings)
        adapter.setup(
            problem.P, q,
            A[is_eq] if is_eq.any() else None, bu[is_eq] if is_eq.any() else None,
            A[~is_eq] if (~is_eq).any() else None,
            bl[~is_eq] if (~is_eq).any() else None, bu[~is_eq] if (~is_eq).any() else None,
            problem.lb, problem.ub,
        )
        return adapter.solve()
    if solver == "clarabel":
        from proxops.solvers.clarabel_socp import ClarabelSOCP, conic_from_qp

        adapter = ClarabelSOCP(**settings)
        adapter.setup_problem(conic_from_qp(problem.P, q, problem.A, problem.bl, problem.bu, problem.lb, problem.ub))
        return adapter.solve()
    if solver == "highs":
        from proxops.solvers.highs_lp import HighsLP

        if problem.P is not None:
            P = problem.P
            nnz = P.count_nonzero() if sp.issparse(P) else np.count_nonzero(np.asarray(P))
            if nnz:
                raise input_error("solver", "highs", "HiGHS is used for LPs only (P must be None or zero); "
                                  "use daqp, piqp or clarabel for QPs")
        adapter = HighsLP(**settings)
        adapter.setup(q, problem.A, problem.bl, problem.bu, problem.lb, problem.ub)
        return adapter.solve()
    raise input_error("solver", solver, f"allowed: {', '.join(SOLVERS)}")
