"""numba's disk cache does not follow edits of the modules a cached kernel calls; proxops keys
its cache directory by all its sources (proxops._numba_cache). Checked on a two-module toy
package in subprocesses (fresh interpreters, as a user's next run)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import proxops
from proxops._numba_cache import cache_dir, source_stamp

CALLEE = "from numba import njit\n\n@njit(cache=True)\ndef g():\n    return {value}\n"
CALLER = "from numba import njit\nfrom callee import g\n\n@njit(cache=True)\ndef f():\n    return g() + 0\n"


def _run(folder: Path, numba_cache: str) -> str:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PROXOPS_NUMBA"))}
    env["NUMBA_CACHE_DIR"] = numba_cache
    res = subprocess.run([sys.executable, "-c", "import caller; print(caller.f())"], cwd=folder, env=env,
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert res.returncode == 0, res.stderr
    return res.stdout.strip()


def test_stamped_cache_follows_an_edited_callee(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "callee.py").write_text(CALLEE.format(value=1))
    (pkg / "caller.py").write_text(CALLER)
    base = str(tmp_path / "cache")
    first = cache_dir(pkg, base)
    assert _run(pkg, first) == "1"
    (pkg / "callee.py").write_text(CALLEE.format(value=22))
    st = os.stat(pkg / "callee.py")
    os.utime(pkg / "callee.py", ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # a later edit, whatever the clock
    # numba's own key (the caller's file) is unchanged: the old cache runs the old callee
    assert _run(pkg, first) == "1"
    # the stamped directory changed with the callee: recompiled, the new value
    second = cache_dir(pkg, base)
    assert second != first
    assert _run(pkg, second) == "22"


def _fresh(code: str, cache: Path) -> list[str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PROXOPS_NUMBA"))}
    env["PROXOPS_NUMBA_CACHE"] = str(cache)
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    return res.stdout.split()


def test_numba_imported_after_proxops_reads_the_stamped_cache(tmp_path):
    """Importing proxops hashes nothing (no NUMBA_CACHE_DIR, no numba, no hashlib: a command without
    numba skips the stamp); numba's configuration, read when numba is imported, is the stamped folder."""
    code = ("import os, sys, proxops; print(os.environ.get('NUMBA_CACHE_DIR', '-'), 'numba' in sys.modules, "
            "'hashlib' in sys.modules)\n"
            "import numba.core.config as c; print(c.CACHE_DIR, os.environ['NUMBA_CACHE_DIR'])")
    before, numba_loaded, hashed, config_dir, env_dir = _fresh(code, tmp_path)
    assert (before, numba_loaded, hashed) == ("-", "False", "False")
    stamped = os.path.join(str(tmp_path), source_stamp(Path(proxops.__file__).parent))
    assert config_dir == env_dir == stamped


def test_numba_imported_before_proxops_is_pointed_at_the_stamped_cache(tmp_path):
    code = "import numba.core.config as c, proxops; print(c.CACHE_DIR)"
    assert _fresh(code, tmp_path) == [os.path.join(str(tmp_path), source_stamp(Path(proxops.__file__).parent))]


def test_setup_memo_lies_in_the_stamped_cache_folder_once():
    """The truth set-up memo is ``<NUMBA_CACHE_DIR>/truth-setup`` of this process: the stamp appears once in its
    path (it was ``<base>/<stamp>/<stamp>/truth-setup`` when the stamped directory was read as the base)."""
    import numba  # noqa: F401 (importing numba after proxops stamps the cache)

    from proxops.environment import disk_memo

    assert os.environ.get("PROXOPS_NUMBA_CACHE_STAMPED") == "1"
    path = disk_memo.memo_dir()
    assert path == os.path.join(os.environ["NUMBA_CACHE_DIR"], "truth-setup")
    assert path.count(source_stamp()) == 1
