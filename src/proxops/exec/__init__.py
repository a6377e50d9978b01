"""Execution: serial / process pool / Dask map of runs (:func:`map_runs`)."""

from proxops.exec.backends import RunError, default_workers, map_runs, shutdown_pools

__all__ = ["RunError", "default_workers", "map_runs", "shutdown_pools"]
