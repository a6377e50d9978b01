"""Monte Carlo campaigns: dispersed closed-loop runs on a local process pool or Dask.

A campaign is a scenario (its ``[dispersions]`` table, see :mod:`proxops.analysis.dispersions`),
a campaign seed and a number of runs. Run ``i`` gets its own seeds from the numpy
SeedSequence spawn tree of the campaign seed: child ``(i, 0)`` seeds the simulation (navigation
noise, thrust errors, missed thrusts), child ``(i, 1)`` draws the dispersed values. Its row
holds ``run_id, seed, grid_index``, the dispersed values (``disp.<key>``), the outcome and
the run summary flattened (``metric.<key>``), so :func:`rerun` repeats it alone, bit for bit.

On disk (``out``)::

    campaign.json            manifest: scenario name, content hash (file + overrides),
                             campaign seed, n_runs, the scenario data itself (for rerun)
    runs/part-*.parquet      rows, one file per finished batch (atomic rename), read back
                             consolidated (deduplicated on run_id, sorted)
    series/run_XXXXXX/       optional per-run time series (SimResult.save)

Execution: ``workers=1`` runs in this process; ``workers>1`` uses a spawn-safe
ProcessPoolExecutor; ``scheduler="tcp://HOST:PORT"``, a scheduler-file path or a
``distributed.Client`` uses Dask. Runs are sent in batches sized on the fly (about
``target_batch_s`` of work each) to keep per-run overhead low. A run that raises is a row with
``outcome = "error"``; a killed pool worker is replaced and its runs retried.

Ctrl-C (or SIGTERM) at any moment: the first one only raises a flag (:class:`_GracefulStop`);
the driver stops submitting, lets the batches in flight finish, saves them and raises
:class:`CampaignInterrupted`. A second Ctrl-C stops waiting (runs still in flight are not
saved; finished ones are). Pool workers are born with SIGINT blocked and ignore it from their
first instruction, so a Ctrl-C during their imports cannot kill them.

Columns whose values depend on the machine (``metric.wall_time_s``, ``metric.solve_time_ms.*``,
``run_wall_s``, ``run_cpu_s``) are excluded by :meth:`CampaignResult.deterministic_table`.
"""

from __future__ import annotations

import atexit
import copy
import hashlib
import json
import math
import multiprocessing
import os
import signal
import sys
import time
import traceback
import uuid
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as cf_wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np
import pandas as pd

from proxops.analysis.dispersions import DispersionPlan, apply_values, parse_dispersions
from proxops.analysis.statistics import (
    METRIC_PREFIX,
    DISP_PREFIX,
    metric_statistics,
    outcome_counts,
    statistics_dict,
)
from proxops.errors import ProxopsError, ProxopsInputError

FORMAT = "proxops-campaign/1"
MANIFEST = "campaign.json"
START_METHOD = "spawn"  # spawn-safe everywhere; nothing is inherited from the parent
MAX_POOL_RESTARTS = 10
MAX_RUNS = 10_000_000  # rows of one campaign; items are made lazily, the table of results is what grows
from proxops.systems.base import FAILED_STATUSES  # noqa: E402,F401  (one home: the default SystemBase.success)


class CampaignError(ProxopsError):
    """The campaign could not go on (finished runs are saved; ``resume`` continues)."""


class CampaignInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a campaign; every finished run was saved. ``str()`` says how many and where."""

    def __init__(self, message: str, new_runs: int = 0, out: Path | None = None):
        super().__init__(message)
        self.new_runs = new_runs
        self.out = out


@dataclass
class RunError:
    """What :func:`map_runs` returns for an item whose function raised (``errors="return"``)."""

    message: str
    traceback: str = ""


# =========================================================================== execution layer
_NO_CONTEXT = "__proxops_no_context__"
_POOLS: dict[int, ProcessPoolExecutor] = {}  # reused across campaigns/sweeps of this process


def _init_worker() -> None:
    """Pool worker start: ignore Ctrl-C (the parent decides when to stop). The worker was
    spawned with SIGINT blocked (:func:`_sigint_blocked`), so a Ctrl-C that arrived during its
    imports is pending: ignoring it discards it, then it is unblocked."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread
        pass
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


class _sigint_blocked:
    """Block SIGINT in this thread (a Ctrl-C waits, it is not lost). Processes started inside
    inherit the mask, so spawned pool workers cannot be interrupted before :func:`_init_worker`."""

    def __enter__(self):
        self.old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        return self

    def __exit__(self, *exc):
        signal.pthread_sigmask(signal.SIG_SETMASK, self.old)
        return False


class _GracefulStop:
    """While active (main thread only): the first SIGINT/SIGTERM sets ``requested``; the
    second raises KeyboardInterrupt. Elsewhere (another thread) it only reads ``requested``."""

    def __init__(self):
        self.requested = False
        self.previous: dict = {}

    def _handler(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def __enter__(self):
        import threading

        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.previous[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc):
        for sig, old in self.previous.items():
            signal.signal(sig, old)
        self.previous.clear()
        return False


def _run_chunk(func, items, context, errors: str):
    """Apply ``func`` to each item; returns ``(results, elapsed_s)``."""
    t0 = time.perf_counter()
    out = []
    for item in items:
        if errors == "return":
            try:
                out.append(func(item) if _is_no_context(context) else func(context, item))
            except Exception as exc:  # recorded, the sweep goes on
                out.append(RunError(f"{type(exc).__name__}: {exc}", traceback.format_exc(limit=20)))
        else:
            out.append(func(item) if _is_no_context(context) else func(context, item))
    return out, time.perf_counter() - t0


def _is_no_context(context) -> bool:
    return isinstance(context, str) and context == _NO_CONTEXT


def _run_chunk_dask(func, items, context, errors):
    return _run_chunk(func, items, context, errors)


class _SerialBackend:
    """Runs batches in this process, one item at a time (Ctrl-C keeps what finished)."""

    slots = 1
    name = "serial"
    suspects_alone = False

    def __init__(self, context):
        self.context = context
        self.stop = _GracefulStop()  # replaced by the driver's

    def submit(self, func, items, errors):
        fut: Future = Future()
        t0 = time.perf_counter()
        out = []
        try:
            for item in items:
                if self.stop.requested:  # Ctrl-C: keep what finished, leave the rest queued
                    break
                out.append(_run_chunk(func, [item], self.context, errors)[0][0])
        except Exception as exc:
            fut.set_exception(exc)
            return fut
        fut.set_result((out, time.perf_counter() - t0))
        return fut

    def wait(self, futures, timeout):
        return set(futures), set()

    def cancel(self, fut) -> bool:
        return False

    def restart(self) -> None:
        raise AssertionError("serial backend never breaks")

    def close(self, cancel: bool = False, force: bool = False) -> None:
        pass


class _PoolBackend:
    """Local ProcessPoolExecutor (spawn). The pool is kept for later campaigns and sweeps of
    this process (workers keep their imports, JIT caches and prepared scenarios); the context
    travels with each batch (a few kB)."""

    name = "local"
    suspects_alone = True  # a dying worker breaks the whole pool: run suspects alone

    def __init__(self, workers: int, context):
        self.slots = workers
        self.context = context
        self._saved_env = _single_thread_env()  # workers spawned while this backend lives inherit it
        pool = _POOLS.get(workers)
        if pool is None or getattr(pool, "_broken", False) or getattr(pool, "_shutdown_thread", False):
            pool = _POOLS[workers] = _new_pool(workers)
        self.pool = pool

    def submit(self, func, items, errors):
        with _sigint_blocked():  # submit() may spawn a worker: it must start immune to Ctrl-C
            return self.pool.submit(_run_chunk, func, items, self.context, errors)

    def wait(self, futures, timeout):
        return cf_wait(futures, timeout=timeout, return_when=FIRST_COMPLETED)

    def cancel(self, fut) -> bool:
        return fut.cancel()

    def restart(self) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)
        self.pool = _POOLS[self.slots] = _new_pool(self.slots)

    def close(self, cancel: bool = False, force: bool = False) -> None:
        if cancel:  # interrupted or failed: do not keep a pool with work in it
            _POOLS.pop(self.slots, None)
            _stop_pool(self.pool, force)
        _restore_env(self._saved_env)


