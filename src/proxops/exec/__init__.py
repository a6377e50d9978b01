"""Execution and process start-up: serial / process pool / Dask map of runs
(:mod:`proxops.exec.backends`, ``map_runs``), the console entry point (:mod:`proxops.exec.entry`),
the early start of a campaign's pool (:mod:`proxops.exec.prestart`), the fork server's warm-up
(:mod:`proxops.exec.worker_warmup`) and start-up trimming (:mod:`proxops.exec.startup`).

Nothing is imported here: ``proxops.exec.entry`` must load before anything heavy (the pool
machinery of ``backends`` costs ~0.09 s of CPU to import, measured with ``-X importtime``)."""
