"""CORTEX reference generation (Wijayatunga et al. §3.1).

- :mod:`.holds`      sunlight-aware hold times (eqs. 13-15, Algorithm 1) on a sampled profile
- :mod:`.phases`     the convex phases CP1 (fly-around, KOS planes) and CP2 (cone, plume SCP)
- :mod:`.reference`  the outer problem (eq. 12), plan checks, Fibonacci axes
"""

from proxops.guidance.cortex.reference import (
    PAPER_FIXED_AXIS_HILL,
    CortexConfig,
    CortexPlan,
    fibonacci_axes,
    plan_reference,
)

__all__ = ["PAPER_FIXED_AXIS_HILL", "CortexConfig", "CortexPlan", "fibonacci_axes", "plan_reference"]
