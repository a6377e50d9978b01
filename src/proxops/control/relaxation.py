"""One relaxation ladder for controllers whose convex problem can be infeasible: the printed problem
first, then versions with fewer rows, in a fixed order; the first that solves gives the command and
each rung passed is an event. Users: the srf MPC (design rows -> terminal set -> hop rows; the CBF rows
are never dropped, Silva et al. §4.4) and the CORTEX tracking guidance CP_g (tightened cone -> printed
cone with plume rows -> without plume rows -> without cone, Wijayatunga et al. §3.2.1); each controller
names its own rungs.

    attempt(rung) -> (result, status)    result None: this rung failed with ``status``
    climb(rungs, attempt, on_relax)      on_relax(level, rung, status) after each failed rung but the last
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Generic, Sequence, TypeVar

R = TypeVar("R")


@dataclass
class Climb(Generic[R]):
    """Outcome of a ladder: the rung that solved (``level`` its index), or the last rung tried with
    ``result`` None and the status it failed with."""

    level: int
    rung: R
    result: Any
    status: Any

    @property
    def solved(self) -> bool:
        return self.result is not None


def climb(rungs: Sequence[R], attempt: Callable[[R], tuple[Any, Any]],
          on_relax: Callable[[int, R, Any], None] | None = None) -> Climb[R]:
    """Try ``rungs`` in order until ``attempt`` returns a result (see the module doc)."""
    if not rungs:
        raise ValueError("a relaxation ladder needs at least one rung")
    status = None
    for level, rung in enumerate(rungs):
        result, status = attempt(rung)
        if result is not None:
            return Climb(level, rung, result, status)
        if on_relax is not None and level < len(rungs) - 1:
            on_relax(level, rung, status)
    return Climb(len(rungs) - 1, rungs[-1], None, status)
