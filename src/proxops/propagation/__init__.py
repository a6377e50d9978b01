"""Truth propagation: two-body + J2 with the chaser relative to the target (Encke),
fast numba DOP853 path and scipy reference path, plus a linear CW plant."""

from proxops.propagation.truth import CWPlant, RelativeTruth, propagate_free_drift

__all__ = ["CWPlant", "RelativeTruth", "propagate_free_drift"]
