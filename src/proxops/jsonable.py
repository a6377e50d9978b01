"""One JSON ``default=`` for everything proxops writes (summaries, reports, caches): numpy
scalars and arrays become Python numbers and lists, anything else its text (paths, enums)."""

from __future__ import annotations


def json_default(obj):
    """``json.dumps(..., default=json_default)``: numpy scalar -> item, array -> list, else ``str``."""
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)
