"""One module per paper (``claims/<system>.py``: a ``claims(ctx) -> list[Claim]``) and the shared row
types and verdict rules (:mod:`proxops.report.claims.common`). :data:`SYSTEMS` lists them in the
order ``proxops reproduce all`` runs them."""

from __future__ import annotations
from proxops.report.claims import cortex, hybrid, los, reach, srf, underactuated


def systems() -> dict:
    return {"srf": srf.srf_claims, "los": los.los_claims, "reach": reach.reach_claims,
            "underactuated": underactuated.underactuated_claims, "cortex": cortex.cortex_claims,
            "hybrid": hybrid.hybrid_claims}


SYSTEM_NAMES = ("srf", "los", "reach", "underactuated", "cortex", "hybrid")
