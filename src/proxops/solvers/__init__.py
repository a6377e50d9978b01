"""Thin adapters over QP / LP / SOCP solvers with one result type.

Persistent adapters (``setup`` once, ``update`` in place, ``solve`` many times):

- :class:`DaqpQP`       dense QP, active set, warm-started working set (condensed MPC)
- :class:`PiqpQP`       sparse QP/LP, proximal interior point (fuel problems)
- :class:`ClarabelSOCP` conic QP / SOCP, interior point (cones, robust fallback)
- :class:`HighsLP`      pure LP, dual simplex hot-started from the last basis

Every ``solve`` returns a :class:`SolverResult` whose :class:`SolveStatus` comes from
an explicit per-solver table; infeasible, inaccurate, iteration/time-limited and
failed solves are statuses, never exceptions (only wrong shapes/unknown settings
raise :class:`proxops.errors.ProxopsInputError`). Verify answers with
:func:`check_feasibility` / :func:`check_conic_feasibility`.

Solver modules are imported lazily (on first use of an adapter). OSQP is not
shipped: it gave false infeasibility on the seed problems (issues #4, #5).
"""

from proxops.solvers.clarabel_socp import ClarabelSOCP, ConicProblem, build_conic_problem, conic_from_qp
from proxops.solvers.daqp_qp import DaqpQP
from proxops.solvers.feasibility import (
    FeasibilityReport,
    check_conic_feasibility,
    check_feasibility,
    max_violation,
)
from proxops.solvers.front import QuadraticProgram, solve_qp
from proxops.solvers.highs_lp import HighsLP
from proxops.solvers.piqp_qp import PiqpQP
from proxops.solvers.result import SolverResult, SolveStatus

__all__ = [
    "ClarabelSOCP",
    "ConicProblem",
    "DaqpQP",
    "FeasibilityReport",
    "HighsLP",
    "PiqpQP",
    "QuadraticProgram",
    "SolveStatus",
    "SolverResult",
    "build_conic_problem",
    "check_conic_feasibility",
    "check_feasibility",
    "conic_from_qp",
    "max_violation",
    "solve_qp",
]