# One BLAS/OpenMP thread per worker process: with several processes on few cores, threaded
# BLAS on the small matrices of a closed loop oversubscribes the CPUs (measured 2.5x slower
# per run with 2 processes on 2 cores). Dask's nanny does the same for its workers. Values the
# user has set are kept.
THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _single_thread_env() -> dict:
    saved = {}
    for key, val in THREAD_ENV.items():
        if key not in os.environ:
            saved[key] = None
            os.environ[key] = val
    return saved


def _restore_env(saved: dict) -> None:
    for key in saved:
        os.environ.pop(key, None)


def _new_pool(workers: int) -> ProcessPoolExecutor:
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(START_METHOD),
                               initializer=_init_worker)


def _stop_pool(pool: ProcessPoolExecutor, force: bool) -> None:
    """Shut a pool down and join its manager thread and workers, so their pipes and semaphores
    are released before this process exits; ``force`` first terminates busy workers. (One
    ``shutdown`` call: after ``shutdown(wait=False)`` the executor forgets its thread and a
    later ``wait=True`` would not join it.)"""
    if force:
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            try:
                proc.terminate()
            except Exception:  # already gone
                pass
    with _sigint_blocked():  # a Ctrl-C now would leave half-closed queues behind
        pool.shutdown(wait=True, cancel_futures=True)


def shutdown_pools(force: bool = False) -> None:
    """Stop the worker processes kept for reuse (also done at interpreter exit); ``force``
    terminates busy ones instead of waiting for them."""
    while _POOLS:
        _, pool = _POOLS.popitem()
        _stop_pool(pool, force)


atexit.register(shutdown_pools)


class _DaskBackend:
    """Dask distributed: a scheduler address, a scheduler file or an existing Client."""

    name = "dask"
    suspects_alone = False  # Dask reports a lost task per batch

    def __init__(self, scheduler, context, connect_timeout_s: float):
        self.own_client = False
        self.client = _dask_client(scheduler, connect_timeout_s)
        self.own_client = not _is_client(scheduler)
        try:
            self.client.wait_for_workers(1, timeout=connect_timeout_s)
        except (TimeoutError, OSError):
            self.close()
            raise ProxopsInputError(
                f"--scheduler {scheduler}: the scheduler has no workers after {connect_timeout_s:g} s; "
                "start some with `dask worker ADDRESS`"
            ) from None
        nthreads = self.client.nthreads()
        self.slots = max(1, sum(nthreads.values()))
        self.has_context = not _is_no_context(context)
        self.context = self.client.scatter(context, broadcast=True, hash=False) if self.has_context else context

    def submit(self, func, items, errors):
        return self.client.submit(_run_chunk_dask, func, items, self.context, errors, pure=False)

    def wait(self, futures, timeout):
        # poll: distributed.wait() needs a default client, and batches last ~target_batch_s anyway
        deadline = time.perf_counter() + timeout
        while True:
            done = {f for f in futures if f.done()}
            if done or time.perf_counter() >= deadline:
                return done, set(futures) - done
            time.sleep(0.002)

    def cancel(self, fut) -> bool:
        return False  # Dask cannot tell queued from running: let in-flight batches finish

    def restart(self) -> None:
        raise AssertionError("dask backend retries per batch")

    def close(self, cancel: bool = False, force: bool = False) -> None:
        if self.own_client:
            try:
                self.client.close(timeout=5)
            except Exception:
                pass


def _is_client(obj) -> bool:
    return type(obj).__name__ == "Client" and hasattr(obj, "submit") and hasattr(obj, "scatter")


def _dask_client(scheduler, connect_timeout_s: float):
    """A connected ``distributed.Client`` or a clear error within ``connect_timeout_s``."""
    if _is_client(scheduler):
        return scheduler
    from distributed import Client

    text = str(scheduler)
    is_address = "://" in text or (":" in text and not Path(text).suffix == ".json" and not Path(text).exists())
    kwargs = dict(timeout=connect_timeout_s, set_as_default=False)
    if not is_address:
        path = Path(text)
        if not path.is_file():
            raise ProxopsInputError(
                f"--scheduler {text!r}: no such scheduler file, and not an address; give tcp://HOST:PORT "
                "or the JSON file written by `dask scheduler --scheduler-file FILE`"
            )
        kwargs["scheduler_file"] = str(path)
    else:
        from distributed.comm.addressing import parse_address, parse_host_port

        try:  # checked before a Client exists: a half-built Client prints a traceback when collected
            scheme, location = parse_address(text)
            if scheme in ("tcp", "tls"):
                parse_host_port(location)
        except ValueError as exc:
            raise ProxopsInputError(f"--scheduler {text!r}: {exc}; give tcp://HOST:PORT or a scheduler file") from None
        kwargs["address"] = text
    try:
        return Client(**kwargs)
    except (OSError, TimeoutError) as exc:
        raise ProxopsInputError(
            f"--scheduler {text!r}: could not connect within {connect_timeout_s:g} s "
            f"({type(exc).__name__}: {exc}); start one with `dask scheduler` and `dask worker ADDRESS`, "
            "or leave --scheduler out to use local processes"
        ) from None
    except ValueError as exc:
        raise ProxopsInputError(f"--scheduler {text!r}: {exc}") from None


def _make_backend(workers: int | None, scheduler, context, connect_timeout_s: float, n_items: int):
    if scheduler is not None:
        return _DaskBackend(scheduler, context, connect_timeout_s)
    workers = default_workers() if workers is None else workers
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ProxopsInputError(f"workers = {workers!r}: give a whole number >= 1 (1 runs in this process)")
    workers = min(workers, max(1, n_items))
    if workers == 1:
        return _SerialBackend(context)
    return _PoolBackend(workers, context)


