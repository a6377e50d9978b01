"""Numba disk cache keyed by the whole package's sources (cache busting).

numba's ``cache=True`` re-validates a cached kernel against its *own* source file only
(file time stamp and size); a kernel that calls kernels of other modules is not recompiled
when those change, so a stale cache can run an old callee inlined into a new caller (e.g.
an old kernels_full right-hand side on a new parameter or coefficient layout). Here the
cache directory is chosen per state of the package: ``NUMBA_CACHE_DIR`` =
``<base>/<stamp>``, the stamp a hash of (name, mtime_ns, size) of every ``.py`` file of
proxops, so any edit anywhere gives a fresh cache (one full recompilation). Set right before
numba's own import (a one-shot import hook that ``proxops/__init__`` installs; no numba import):
a command that never imports numba (``--help``, ``scenarios``, ``validate``) never hashes the
~200 files nor imports hashlib (4-7 ms of CPU, measured).

``<base>``: ``$PROXOPS_NUMBA_CACHE`` or ``~/.cache/proxops-numba``. A ``NUMBA_CACHE_DIR`` set
by the user is respected (used as the base). Old stamps' folders are not deleted (each is the
size of one compiled cache, a few MB).
"""

from __future__ import annotations

import os
import sys

PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


def _entries(folder: str, prefix: str, out: list) -> None:
    with os.scandir(folder) as it:
        for e in it:
            if e.name.endswith(".py"):
                st = e.stat()
                out.append(f"{prefix}{e.name}:{st.st_mtime_ns}:{st.st_size}")
            elif e.is_dir() and e.name != "__pycache__" and not e.name.startswith("."):
                _entries(e.path, f"{prefix}{e.name}/", out)


def source_stamp(package_dir: str = PACKAGE_DIR) -> str:
    """16-hex-digit hash of the names, mtimes and sizes of the ``.py`` files under ``package_dir``."""
    import hashlib  # here: a command without numba never stamps, so never imports it

    out: list[str] = []
    _entries(str(package_dir), "", out)
    return hashlib.sha1(";".join(sorted(out)).encode()).hexdigest()[:16]


def cache_base() -> str:
    """``$PROXOPS_NUMBA_CACHE``, else the user's ``NUMBA_CACHE_DIR``, else ``~/.cache/proxops-numba``."""
    return os.environ.get("PROXOPS_NUMBA_CACHE") or os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.path.expanduser("~"), ".cache", "proxops-numba"
    )


def cache_dir(package_dir: str = PACKAGE_DIR, base: str | None = None) -> str:
    """The cache directory for the current sources of ``package_dir``."""
    return os.path.join(cache_base() if base is None else base, source_stamp(package_dir))


def current_cache_dir() -> str:
    """The cache directory this process uses: ``NUMBA_CACHE_DIR`` once :func:`stamp_numba_cache` has set it
    (it already holds the stamp; :func:`cache_dir` would read it as the base and add the stamp twice), else
    :func:`cache_dir`."""
    if os.environ.get("PROXOPS_NUMBA_CACHE_STAMPED") == "1" and os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    return cache_dir()


def stamp_numba_cache() -> None:
    """Point numba's cache at :func:`cache_dir` before numba reads its configuration: now if numba is
    imported (its configuration is re-read), else right before numba's import (:class:`_BeforeNumba`)."""
    if os.environ.get("PROXOPS_NUMBA_CACHE_STAMPED") == "1":  # once per process tree (workers inherit it)
        return
    if "numba" in sys.modules:
        _stamp()
    elif not any(isinstance(f, _BeforeNumba) for f in sys.meta_path):
        sys.meta_path.insert(0, _BeforeNumba())


def _stamp() -> None:
    os.environ["NUMBA_CACHE_DIR"] = cache_dir()
    os.environ["PROXOPS_NUMBA_CACHE_STAMPED"] = "1"
    config = sys.modules.get("numba.core.config")
    if config is not None:  # numba imported before proxops: re-read the environment
        config.reload_config()


class _BeforeNumba:
    """Meta path finder that stamps the cache when ``numba`` is first looked up (then removes itself);
    it finds nothing, so numba is imported as usual, after the stamp."""

    def find_spec(self, name, path=None, target=None):
        if name == "numba":
            if self in sys.meta_path:
                sys.meta_path.remove(self)
            if os.environ.get("PROXOPS_NUMBA_CACHE_STAMPED") != "1":
                _stamp()
        return None
