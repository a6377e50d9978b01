"""Optional extras: what only some users need is not installed by default, and asking for it
without the extra is a one-line input error naming the extra (not an ImportError traceback)."""

import sys

import pytest

from proxops.errors import ProxopsInputError
from proxops.exec.backends import _dask_client


def test_scheduler_without_the_cluster_extra_names_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if `proxops[cluster]` were not installed
    with pytest.raises(ProxopsInputError, match=r"--scheduler 'tcp://127.0.0.1:1'.*proxops\[cluster\]"):
        _dask_client("tcp://127.0.0.1:1", 1.0)