def default_workers() -> int:
    """Worker processes when none are asked for: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


@dataclass
class _Progress:
    done: int = 0
    failed: int = 0


def _drive(backend, func, items: Sequence, errors: str, on_batch: Callable, chunk_size: int | None,
           target_batch_s: float, on_lost: Callable | None = None, on_tick: Callable | None = None) -> None:
    """Send ``items`` in adaptive batches to ``backend`` and hand each finished batch to
    ``on_batch(indices, results)``. Handles Ctrl-C (:class:`_GracefulStop`: finish and hand over
    the batches in flight, then raise KeyboardInterrupt), broken local pools (restart, retry
    suspects one at a time) and lost Dask batches."""
    queue = _Queue(len(items))
    suspects: set[int] = set()
    in_flight: dict[Any, list[int]] = {}
    per_item_s: float | None = None
    restarts = 0
    finished = False
    forced = False
    max_in_flight = 2 * backend.slots
    stop = _GracefulStop()
    backend.stop = stop

    def batch_size() -> int:
        if chunk_size is not None:
            return chunk_size
        if per_item_s is None:
            return 1
        cap = max(1, math.ceil(len(queue) / max_in_flight))
        return max(1, min(cap, int(target_batch_s / max(per_item_s, 1e-6))))

    def submit_more() -> None:
        while queue and len(in_flight) < max_in_flight:
            if queue[0] in suspects:  # after a lost batch: suspects go one per batch to find the culprit
                if backend.suspects_alone and in_flight:  # a broken pool fails every batch in flight
                    return
                idx = [queue.popleft()]
                in_flight[backend.submit(func, [items[idx[0]]], errors)] = idx
                if backend.suspects_alone:
                    return
                continue
            size = min(batch_size(), len(queue))
            idx = []
            while queue and len(idx) < size and queue[0] not in suspects:
                idx.append(queue.popleft())
            in_flight[backend.submit(func, [items[i] for i in idx], errors)] = idx

    def harvest(fut, idx) -> None:
        nonlocal per_item_s
        results, elapsed = fut.result()
        if results:
            rate = elapsed / len(results)
            per_item_s = rate if per_item_s is None else 0.7 * per_item_s + 0.3 * rate
        if len(results) < len(idx):  # serial backend interrupted mid-batch
            queue.extendleft(reversed(idx[len(results):]))
        if results:
            on_batch(idx[: len(results)], results)

    with stop:
        try:
            while queue or in_flight:
                if stop.requested:
                    raise KeyboardInterrupt
                submit_more()
                done, _ = backend.wait(list(in_flight), timeout=0.1)
                if on_tick is not None:
                    on_tick()
                broken = False
                for fut in done:
                    idx = in_flight.pop(fut)
                    try:
                        harvest(fut, idx)
                    except BrokenProcessPool:
                        broken = True
                        if len(idx) == 1 and idx[0] in suspects and not in_flight:
                            _lost(on_lost, idx, "the worker process died while running this item", errors, items)
                            suspects.discard(idx[0])
                            broken = "culprit"
                        else:
                            suspects.update(idx)
                            queue.extendleft(reversed(idx))
                    except Exception as exc:
                        if errors == "raise" or not _is_lost_batch(exc):
                            raise
                        if len(idx) > 1:  # a Dask worker died: retry the items one by one
                            suspects.update(idx)
                            queue.extendleft(reversed(idx))
                        else:
                            _lost(on_lost, idx, f"{type(exc).__name__}: {exc}", errors, items)
                            suspects.discard(idx[0])
                if broken:
                    for fut, idx in list(in_flight.items()):
                        suspects.update(idx)
                        queue.extendleft(reversed(idx))
                    in_flight.clear()
                    restarts += broken != "culprit"  # breaks not yet pinned on one item
                    if restarts > MAX_POOL_RESTARTS:
                        raise CampaignError(
                            f"worker processes died {restarts} times; every finished run is saved, "
                            "resume to complete the rest"
                        )
                    backend.restart()
            finished = True
        except KeyboardInterrupt:  # a second Ctrl-C while waiting gives up on the runs in flight
            forced = not _finish_in_flight(backend, in_flight, harvest)
            raise
        finally:
            backend.close(cancel=not finished, force=forced)


class _Queue:
    """Indices still to send: retried ones first (a deque), then ``next_fresh .. n - 1`` made on
    demand, so a campaign of millions of runs starts at once and holds no list of them."""

    def __init__(self, n: int):
        self.n, self.next_fresh, self.retry = n, 0, deque()

    def __len__(self) -> int:
        return len(self.retry) + self.n - self.next_fresh

    def __bool__(self) -> bool:
        return len(self) > 0

    def __getitem__(self, k: int) -> int:  # only [0] is used: the next index
        return self.retry[0] if self.retry else self.next_fresh

    def popleft(self) -> int:
        if self.retry:
            return self.retry.popleft()
        self.next_fresh += 1
        return self.next_fresh - 1

    def extendleft(self, indices) -> None:
        self.retry.extendleft(indices)


def _finish_in_flight(backend, in_flight: dict, harvest) -> bool:
    """After Ctrl-C: cancel what has not started, hand over what finishes. Returns False if a
    second Ctrl-C gave up waiting."""
    for fut in list(in_flight):
        if backend.cancel(fut):
            in_flight.pop(fut)
    try:
        while in_flight:
            done, _ = backend.wait(list(in_flight), timeout=0.1)
            for fut in done:
                idx = in_flight.pop(fut)
                try:
                    harvest(fut, idx)
                except Exception:  # a batch lost while stopping: its runs stay missing
                    pass
    except KeyboardInterrupt:
        return False
    return True


def _is_lost_batch(exc: BaseException) -> bool:
    name = type(exc).__name__
    return name in ("KilledWorker", "CommClosedError", "FutureCancelledError", "CancelledError") or isinstance(exc, OSError)


def _lost(on_lost, idx, message, errors, items):
    if errors == "raise" or on_lost is None:
        raise CampaignError(f"item {idx[0]}: {message}")
    on_lost(idx[0], message)


def map_runs(func: Callable, items: Iterable, workers: int | None = None, scheduler=None, *, context: Any = _NO_CONTEXT,
             errors: str = "raise", chunk_size: int | None = None, progress: bool = False,
             connect_timeout_s: float = 5.0, target_batch_s: float = 0.5, desc: str = "runs") -> list:
    """``[func(item) for item in items]`` (or ``func(context, item)``) in parallel, in order.

    - ``func`` must be picklable (a module-level function); ``context`` (optional) is sent
      once per worker, e.g. a precomputed grid or a scenario dict.
    - ``workers``: local processes (default: the usable CPUs; 1 = this process).
    - ``scheduler``: ``"tcp://HOST:PORT"``, a scheduler-file path or a ``distributed.Client``
      (Dask; an unreachable scheduler is a :class:`ProxopsInputError` after ``connect_timeout_s``).
    - ``errors="raise"`` stops at the first exception; ``"return"`` puts a :class:`RunError`
      in that item's place and goes on.
    - Items go in batches of about ``target_batch_s`` seconds (or ``chunk_size`` items).
    """
    items = list(items)
    if errors not in ("raise", "return"):
        raise ProxopsInputError(f"errors = {errors!r}: allowed raise, return")
    if chunk_size is not None and chunk_size < 1:
        raise ProxopsInputError(f"chunk_size = {chunk_size!r}: give a whole number >= 1")
    results: list = [None] * len(items)
    if not items:
        return results
    backend = _make_backend(workers, scheduler, context, connect_timeout_s, len(items))
    bar = _bar(len(items), 0, desc, progress)
    state = _Progress()

    def on_batch(idx, batch):
        for i, r in zip(idx, batch):
            results[i] = r
            state.failed += isinstance(r, RunError)
        state.done += len(idx)
        bar.update(len(idx))
        if state.failed:
            bar.set_postfix(failed=state.failed, refresh=False)

    def on_lost(i, message):
        on_batch([i], [RunError(message)])

    try:
        _drive(backend, func, items, errors, on_batch, chunk_size, target_batch_s, on_lost=on_lost)
    finally:
        bar.close()
    return results


def _bar(total: int, initial: int, desc: str, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit="run", file=sys.stderr, disable=not enabled,
                dynamic_ncols=True, mininterval=0.5, smoothing=0.1)


# =========================================================================== campaign
@dataclass(frozen=True)
class CampaignSpec:
    """What every worker needs to run any run of a campaign (sent once per worker)."""

    data: dict  # scenario TOML data after overrides, without [dispersions]
    system: str
    system_module: str
    source: str
    scenario_hash: str
    keep_series: bool = False


@dataclass(frozen=True)
class RunItem:
    run_id: int
    seed: int
    grid_index: int
    values: dict  # {dispersed key path: value}


_PREPARED: dict[str, tuple] = {}


def _prepared(spec: CampaignSpec):
    """(system, nominal validated scenario) of a spec, cached per process."""
    got = _PREPARED.get(spec.scenario_hash)
    if got is None:
        import importlib

        from proxops.scenarios.loader import validate_scenario

        if spec.system_module:
            importlib.import_module(spec.system_module)
        loaded = validate_scenario(copy.deepcopy(spec.data), (), source=spec.source)
        got = (loaded.system, loaded.scenario)
        _PREPARED[spec.scenario_hash] = got
    return got


def run_seeds(campaign_seed: int, run_id: int) -> tuple[int, np.random.Generator]:
    """Simulation seed (child ``(run_id, 0)``) and dispersion generator (child ``(run_id, 1)``)
    of run ``run_id``: the SeedSequence spawn tree of ``campaign_seed``."""
    sim_ss = np.random.SeedSequence(campaign_seed, spawn_key=(run_id, 0))
    seed = int(sim_ss.generate_state(1, np.uint64)[0] >> np.uint64(1))  # 63 bits: fits Parquet int64
    disp_rng = np.random.default_rng(np.random.SeedSequence(campaign_seed, spawn_key=(run_id, 1)))
    return seed, disp_rng


def campaign_run(spec: CampaignSpec, item: RunItem):
    """Run one dispersed closed loop; returns ``(row, SimResult or None)``. Never raises:
    an exception becomes ``outcome = "error"`` with its message."""
    from proxops.runner import execute
    from proxops.scenarios.loader import validate_scenario

    t0, cpu0 = time.perf_counter(), time.process_time()
    row: dict[str, Any] = {"run_id": int(item.run_id), "seed": int(item.seed), "grid_index": int(item.grid_index)}
    row.update({DISP_PREFIX + k: v for k, v in item.values.items()})
    series = None
    try:
        system, nominal = _prepared(spec)
        data = apply_values(copy.deepcopy(spec.data), item.values, nominal)
        loaded = validate_scenario(data, (), source=f"{spec.source} (run {item.run_id})")
        summary, results = execute(loaded, seed=item.seed)
        main = next(iter(results.values()))
        for name, value in (main.meta.get("max_violation") or {}).items():
            summary.setdefault("max_violation", {})[name] = float(value)
        ok = classify(system, loaded.scenario, summary)
        row.update(outcome="success" if ok else "failure", success=bool(ok), status=str(summary.get("status", "")),
                   error="")
        row.update(flatten_summary(summary))
        if spec.keep_series:
            series = main
    except Exception as exc:
        row.update(outcome="error", success=False, status="error", error=f"{type(exc).__name__}: {exc}",
                   error_traceback=traceback.format_exc(limit=20)[-4000:])
    row["run_wall_s"] = time.perf_counter() - t0
    row["run_cpu_s"] = time.process_time() - cpu0
    return row, series


def classify(system, sc, summary: dict) -> bool:
    """Success of one run: ``system.success(sc, summary)`` when the system defines it,
    otherwise the run did not end in a failed status."""
    return bool(system.success(sc, summary))  # default: SystemBase.success (status not failed)


_SKIP_SUMMARY = {"scenario", "system", "seed", "out", "status"}


def flatten_summary(summary: dict) -> dict:
    """Run summary -> ``{"metric.a.b": scalar}`` (lists as JSON text, None as NaN)."""
    out: dict[str, Any] = {}

    def walk(prefix: str, val) -> None:
        if isinstance(val, dict):
            for k, v in val.items():
                walk(f"{prefix}.{k}" if prefix else str(k), v)
        elif isinstance(val, (list, tuple, np.ndarray)):
            out[METRIC_PREFIX + prefix] = json.dumps(np.asarray(val).tolist() if isinstance(val, np.ndarray) else val,
                                                     default=str)
        elif val is None:
            out[METRIC_PREFIX + prefix] = math.nan
        elif isinstance(val, np.generic):
            out[METRIC_PREFIX + prefix] = val.item()
        elif isinstance(val, (bool, int, float, str)):
            out[METRIC_PREFIX + prefix] = val
        else:
            out[METRIC_PREFIX + prefix] = str(val)

    for key, val in summary.items():
        if key not in _SKIP_SUMMARY:
            walk(key, val)
    return out


_TIMING_MARKS = ("wall_time", "solve_time", "solve_ms", "compute_time", "compute_ms", "cpu_time", "elapsed")


def is_timing_column(col: str) -> bool:
    """Columns that depend on the machine and load, not on the run's inputs (wall and CPU
    times, solver and compute times in any unit, e.g. ``metric.mpc_solve_ms.median``)."""
    return col in ("run_wall_s", "run_cpu_s") or col.startswith(METRIC_PREFIX) and any(m in col for m in _TIMING_MARKS)


# --------------------------------------------------------------------------- loading scenarios
@dataclass
class _Prepared:
    data: dict  # full data after overrides (with dispersions)
    loaded: Any
    plan: DispersionPlan
    source: str
    overrides: list[str]


def _prepare(scenario, overrides: Sequence[str]) -> _Prepared:
    from proxops.scenarios.loader import LoadedScenario, read_toml, resolve, validate_scenario

    overrides = list(overrides)
    if isinstance(scenario, LoadedScenario):
        if overrides:
            raise ProxopsInputError("overrides: apply them when loading, or pass the scenario name/file/dict instead")
        data = scenario.scenario.model_dump(mode="json", exclude_none=True)
        source = scenario.source
    elif isinstance(scenario, dict):
        data = copy.deepcopy(scenario)
        source = "<dict>"
    else:
        path = resolve(str(scenario))
        data = read_toml(path)
        source = str(path)
    loaded = validate_scenario(data, overrides, source=source)  # applies overrides to data in place
    plan = parse_dispersions(loaded.scenario, loaded.scenario.dispersions)
    return _Prepared(data=data, loaded=loaded, plan=plan, source=source, overrides=overrides)


def scenario_hash(data: dict) -> str:
    """Content hash of a scenario's data after overrides (dispersions included)."""
    text = json.dumps(data, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# --------------------------------------------------------------------------- results
@dataclass
class CampaignResult:
    """Rows of a campaign (one per finished run) and its manifest."""

    table: pd.DataFrame
    manifest: dict
    out: Path | None = None
    wall_time_s: float = math.nan
    new_runs: int = 0

    @property
    def n_runs(self) -> int:
        return int(self.manifest.get("n_runs", len(self.table)))

    @property
    def complete(self) -> bool:
        return len(self.table) >= self.n_runs

    def missing(self) -> list[int]:
        have = set(self.table["run_id"].tolist()) if len(self.table) else set()
        return [i for i in range(self.n_runs) if i not in have]

    def statistics(self, subset: str = "completed", by=None) -> pd.DataFrame:
        return metric_statistics(self.table, subset=subset, by=by)

    def counts(self) -> dict:
        return outcome_counts(self.table)

    def deterministic_table(self) -> pd.DataFrame:
        """The table without machine-dependent timing columns (equal across backends/resumes)."""
        return self.table[[c for c in self.table.columns if not is_timing_column(c)]]

    def summary(self) -> dict:
        """The ``proxops mc --json`` object."""
        counts = self.counts()
        return {
            "scenario": self.manifest.get("scenario"),
            "runs": counts["runs"],
            "n_runs": self.n_runs,
            "succeeded": counts["succeeded"],
            "failed": counts["failed"],
            "errors": counts["errors"],
            "with_violations": counts["with_violations"],
            "violations_by_constraint": counts["violations_by_constraint"],
            "wall_time_s": None if not math.isfinite(self.wall_time_s) else round(self.wall_time_s, 3),
            "new_runs": self.new_runs,
            "complete": self.complete,
            "seed": self.manifest.get("seed"),
            "out": str(self.out) if self.out else None,
            "statistics": statistics_dict(self.statistics()),
        }

    def row(self, run_id: int) -> dict:
        hit = self.table[self.table["run_id"] == run_id]
        if hit.empty:
            raise ProxopsInputError(f"run_id = {run_id}: not in this campaign's finished runs (0..{self.n_runs - 1})")
        return hit.iloc[0].to_dict()

    def rerun(self, row_or_id, keep_series: bool = True):
        """Repeat one run alone from its row (or run_id); returns ``(row, SimResult or None)``."""
        row = self.row(row_or_id) if isinstance(row_or_id, (int, np.integer)) else dict(row_or_id)
        return rerun(row, self, keep_series=keep_series)

    def series(self, run_id: int):
        """The saved time series of a run (``keep_series=True`` campaigns)."""
        from proxops.sim.result import SimResult

        if self.out is None:
            raise ProxopsInputError("this campaign was not written to disk; rerun(run_id) gives its time series")
        path = series_dir(self.out, run_id)
        if not path.is_dir():
            raise ProxopsInputError(f"no time series for run {run_id} in {self.out} (run the campaign with keep_series)")
        return SimResult.load(path)


def series_dir(out: Path, run_id: int) -> Path:
    return Path(out) / "series" / f"run_{run_id:06d}"


def load_campaign(out: str | Path) -> CampaignResult:
    """Read a campaign folder: manifest and all finished rows (consolidated)."""
    out = Path(out)
    if not out.is_dir():
        raise ProxopsInputError(f"{out}: not a folder; give a campaign folder written by `proxops mc ... --out DIR`")
    manifest = read_manifest(out)
    if manifest is None:
        raise ProxopsInputError(f"{out}: not a campaign folder (no {MANIFEST}); `proxops mc ... --out {out}` makes one")
    return CampaignResult(table=read_rows(out, strict=True), manifest=manifest, out=out)


_MANIFEST_KEYS = ("format", "scenario", "scenario_hash", "seed", "n_runs", "scenario_data")


def read_manifest(out: Path) -> dict | None:
    """The folder's ``campaign.json`` (None if absent); a damaged one is a one-line error."""
    path = Path(out) / MANIFEST
    if not path.is_file():
        return None
    try:
        manifest = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ProxopsInputError(f"{path}: damaged campaign manifest ({exc}); restore it, or start the campaign "
                                "again in another folder") from None
    missing = [k for k in _MANIFEST_KEYS if not isinstance(manifest, dict) or k not in manifest]
    if missing:
        raise ProxopsInputError(f"{path}: damaged campaign manifest (missing {', '.join(missing)}); restore it, "
                                "or start the campaign again in another folder")
    return manifest


def read_rows(out: Path, strict: bool = False) -> pd.DataFrame:
    """Consolidate ``runs/part-*.parquet`` (last write of a run_id wins), sorted by run_id.
    A damaged part is an error with ``strict`` (reports must not silently drop runs); otherwise
    a warning, and its runs count as missing (resume runs them again; the file is kept)."""
    parts = sorted((Path(out) / "runs").glob("part-*.parquet"))
    frames = []
    for p in parts:
        try:
            frames.append(pd.read_parquet(p))
        except Exception as exc:  # a part cut by a crash or damaged on disk
            if strict:
                raise ProxopsInputError(
                    f"{p}: unreadable results file ({type(exc).__name__}); `proxops mc ... --resume` runs its "
                    "runs again, then move the file away") from None
            print(f"warning: {p.name} is unreadable, its runs count as missing and run again", file=sys.stderr)
    if not frames:
        return _empty_table()
    return _tidy(pd.concat(frames, ignore_index=True, sort=False))


def _empty_table() -> pd.DataFrame:
    return pd.DataFrame(columns=["run_id", "seed", "grid_index", "outcome", "success", "status", "error"])


def _tidy(table: pd.DataFrame) -> pd.DataFrame:
    table = table.drop_duplicates("run_id", keep="last").sort_values("run_id", kind="stable").reset_index(drop=True)
    completed = table["outcome"] != "error"
    for col in table.columns:
        if col.startswith(METRIC_PREFIX + "events."):
            filled = table[col].where(~completed | table[col].notna(), 0)
            table[col] = filled.astype("int64") if filled.notna().all() else filled
    front = ["run_id", "seed", "grid_index", "outcome", "success", "status", "error"]
    disp = sorted(c for c in table.columns if c.startswith(DISP_PREFIX))
    disp = [c for c in disp]  # declaration order is kept in the manifest; sorted here for stability
    metrics = [c for c in table.columns if c.startswith(METRIC_PREFIX)]
    rest = [c for c in table.columns if c not in front and c not in disp and c not in metrics]
    return table[[c for c in front if c in table.columns] + disp + sorted(metrics) + rest]


class _RowWriter:
    """Collects finished runs and appends them as Parquet parts (atomic rename), at most one
    part every ``flush_s`` seconds; time series are written as soon as a run arrives."""

    def __init__(self, out: Path | None, flush_s: float = 2.0):
        self.out = out
        self.flush_s = flush_s
        self.rows: list[dict] = []  # kept only without a folder (in-memory campaigns)
        self.written: list[Path] = []  # parts this writer wrote (compaction deletes only these)
        self.pending: list[dict] = []
        self.last_flush = time.perf_counter()
        if out is not None:
            (out / "runs").mkdir(parents=True, exist_ok=True)

    def add(self, rows: list[dict], series: list) -> None:
        if self.out is None:
            self.rows.extend(rows)
            return
        for row, res in zip(rows, series):
            if res is not None:
                res.save(series_dir(self.out, row["run_id"]))
        self.pending.extend(rows)
        self.tick()

    def tick(self) -> None:
        """Write the pending rows if the last write is ``flush_s`` old (also while runs are slow)."""
        if self.pending and time.perf_counter() - self.last_flush >= self.flush_s:
            with _sigint_blocked():
                self.flush()

    def flush(self) -> None:
        if self.out is None or not self.pending:
            return
        ids = [r["run_id"] for r in self.pending]
        self.written.append(write_part(self.out, pd.DataFrame(self.pending),
                                       f"{min(ids):08d}-{max(ids):08d}-{uuid.uuid4().hex[:8]}"))
        self.pending = []
        self.last_flush = time.perf_counter()


def write_part(out: Path, frame: pd.DataFrame, tag: str) -> Path:
    """Write ``runs/part-<tag>.parquet`` atomically (temporary file, then rename)."""
    final = Path(out) / "runs" / f"part-{tag}.parquet"
    tmp = final.with_name(final.name + ".tmp")
    frame.to_parquet(tmp, index=False)
    os.replace(tmp, final)
    return final


def compact(out: Path, parts: Sequence[Path]) -> None:
    """Merge ``parts`` (files this process wrote) into one; never touches another file, so a
    resume cannot delete results it did not write. A crash in between leaves duplicates,
    which are harmless: reading deduplicates on run_id."""
    parts = [Path(p) for p in parts if Path(p).is_file()]
    if len(parts) <= 1:
        return
    table = _tidy(pd.concat([pd.read_parquet(p) for p in parts], ignore_index=True, sort=False))
    merged = write_part(out, table, f"{int(table['run_id'].min()):08d}-{int(table['run_id'].max()):08d}-"
                                    f"all{uuid.uuid4().hex[:6]}")
    for p in parts:
        if p != merged:
            p.unlink(missing_ok=True)


def _check_out(out: Path, manifest: dict, resume: bool) -> dict | None:
    """Existing manifest for resume (or None for a new campaign); clear errors on mismatch."""
    if out.exists() and not out.is_dir():
        raise ProxopsInputError(f"--out {out}: exists and is a file; give a folder (it is created if missing)")
    old = read_manifest(out) if out.is_dir() else None
    if old is None:
        leftovers = [p.name for p in (out / "runs", out / "series") if p.exists()]
        if leftovers:  # rows of an unknown campaign: never mix them with new ones
            raise ProxopsInputError(
                f"--out {out}: holds {' and '.join(leftovers)}/ but no {MANIFEST}, so those results belong to no "
                "known campaign; choose an empty or new folder")
        if resume:
            raise ProxopsInputError(
                f"--resume {out}: no {MANIFEST} there, so nothing to resume; leave out --resume to start a campaign"
            )
        return None
    if not resume:
        raise ProxopsInputError(
            f"--out {out} already holds a campaign of scenario {old.get('scenario')!r} "
            f"({old.get('n_runs')} runs); pass --resume to complete it or choose another --out"
        )
    if old.get("format") != FORMAT:
        raise ProxopsInputError(f"--resume {out}: manifest format {old.get('format')!r}, this proxops writes {FORMAT!r}")
    if old.get("scenario_hash") != manifest["scenario_hash"]:
        raise ProxopsInputError(
            f"--resume {out}: that folder holds a campaign of scenario {old.get('scenario')!r} "
            f"(content hash {old.get('scenario_hash')}), not of {manifest['scenario']!r} with these overrides "
            f"(hash {manifest['scenario_hash']}); use the same scenario file and --set options, or another --out"
        )
    if old.get("proxops_version") != manifest["proxops_version"]:
        raise ProxopsInputError(
            f"--resume {out}: that campaign was run by proxops {old.get('proxops_version')}, this is "
            f"{manifest['proxops_version']}; rows of two versions would be mixed: finish it with that version or "
            "start again in another folder")
    if old.get("seed") != manifest["seed"]:
        raise ProxopsInputError(
            f"--resume {out}: campaign seed {manifest['seed']} differs from the folder's seed {old.get('seed')}; "
            f"pass --seed {old.get('seed')} or use another --out"
        )
    return old


def run_campaign(scenario, n_runs: int | None = None, workers: int | None = None, scheduler=None,
                 seed: int | None = None, out: str | Path | None = None, resume: bool = False,
                 overrides: Sequence[str] = (), progress: bool = True, keep_series: bool = False,
                 chunk_size: int | None = None, connect_timeout_s: float = 5.0,
                 target_batch_s: float = 0.5) -> CampaignResult:
    """Run (or with ``resume`` complete) a Monte Carlo campaign of a scenario.

    ``scenario``: built-in name, TOML file, raw dict or LoadedScenario. ``n_runs`` defaults to
    the number of grid points when the dispersions declare grids. ``seed`` (campaign seed,
    default ``sim.seed``) makes every run reproducible. ``out`` receives the manifest, the rows
    (Parquet, incrementally) and with ``keep_series`` each run's time series; ``out=None``
    keeps the rows in memory only. Ctrl-C saves the finished runs and re-raises KeyboardInterrupt.
    """
    if n_runs is not None and (isinstance(n_runs, bool) or not isinstance(n_runs, (int, np.integer))
                               or not 1 <= n_runs <= MAX_RUNS):
        raise ProxopsInputError(f"runs = {n_runs!r}: give a whole number of runs from 1 to {MAX_RUNS:,}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))
                             or not 0 <= seed < 2**63):
        raise ProxopsInputError(f"seed = {seed!r}: give a whole number from 0 to 2^63 - 1")
    if not (isinstance(connect_timeout_s, (int, float)) and math.isfinite(connect_timeout_s) and connect_timeout_s > 0):
        raise ProxopsInputError(f"connect_timeout_s = {connect_timeout_s!r} s: give a positive, finite number of seconds")
    if resume and out is None:
        raise ProxopsInputError("resume: give the campaign folder (--out DIR) to resume")
    if chunk_size is not None and (not isinstance(chunk_size, int) or chunk_size < 1):
        raise ProxopsInputError(f"chunk_size = {chunk_size!r}: give a whole number >= 1 (or None: sized on the fly)")
    if not target_batch_s > 0:
        raise ProxopsInputError(f"target_batch_s = {target_batch_s!r} s: give a positive duration")
    prep = _prepare(scenario, overrides)
    sc = prep.loaded.scenario
    plan = prep.plan
    from proxops.runner import check_scenario

    check_scenario(prep.loaded)  # every check a run makes, once, before anything is written
    previous = read_manifest(Path(out)) if (resume and out is not None and Path(out).is_dir()) else None
    if seed is None:
        seed = previous["seed"] if previous and isinstance(previous.get("seed"), int) else int(sc.sim.seed)
    seed = int(seed)
    if n_runs is None:
        if previous and previous.get("n_runs"):
            n_runs = int(previous["n_runs"])
        elif plan.grid:
            n_runs = plan.n_grid
        else:
            raise ProxopsInputError("runs: give the number of runs (--runs N, a whole number >= 1)")
    n_runs = int(n_runs)
    if n_runs > MAX_RUNS:
        raise ProxopsInputError(f"runs = {n_runs:,} (the grid size): at most {MAX_RUNS:,} runs in one campaign")

    system_module = type(prep.loaded.system).__module__
    data_hash = scenario_hash(prep.data)
    manifest = {
        "format": FORMAT,
        "scenario": sc.name,
        "system": sc.system,
        "source": prep.source,
        "overrides": prep.overrides,
        "scenario_hash": data_hash,
        "seed": seed,
        "n_runs": n_runs,
        "n_grid": plan.n_grid,
        "dispersion_columns": [DISP_PREFIX + c for c in plan.columns()],
        "grid_axes": [[DISP_PREFIX + c for c in cols] for cols in plan.grid_columns()],
        "keep_series": bool(keep_series),
        "system_module": system_module,
        "scenario_data": prep.data,
        "proxops_version": _version(),
    }
    out_path = Path(out) if out is not None else None
    done_ids: set[int] = set()
    if out_path is not None:
        old = _check_out(out_path, manifest, resume)
        if old is not None:
            if n_runs < old.get("n_runs", 0):
                n_runs = int(old["n_runs"])  # resume never shrinks a campaign
                manifest["n_runs"] = n_runs
            manifest["keep_series"] = bool(old.get("keep_series", keep_series)) or bool(keep_series)
            manifest["created_utc"] = old.get("created_utc")
            existing = read_rows(out_path)
            done_ids = set(int(i) for i in existing["run_id"].tolist())

    spec_data = {k: v for k, v in prep.data.items() if k != "dispersions"}
    spec = CampaignSpec(data=spec_data, system=sc.system, system_module=system_module, source=prep.source,
                        scenario_hash=data_hash, keep_series=manifest["keep_series"])
    items = _LazyItems(plan, seed, n_runs, done_ids)
    # connect (Dask) / check workers before writing anything, so a bad --scheduler leaves no folder behind
    backend = _make_backend(workers, scheduler, spec, connect_timeout_s, len(items)) if items else None
    if out_path is not None:
        out_path.mkdir(parents=True, exist_ok=True)
        manifest["created_utc"] = manifest.get("created_utc") or time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        tmp = out_path / (MANIFEST + ".tmp")
        tmp.write_text(json.dumps(manifest, indent=2, default=str))
        os.replace(tmp, out_path / MANIFEST)

    writer = _RowWriter(out_path)
    bar = _bar(n_runs, len(done_ids), f"mc {sc.name}", progress)
    state = _Progress()
    wall0 = time.perf_counter()

    def on_batch(idx, batch):
        rows = [r for r, _ in batch]
        writer.add(rows, [s for _, s in batch])
        state.done += len(rows)
        state.failed += sum(not r["success"] for r in rows)
        bar.update(len(rows))
        bar.set_postfix(failed=state.failed, refresh=False)

    def on_lost(i, message):
        item = items[i]
        row = {"run_id": item.run_id, "seed": item.seed, "grid_index": item.grid_index,
               **{DISP_PREFIX + k: v for k, v in item.values.items()},
               "outcome": "error", "success": False, "status": "error", "error": f"WorkerLost: {message}"}
        on_batch([i], [(row, None)])

    try:
        if backend is not None:
            _drive(backend, campaign_run, items, "return", on_batch, chunk_size, target_batch_s, on_lost=on_lost,
                   on_tick=writer.tick)
    except KeyboardInterrupt:
        with _sigint_blocked():  # the rows in hand are written whatever the user presses now
            writer.flush()
            bar.close()
        where = f"saved in {out_path}" if out_path is not None else "kept in memory only (no --out)"
        raise CampaignInterrupted(
            f"interrupted: {state.done} new runs {where}, {len(done_ids) + state.done} of {n_runs} finished; "
            "complete them with --resume", new_runs=state.done, out=out_path) from None
    finally:
        with _sigint_blocked():
            writer.flush()
        bar.close()
        wall = time.perf_counter() - wall0
    if out_path is not None:
        compact(out_path, writer.written)
        table = read_rows(out_path)
    else:
        table = _tidy(pd.DataFrame(writer.rows)) if writer.rows else _empty_table()
    return CampaignResult(table=table, manifest=manifest, out=out_path, wall_time_s=wall, new_runs=state.done)


class _LazyItems:
    """The runs still to do, as a sequence whose items are made when sent (a campaign of
    millions of runs starts at once)."""

    def __init__(self, plan: DispersionPlan, seed: int, n_runs: int, done_ids: set[int]):
        self.plan, self.seed = plan, seed
        self.todo = range(n_runs) if not done_ids else [i for i in range(n_runs) if i not in done_ids]

    def __len__(self) -> int:
        return len(self.todo)

    def __getitem__(self, k: int) -> RunItem:
        return make_item(self.plan, self.seed, self.todo[k])


def make_item(plan: DispersionPlan, campaign_seed: int, run_id: int) -> RunItem:
    """Seeds and dispersed values of run ``run_id`` (pure function of plan, seed and id)."""
    seed, rng = run_seeds(campaign_seed, run_id)
    grid_index, values = plan.values(run_id, rng)
    return RunItem(run_id=run_id, seed=seed, grid_index=grid_index, values=values)


def rerun(row: dict, campaign, keep_series: bool = True):
    """Repeat one run alone from its ``row`` (a dict or pandas Series of the campaign table).

    ``campaign``: a :class:`CampaignResult` or a campaign folder. Uses only the row's seed
    and ``disp.*`` values plus the scenario data stored in the manifest, so the returned row
    equals the stored one bit for bit (timing columns aside). Returns ``(row, SimResult)``."""
    if not isinstance(campaign, CampaignResult):
        campaign = load_campaign(campaign)
    m = campaign.manifest
    row = dict(row)
    data = m["scenario_data"]
    spec = CampaignSpec(data={k: v for k, v in data.items() if k != "dispersions"}, system=m["system"],
                        system_module=m.get("system_module", ""), source=m.get("source", "<manifest>"),
                        scenario_hash=m["scenario_hash"], keep_series=keep_series)
    values = {}
    for col, val in row.items():
        if isinstance(col, str) and col.startswith(DISP_PREFIX):
            if isinstance(val, float) and math.isnan(val):
                continue
            values[col[len(DISP_PREFIX):]] = val.item() if isinstance(val, np.generic) else val
    item = RunItem(run_id=int(row["run_id"]), seed=int(row["seed"]), grid_index=int(row.get("grid_index", 0)),
                   values=values)
    return campaign_run(spec, item)


def write_report(campaign, report_dir: str | Path | None = None, figures: bool = True, max_overlay: int = 100) -> dict:
    """Rebuild tables and figures of a campaign folder (or CampaignResult) under ``report_dir``
    (default ``<out>/report``): statistics.csv (Table 4 layout), summary.json, report.md and
    PNG figures. Returns ``{"summary": ..., "files": [...]}``."""
    from proxops.analysis.formatting import format_percent, format_quantity
    from proxops.analysis.statistics import format_table4

    result = campaign if isinstance(campaign, CampaignResult) else load_campaign(campaign)
    if result.out is None and report_dir is None:
        raise ProxopsInputError("report: this campaign has no folder; give report_dir")
    rdir = Path(report_dir) if report_dir is not None else result.out / "report"
    rdir.mkdir(parents=True, exist_ok=True)
    table, m = result.table, result.manifest
    summary = result.summary()
    files: list[Path] = []
    stats = result.statistics()
    stats.to_csv(rdir / "statistics.csv", index_label="metric")
    files.append(rdir / "statistics.csv")
    (rdir / "summary.json").write_text(json.dumps(summary, indent=2, default=str))
    files.append(rdir / "summary.json")
    counts = result.counts()
    lines = [
        f"# Monte Carlo campaign: {m.get('scenario')}",
        "",
        f"- scenario source: `{m.get('source')}`, overrides: {m.get('overrides') or 'none'}",
        f"- content hash {m.get('scenario_hash')}, campaign seed {m.get('seed')}, "
        f"{counts['runs']} of {m.get('n_runs')} runs finished",
        f"- succeeded {counts['succeeded']}, failed {counts['failed']} (of which {counts['errors']} raised), "
        f"runs with constraint violations {counts['with_violations']} {counts['violations_by_constraint'] or ''}",
        "",
        "## Statistics over runs that did not raise (layout of cortex-convex-guidance.md Table 4)",
        "",
        format_table4(stats) if len(stats) else "(no completed runs)",
        "",
    ]
    if counts["succeeded"] and counts["succeeded"] < counts["runs"]:
        lines += ["## Statistics over successful runs", "", format_table4(result.statistics(subset="success")), ""]
    grid_cols = [c for axis in m.get("grid_axes", []) for c in axis if c in table]
    if grid_cols and len(table) and m.get("n_grid", 1) <= 20:  # one Table 4 block per grid point (e.g. error level)
        done = table[table["outcome"] != "error"]
        for gi, grp in done.groupby("grid_index", sort=True):
            point = grp.iloc[0]
            label = ", ".join(f"{c.removeprefix('disp.')} = {format_quantity(point[c], c, significant=True)}" for c in grid_cols)
            lines += [f"### Grid point {int(gi)}: {label}", "", format_table4(metric_statistics(grp, subset="all")), ""]
    if grid_cols and len(table):
        by = table.groupby(grid_cols, sort=True)["success"].agg(["mean", "size"]).reset_index()
        by.to_csv(rdir / "grid_success.csv", index=False)
        files.append(rdir / "grid_success.csv")
        lines += ["## Success fraction per grid point", "",
                  "| " + " | ".join(c.removeprefix("disp.") for c in grid_cols) + " | runs | success |",
                  "|" + " --- |" * (len(grid_cols) + 2)]
        for _, r in by.head(200).iterrows():
            lines.append("| " + " | ".join(format_quantity(r[c], c, significant=True) for c in grid_cols)
                         + f" | {int(r['size'])} | {format_percent(r['mean'])} |")
        lines.append("")
    errs = table[table["outcome"] == "error"] if len(table) else table
    if len(errs):
        lines += ["## Runs that raised (first 10)", ""]
        lines += [f"- run {int(r.run_id)}: {r.error}" for r in errs.head(10).itertuples()]
        lines.append("")
    system_table = _system_campaign_table(m, table) if len(table) else ""
    if system_table:
        lines += ["## Results in the paper's layout", "", system_table, ""]
        (rdir / "paper_table.md").write_text(system_table + "\n")
        files.append(rdir / "paper_table.md")
    if figures and len(table):
        from proxops.plotting import campaign as cplot

        figs = [
            cplot.plot_dv_distribution(table, rdir / "dv_distribution.png"),
            cplot.plot_metric_histograms(table, rdir / "metrics.png"),
            cplot.plot_outcome_map(table, m, rdir / "outcome_map.png"),
        ]
        if result.out is not None and (result.out / "series").is_dir():
            picked = []
            for r in table.head(max_overlay).itertuples():
                d = series_dir(result.out, int(r.run_id))
                if d.is_dir():
                    from proxops.sim.result import SimResult

                    picked.append((SimResult.load(d), r.outcome))
            figs.append(cplot.plot_trajectory_overlay(picked, rdir / "trajectories.png", title=f"{m.get('scenario')}: "
                                                      f"{len(picked)} trajectories"))
            figs += _system_campaign_figures(m, [res for res, _ in picked], rdir)
        figs = [f for f in figs if f is not None]
        files += figs
        lines += ["## Figures", ""] + [f"![{f.stem}]({f.name})" for f in figs] + [""]
    (rdir / "report.md").write_text("\n".join(lines))
    files.append(rdir / "report.md")
    return {"summary": summary, "files": [str(f) for f in files], "report_dir": str(rdir)}


def _campaign_system(manifest: dict):
    """The campaign's nominal scenario, validated, with its system (for the report hooks)."""
    from proxops.scenarios.loader import validate_scenario

    data = {k: v for k, v in manifest["scenario_data"].items() if k != "dispersions"}
    return validate_scenario(data, source=str(manifest.get("scenario")))


def _system_campaign_figures(manifest: dict, results: list, rdir: Path) -> list[Path]:
    """Figures the scenario's own system draws from saved series (``campaign_figures`` hook),
    e.g. the srf Monte Carlo overlays of Figs. 5/7/10 with the approach axis and keep-out zone."""
    loaded = _campaign_system(manifest)
    if not results:
        return []
    return list(loaded.system.campaign_figures(loaded.scenario, results, rdir))


def _system_campaign_table(manifest: dict, table: pd.DataFrame) -> str:
    """A Markdown table the system builds from the campaign rows (``campaign_table`` hook),
    e.g. Table 3 of tumbling-target-reachability.md for the los-sweep grid; '' if none."""
    loaded = _campaign_system(manifest)
    return loaded.system.campaign_table(loaded.scenario, table)


def _version() -> str:
    from proxops import __version__

    return __version__


__all__ = [
    "run_campaign",
    "map_runs",
    "rerun",
    "load_campaign",
    "CampaignResult",
    "CampaignError",
    "CampaignInterrupted",
    "RunError",
    "campaign_run",
    "make_item",
    "run_seeds",
    "default_workers",
    "is_timing_column",
    "write_report",
]
