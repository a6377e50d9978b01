"""One persistent interface over QP / SOCP / (MI)LP / NLP solvers, with one result type.

Canonical forms (:mod:`proxops.solvers.forms`): :class:`QuadraticProgram`,
:class:`ConicProblem` (SOCP), :class:`LinearProgram` ((MI)LP) and
:class:`~proxops.solvers.casadi_nlp.NonlinearProgram`. Every adapter has the same calls:
``setup(problem)`` once, ``update(**fields)`` in place (the form's field names),
``warm_start(...)`` (a hint; returns whether the solver uses it) and ``solve()``; DaqpQP and
ClarabelSOCP add a lean ``update_fast`` (trusted per-step data in the solver's native names,
nothing checked); every adapter derives from :class:`SolverAdapter` (:mod:`proxops.solvers.base`):

- :class:`DaqpQP`       dense QP, active set, warm-started working set (condensed MPC); small
  dense LPs in its proximal-point mode (support functions of 2-D sections)
- :class:`PiqpQP`       sparse QP/LP, proximal interior point (fuel problems)
- :class:`ClarabelSOCP` conic QP / SOCP, interior point (cones, robust fallback)
- :class:`HighsLP`      pure LP, dual simplex hot-started from the last basis
- :class:`HighsMILP`    mixed-integer LP, HiGHS branch and cut
- :class:`IpoptSOCP`    SOCP as a smooth NLP by IPOPT (a second, independent SOCP engine for cross-checks)
- :class:`~proxops.solvers.casadi_nlp.CasadiNLP` NLP by IPOPT or fatrop (CasADi)

:func:`make_solver` picks an adapter by form and name (QP, SOCP, LP, MILP), so a consumer is
not welded to one solver. Every ``solve`` returns a :class:`SolverResult` whose :class:`SolveStatus` comes
from an explicit per-solver table; infeasible, inaccurate, iteration/time-limited and
failed solves are statuses, never exceptions (only wrong shapes/unknown settings raise
:class:`proxops.errors.ProxopsInputError`). Verify answers with :func:`check_feasibility`
/ :func:`check_conic_feasibility`. :func:`successive_convexification` is the shared
SCP loop (re-linearisation callback, trust region, convergence test) of srf and cortex.

Solver modules are imported lazily (on first use of an adapter). OSQP is not
shipped: it gave false infeasibility on the seed problems (issues #4, #5).
"""

import importlib

# name -> submodule. Resolved on first access (PEP 562): importing the package (e.g. for
# solve_time_stats in every run summary) does not load scipy.sparse and the solver adapters (0.5 s
# of a short CLI run); ``from proxops.solvers import DaqpQP`` works as before.
_HOME = {
    "ClarabelSOCP": "clarabel_socp", "DaqpQP": "daqp_qp", "PiqpQP": "piqp_qp", "HighsLP": "highs_lp",
    "HighsMILP": "highs_lp", "IpoptSOCP": "ipopt_socp", "FeasibilityReport": "feasibility", "check_conic_feasibility": "feasibility",
    "check_feasibility": "feasibility", "farkas_margin": "feasibility", "max_violation": "feasibility", "ConicProblem": "forms",
    "LinearProgram": "forms", "QuadraticProgram": "forms", "build_conic_problem": "forms",
    "conic_from_program": "forms", "conic_from_qp": "forms", "soc_rows": "forms", "make_solver": "front",
    "form_kind": "front", "SolverAdapter": "base",
    "solve_qp": "front",
    "SolverResult": "result", "SolveStatus": "result", "ScpResult": "scp", "TrustRegion": "scp",
    "successive_convexification": "scp", "solve_time_stats": "stats",
}


def __getattr__(name: str):
    home = _HOME.get(name)
    if home is None:
        raise AttributeError(f"module 'proxops.solvers' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"proxops.solvers.{home}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(__all__)


__all__ = [
    "ClarabelSOCP",
    "ConicProblem",
    "DaqpQP",
    "FeasibilityReport",
    "HighsLP",
    "HighsMILP",
    "IpoptSOCP",
    "LinearProgram",
    "PiqpQP",
    "QuadraticProgram",
    "ScpResult",
    "SolveStatus",
    "SolverAdapter",
    "SolverResult",
    "TrustRegion",
    "build_conic_problem",
    "check_conic_feasibility",
    "check_feasibility",
    "farkas_margin",
    "form_kind",
    "conic_from_program",
    "conic_from_qp",
    "make_solver",
    "max_violation",
    "solve_qp",
    "soc_rows",
    "solve_time_stats",
    "successive_convexification",
]
