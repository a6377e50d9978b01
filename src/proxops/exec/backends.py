"""Execution layer: map a function over items serially, on a spawn-safe local process pool or
on Dask, in batches sized on the fly, with graceful Ctrl-C (see :mod:`proxops.analysis.campaign`
for the campaign built on it). ``map_runs`` is the public entry; ``shutdown_pools`` closes the
pools kept for reuse in this process.
"""

from __future__ import annotations

import atexit
import json
import math
import multiprocessing
import os
import signal
import sys
import time
import traceback
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as cf_wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from proxops.errors import ProxopsError, ProxopsInputError
from proxops.exec import forkserver_exit  # in a parent or worker it only defines (see its docstring)
from proxops.exec.startup import defer_unused_numpy_submodules

# forkserver (POSIX): workers are forked from a server process started once per parent, which
# imports the modules given to :func:`prestart_pool` first, so each worker starts with them loaded
# (a spawned worker imports them itself: ~0.5 s of CPU per worker, measured). Nothing is inherited
# from the parent but the environment (no threads, no locks: the server is a fresh interpreter).
# Elsewhere spawn.
START_METHOD = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
# First module the fork server imports: it ends the server without Python's teardown (0.3-0.5 s
# with numba loaded, while it still holds this process's stderr open)
FORKSERVER_EXIT = "proxops.exec.forkserver_exit"
MAX_POOL_RESTARTS = 10
MAX_WORKERS = 256  # local worker processes of one pool (each holds its imports: ~0.2-0.4 GB)


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
    if forkserver_exit.SERVER_PID is not None:  # forked by the fork server: end when it ends
        forkserver_exit.die_with_parent(forkserver_exit.SERVER_PID)
    atexit.register(_worker_exit)
    defer_unused_numpy_submodules()  # runs after the handlers registered later (numba's): last


def _worker_exit() -> None:
    """A pool worker's last atexit handler: end the process without the interpreter's teardown of
    every module (0.3-0.9 s with numba's kernels loaded, measured), which ``shutdown_pools`` would
    wait for. The worker has handed every result over the pool's synchronous result queue and run
    multiprocessing's exit functions by then."""
    forkserver_exit.exit_without_teardown()


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
    """Local ProcessPoolExecutor (``START_METHOD``: forkserver on POSIX, else spawn). The pool is
    kept for later campaigns and sweeps of this process (workers keep their imports, JIT caches and
    prepared scenarios); the context travels with each batch (a few kB)."""

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

    def check(self, func, meanwhile: Callable[[], None] | None = None) -> bool:
        """Run ``func(context)`` once per worker slot before any work (each task warms a worker) and
        wait for the first to finish: True if it returned, its exception re-raised if it raised,
        False if the pool broke (the caller then checks by itself). ``meanwhile()`` runs in this
        process once the tasks are submitted, while the workers start."""
        pending = {self.submit(func, [None], "raise") for _ in range(self.slots)}
        if meanwhile is not None:
            meanwhile()
        while pending:
            done, pending = cf_wait(pending, timeout=0.1, return_when=FIRST_COMPLETED)
            for fut in done:
                try:
                    fut.result()
                except BrokenProcessPool:
                    return False
                return True
        return False

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


def _new_pool(workers: int, preload: Sequence[str] = ()) -> ProcessPoolExecutor:
    """A pool of ``workers`` processes. With forkserver, ``preload`` (module names) is what the
    server imports before it forks any worker -- effective only when this call starts the server
    (the first pool of this process); later pools fork from the same server."""
    ctx = multiprocessing.get_context(START_METHOD)
    if START_METHOD == "forkserver":  # a server already running keeps its imports
        ctx.set_forkserver_preload([FORKSERVER_EXIT, *(m for m in preload if m != FORKSERVER_EXIT)])
        _ensure_fork_server()
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker)


def _ensure_fork_server() -> None:
    """Start the fork server now (no effect when it runs), SIGINT blocked. Started from the main
    thread it dies with this process (:func:`proxops.exec.forkserver_exit.die_with_parent`: the
    kernel's parent-death signal fires when the thread that started it ends, so never from
    another thread), and its workers die with it."""
    import threading

    from multiprocessing import forkserver, resource_tracker

    main_thread = threading.current_thread() is threading.main_thread()
    if main_thread:
        os.environ[forkserver_exit.PARENT_ENV] = str(os.getpid())
    try:
        # The tracker first: its start unblocks SIGINT in this thread whatever the mask was before,
        # which let the fork server start with SIGINT deliverable (a Ctrl-C during its imports of
        # the warm-up printed a KeyboardInterrupt traceback, measured). Once it runs, the server's
        # own call of it does nothing, and the server starts with SIGINT blocked.
        resource_tracker.ensure_running()
        with _sigint_blocked():
            forkserver.ensure_running()
    finally:
        os.environ.pop(forkserver_exit.PARENT_ENV, None)


