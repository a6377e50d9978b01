"""One bounded per-process memo for values every run of a campaign recomputes identically.

Monte Carlo campaigns disperse a few inputs (usually the initial state); prediction blocks, plans
and ephemerides keyed on everything they depend on are then shared by all runs of a worker. A
dispersed input only misses. The caller's ``dict`` is the cache; it is cleared when it reaches
``max_entries`` (campaigns use a handful of keys, so eviction order does not matter).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

MAX_ENTRIES = 64


def memo_get(cache: dict, key, make: Callable[[], Any], *, read_only: bool = False,
             max_entries: int = MAX_ENTRIES):
    """``cache[key]``, computed by ``make()`` on a miss. With ``read_only`` every numpy array of the
    value (the value itself or the items of a tuple/list) is made read-only, so a caller cannot
    change what other runs receive."""
    value = cache.get(key)
    if value is None:
        value = make()
        if read_only:
            for a in value if isinstance(value, (tuple, list)) else (value,):
                if isinstance(a, np.ndarray):
                    a.flags.writeable = False
        if len(cache) >= max_entries:
            cache.clear()
        cache[key] = value
    return value
