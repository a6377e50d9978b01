"""On-disk memo for deterministic set-up arrays of the full truth (density table, Sun/Moon fit).

A value is stored as ``<dir>/<name>-<key>.npy``, ``<dir>`` = ``truth-setup`` inside the numba cache
directory of the current sources (:func:`proxops._numba_cache.current_cache_dir`: a hash of every ``.py``
file of proxops, so any source edit starts an empty memo, as it starts a fresh numba cache) and
``<key>`` the SHA-1 of everything the value is computed from, which the caller passes (inputs,
the versions of the libraries that compute it). Only values that are a deterministic function of
those inputs may be stored (pymsis and erfa are: same inputs, same bits). Written to a temporary
file and renamed (workers of a campaign may write the same key at once); a missing, unreadable or
ill-shaped file is recomputed. ``PROXOPS_SETUP_CACHE=0`` turns the disk memo off.
"""

from __future__ import annotations

import hashlib
import os
from functools import lru_cache
from typing import Callable

import numpy as np

from proxops._numba_cache import current_cache_dir


@lru_cache(maxsize=1)
def memo_dir() -> str:
    """The folder of the memo for the current sources (computed once per process)."""
    return os.path.join(current_cache_dir(), "truth-setup")


def enabled() -> bool:
    return os.environ.get("PROXOPS_SETUP_CACHE", "1") != "0"


def digest(*parts) -> str:
    """SHA-1 (hex) of the parts: arrays by dtype, shape and bytes, anything else by ``repr``."""
    h = hashlib.sha1()
    for part in parts:
        if isinstance(part, np.ndarray):
            a = np.ascontiguousarray(part)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())
        else:
            h.update(repr(part).encode())
        h.update(b"|")
    return h.hexdigest()


def disk_get(name: str, key: str, shape: tuple, make: Callable[[], np.ndarray]) -> np.ndarray:
    """The float array of ``shape`` stored under (name, key), else ``make()`` (then stored)."""
    if not enabled():
        return make()
    path = os.path.join(memo_dir(), f"{name}-{key}.npy")
    try:
        value = np.load(path, allow_pickle=False)
        if value.shape == shape and value.dtype == np.float64:
            return value
    except (OSError, ValueError):
        pass
    value = make()
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        tmp = f"{path}.{os.getpid()}.tmp"
        with open(tmp, "wb") as f:
            np.save(f, value, allow_pickle=False)
        os.replace(tmp, path)
    except OSError:  # a read-only or full disk only costs the recomputation
        pass
    return value