def prestart_pool(workers: int, modules: Sequence[str] = ()) -> None:
    """Spawn the local pool of ``workers`` processes now and have each import ``modules``, so that
    their start-up overlaps this process's own imports and checks (``proxops mc`` calls it before
    importing the campaign layer). The pool is the one a later campaign of this process with as
    many workers uses (kept in ``_POOLS`` like any pool). No effect for fewer than 2 workers or
    when that pool exists."""
    check_workers(workers)
    if workers < 2 or workers in _POOLS:
        return
    saved = _single_thread_env()  # the workers are spawned (inherit the environment) in submit
    try:
        pool = _POOLS[workers] = _new_pool(workers, modules)
        if START_METHOD == "forkserver":
            # The server has started (in _new_pool), with this environment and SIGINT blocked; its
            # first fork waits for its imports, so the submits that fork the workers wait in a thread
            # while this process goes on with its own imports (a submit of this process waits for them).
            import threading

            threading.Thread(target=_submit_imports, args=(pool, workers, tuple(modules)), daemon=True,
                             name="proxops-prestart").start()
        else:
            _submit_imports(pool, workers, tuple(modules))
    finally:
        _restore_env(saved)


def _submit_imports(pool: ProcessPoolExecutor, workers: int, modules: tuple[str, ...]) -> None:
    """One :func:`_import_modules` task per worker (starting them); a failure here (a broken pool)
    is left to the campaign's own submit, which reports or repairs it."""
    try:
        with _sigint_blocked():  # the workers start with SIGINT blocked
            for _ in range(workers):
                pool.submit(_import_modules, modules)
    except Exception:  # noqa: BLE001
        pass


def _import_modules(modules: tuple[str, ...]) -> None:
    import importlib

    for name in modules:
        importlib.import_module(name)


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
    terminates busy ones instead of waiting for them, and the fork server too (a later pool
    starts a new one): a Ctrl-C while the server still imported the warm-up left ``proxops``
    waiting for it to fork the workers it was asked for (up to 30 s measured, under load), only to
    stop them."""
    if force and _POOLS:
        _kill_fork_server()
    while _POOLS:
        _, pool = _POOLS.popitem()
        _stop_pool(pool, force)


def _kill_fork_server() -> None:
    """SIGKILL the fork server of this process, if one runs (it holds no state of ours: the workers
    it forked end with it, a request waiting for it sees the end of its pipe)."""
    if START_METHOD != "forkserver":
        return
    from multiprocessing import forkserver

    pid = getattr(getattr(forkserver, "_forkserver", None), "_forkserver_pid", None)  # no public accessor
    if pid is not None:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:  # already gone
            pass


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
    try:
        from distributed import Client
    except ImportError:
        raise ProxopsInputError(
            f"--scheduler {scheduler!r}: campaigns on a Dask cluster need the Dask client, which is an "
            "optional extra: pip install 'proxops[cluster]'"
        ) from None

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
    check_workers(workers)
    workers = min(workers, max(1, n_items))
    if workers == 1:
        return _SerialBackend(context)
    return _PoolBackend(workers, context)


def check_workers(workers) -> None:
    """A one-line input error unless ``workers`` is a whole number from 1 to :data:`MAX_WORKERS`."""
    if not isinstance(workers, int) or isinstance(workers, bool) or not 1 <= workers <= MAX_WORKERS:
        raise ProxopsInputError(f"workers = {workers!r}: give a whole number from 1 to {MAX_WORKERS} local processes "
                                "(1 runs in this process; more machines: --scheduler)")


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
           target_batch_s: float, on_lost: Callable | None = None, on_tick: Callable | None = None,
           finish_in_flight: bool = True) -> None:
    """Send ``items`` in adaptive batches to ``backend`` and hand each finished batch to
    ``on_batch(indices, results)``. Handles Ctrl-C (:class:`_GracefulStop`: finish and hand over
    the batches in flight, then raise KeyboardInterrupt; without ``finish_in_flight`` stop them at once), broken local pools (restart, retry
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
            forced = not finish_in_flight or not _finish_in_flight(backend, in_flight, harvest)
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
             connect_timeout_s: float = 5.0, target_batch_s: float = 0.5, desc: str = "runs",
             on_result: Callable[[int, Any], None] | None = None, finish_in_flight: bool = True) -> list:
    """``[func(item) for item in items]`` (or ``func(context, item)``) in parallel, in order.

    - ``func`` must be picklable (a module-level function); ``context`` (optional) is sent
      once per worker, e.g. a precomputed grid or a scenario dict.
    - ``workers``: local processes (default: the usable CPUs; 1 = this process).
    - ``scheduler``: ``"tcp://HOST:PORT"``, a scheduler-file path or a ``distributed.Client``
      (Dask; an unreachable scheduler is a :class:`ProxopsInputError` after ``connect_timeout_s``).
    - ``errors="raise"`` stops at the first exception; ``"return"`` puts a :class:`RunError`
      in that item's place and goes on.
    - Items go in batches of about ``target_batch_s`` seconds (or ``chunk_size`` items).
    - ``on_result(index, result)`` (optional) is called in this process as each result arrives.
    - Ctrl-C: the items in flight finish and are handed over (a second Ctrl-C stops them), then
      KeyboardInterrupt; with ``finish_in_flight=False`` they are stopped at once.
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
            if on_result is not None:
                on_result(i, r)
        state.done += len(idx)
        bar.update(len(idx))
        if state.failed:
            bar.set_postfix(failed=state.failed, refresh=False)

    def on_lost(i, message):
        on_batch([i], [RunError(message)])

    try:
        _drive(backend, func, items, errors, on_batch, chunk_size, target_batch_s, on_lost=on_lost,
               finish_in_flight=finish_in_flight)
    finally:
        bar.close()
    return results


def _bar(total: int, initial: int, desc: str, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit="run", file=sys.stderr, disable=not enabled,
                dynamic_ncols=True, mininterval=0.5, smoothing=0.1)
