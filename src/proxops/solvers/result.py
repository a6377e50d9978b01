"""One result type for every solver adapter.

Every adapter maps its solver's native exit code onto :class:`SolveStatus` with an
explicit table (as CVXPY's solver interfaces do) and returns a :class:`SolverResult`.
Infeasible, inaccurate or iteration-limited solves are *statuses*; a solver that
raises is reported as ``NUMERICAL_ERROR`` with the message in ``info["error"]``.
Callers should still verify the returned ``x`` with
:func:`proxops.solvers.check_feasibility` rather than trust the status.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from proxops.status import Status


# The one status vocabulary of solvers and controllers lives in proxops.status (lowest layer);
# SolveStatus is that enum (members OPTIMAL, OPTIMAL_INACCURATE, INFEASIBLE, UNBOUNDED, MAX_ITER,
# TIME_LIMIT, NUMERICAL_ERROR; ``str(status)`` is its value, ``status.ok`` a usable solution).
SolveStatus = Status


@dataclass
class SolverResult:
    """Result of one solve.

    x: primal solution (None when infeasible, unbounded or failed without an iterate;
       for MAX_ITER / TIME_LIMIT it is the last iterate, which is NOT to be trusted).
    objective: 1/2 x'Px + q'x at ``x`` as reported by the solver (nan without x).
    iterations: solver iterations (active-set, IPM or simplex, per solver).
    solve_time_s: wall time of the solve call measured around the solver, s.
    solver: adapter name ("daqp", "piqp", "clarabel", "highs").
    info: solver-specific extras. Common keys: "raw_status" (native code/name),
       "solver_time_s" (solver's own timer, when it has one), "error" (message),
       "dual" (multipliers, adapter-specific layout), "rebuilt" (structure changed
       so the solver was set up again).
    """

    status: SolveStatus
    x: np.ndarray | None
    objective: float
    iterations: int
    solve_time_s: float
    solver: str
    info: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """Shortcut for ``self.status.ok``."""
        return self.status.ok

    def __repr__(self) -> str:
        x_text = "None" if self.x is None else f"array(shape={self.x.shape})"
        return (
            f"SolverResult(status={self.status.value}, objective={self.objective:.6g}, "
            f"iterations={self.iterations}, solve_time_s={self.solve_time_s:.3g}, "
            f"solver={self.solver!r}, x={x_text})"
        )


def failed_result(solver: str, message: str, solve_time_s: float = 0.0, **info) -> SolverResult:
    """A NUMERICAL_ERROR result carrying ``message`` in ``info["error"]``."""
    return SolverResult(
        status=SolveStatus.NUMERICAL_ERROR,
        x=None,
        objective=math.nan,
        iterations=0,
        solve_time_s=solve_time_s,
        solver=solver,
        info={"error": message, **info},
    )


def error_message(exc: BaseException) -> str:
    """``TypeName: message`` for an exception raised inside a solver."""
    return f"{type(exc).__name__}: {exc}"
