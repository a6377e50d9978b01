"""One status vocabulary for solver and controller outcomes, and one for why a run stopped.

This module sits at the bottom of the layer order (beside :mod:`proxops.errors`): the
solver adapters (:mod:`proxops.solvers`), the controllers, the engine, the results and the
systems all import :class:`Status` from here, so nothing matches strings such as
``"ok"`` / ``"optimal"`` / ``"infeasible"``.

Both enums are ``str`` enums whose value is the text written to results (Parquet
``status`` column, ``meta.json`` ``stop_reason``): a value read back from disk compares
equal to its member (``"infeasible" == Status.INFEASIBLE``), and ``Status.parse`` maps any
stored text back onto a member.
"""

from __future__ import annotations

import enum


class Status(str, enum.Enum):
    """Outcome of one solve or one controller step."""

    NONE = ""  # no controller step at this sample (the final sample, a stop before stepping)
    OK = "ok"  # a law that does not optimise produced its command
    OPTIMAL = "optimal"
    OPTIMAL_INACCURATE = "optimal_inaccurate"  # converged to reduced tolerances
    INFEASIBLE = "infeasible"  # primal infeasible (certificate found)
    UNBOUNDED = "unbounded"  # dual infeasible: objective unbounded below
    MAX_ITER = "max_iter"
    TIME_LIMIT = "time_limit"
    NUMERICAL_ERROR = "numerical_error"  # includes solver exceptions and bad (NaN) data
    INFEASIBLE_SOLUTION = "infeasible_solution"  # solver said optimal, the returned point fails the check
    CBF_VIOLATION = "cbf_violation"  # successive convexification ended on a point that breaks the CBF
    INVALID_INPUT = "invalid_input"  # the controller was given a non-finite state (nothing solved)
    FAILED = "failed"  # any other failure of a controller (detail in the step's events / info)

    @property
    def ok(self) -> bool:
        """True when the step produced a usable command / the solve a usable solution."""
        return self in _OK

    @property
    def failed(self) -> bool:
        """True for a controller step or solve that failed (not ok, not NONE)."""
        return self is not Status.NONE and self not in _OK

    @property
    def flagged(self) -> bool:
        """True for every status the engine reports as a ``solver`` event and a run summary
        counts in ``solver_failures``: anything but NONE, OK and OPTIMAL (an inaccurate solve
        is usable but flagged)."""
        return self not in _CLEAN

    @classmethod
    def parse(cls, value) -> "Status":
        """The member for ``value`` (a member or its stored text); unknown text -> FAILED."""
        if value.__class__ is cls:
            return value
        return cls._value2member_map_.get(str(value), cls.FAILED)  # a dict look-up: runs every engine step

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)


_OK = frozenset({Status.OK, Status.OPTIMAL, Status.OPTIMAL_INACCURATE})
_CLEAN = frozenset({Status.NONE, Status.OK, Status.OPTIMAL})
NOT_FLAGGED = _CLEAN  # the statuses that are not ``flagged`` (the engine tests membership inline)


class StopReason(str, enum.Enum):
    """Why a closed-loop run ended (``SimResult.meta["stop_reason"]``). The specific name
    (``"docked"``, ``"handover"``, ``"qp_infeasible"`` ...) stays in ``meta["outcome"]``."""

    COMPLETED = "completed"  # reached the scenario duration
    STOP_CONDITION = "stop_condition"  # the setup's stop_condition(t, x) returned a reason
    CONTROLLER = "controller"  # the controller set Command.stop (mission end or failure)
    PLANT = "plant"  # the plant could not go on (proxops.errors.PlantEnded, e.g. re-entry)

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)
