"""Successive convexification: one loop shared by the srf MPC (CBF re-linearisation,
Silva et al. 2026 §4.4) and the CORTEX final approach (plume, Wijayatunga et al. eq. 22).

Each iteration solves a convex subproblem linearised about the previous iterate; the
caller supplies three callbacks and the loop owns the iteration order, the trust-region
update and the stop reasons::

    for it in 1..max_iter:
        if it > 1: relinearize(prev, trust.radius)     # new rows about the last iterate
        iterate, failure = solve()                     # failure: the subproblem's Status, iterate None
        if failure: stop (FAILED, failure)
        if converged(iterate, prev): stop (OPTIMAL)
        if merit(iterate) > merit(prev) + merit_tol: trust.shrink()   # over-reached
        prev = iterate
    stop (MAX_ITER)

The stop is a :class:`proxops.status.Status` (OPTIMAL: converged; MAX_ITER: the iteration cap
without convergence; FAILED: a subproblem failed, its own status in ``ScpResult.failure``).

``merit`` (e.g. the largest violation of the true non-convex constraint) drives the
trust region; without it the radius never changes. The helper does no linear algebra,
so a caller that keeps its problem in a persistent adapter (``update`` in place) keeps
its warm start / factorisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

from proxops.status import Status


@dataclass
class TrustRegion:
    """Radius of the trust region on the iterate's step (caller's units), halved by ``shrink``."""

    radius: float = math.inf
    factor: float = 0.5

    def shrink(self) -> None:
        self.radius *= self.factor


@dataclass
class ScpResult:
    """How the loop ended: ``status`` Status.OPTIMAL (converged), Status.MAX_ITER (cap reached
    without convergence) or Status.FAILED (a subproblem failed: ``failure`` holds its Status;
    Status.NONE otherwise); ``iterate`` is the last accepted iterate (None if none),
    ``iterations`` the number of subproblems solved."""

    status: Status
    iterate: Any
    iterations: int
    failure: Status = Status.NONE
    trust: TrustRegion | None = None

    @property
    def converged(self) -> bool:
        return self.status is Status.OPTIMAL


def successive_convexification(
    solve: Callable[[], tuple[Any, str | None]],
    converged: Callable[[Any, Any], bool],
    relinearize: Callable[[Any, float], None] | None = None,
    *,
    max_iter: int,
    trust: TrustRegion | None = None,
    merit: Callable[[Any], float] | None = None,
    merit_tol: float = 0.0,
) -> ScpResult:
    """Run the successive-convexification loop (see the module doc).

    solve(): solve the current convex subproblem -> (iterate, None) or (None, failure status: a
    :class:`Status`, or text that :meth:`Status.parse` reads; none given -> Status.FAILED).
    converged(iterate, prev): the convergence test (``prev`` is None on the first iterate).
    relinearize(prev, radius): rebuild the linearised rows (and trust-region rows) about ``prev``.
    max_iter: most subproblems solved (>= 1).
    trust / merit / merit_tol: the trust region is shrunk when merit rises by more than merit_tol.
    """
    trust = trust if trust is not None else TrustRegion()
    prev = None
    prev_merit = math.inf
    for it in range(1, max(1, int(max_iter)) + 1):
        if it > 1 and relinearize is not None:
            relinearize(prev, trust.radius)
        iterate, failure = solve()
        if iterate is None:
            reason = Status.parse(failure) if failure else Status.FAILED
            return ScpResult(Status.FAILED, prev, it, Status.FAILED if reason is Status.NONE else reason, trust)
        if converged(iterate, prev):
            return ScpResult(Status.OPTIMAL, iterate, it, Status.NONE, trust)
        value = merit(iterate) if merit is not None else math.nan
        if merit is not None and prev is not None and value > prev_merit + merit_tol:
            trust.shrink()
        prev, prev_merit = iterate, value
    return ScpResult(Status.MAX_ITER, prev, max(1, int(max_iter)), Status.NONE, trust)
