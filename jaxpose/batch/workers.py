"""Where batch tasks run: local worker processes, a thread of this process, or a Dask cluster.

One small interface for all: ``submit(fn, *args) -> future``, ``wait(pending) -> done`` (wakes at
least every half second, so the caller stays responsive to interrupts), ``result(future)``
(raises :class:`WorkerLost` when the worker itself died, :class:`TaskTimeout` when a local task ran
past its time limit) and ``close(kill)``. A lost or stopped worker costs its own task only. Tasks must be pure
functions of their arguments; nothing is kept in a worker between tasks except what JAX caches
(compiled programs), so each worker compiles once.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import logging
import os
import queue
import threading

from ..errors import InvalidInputError, JaxposeError
from .pool import POLL_S, ProcessPool, TaskTimeout, WorkerLost

__all__ = ["WorkerLost", "TaskTimeout", "LocalExecutor", "DaskExecutor", "local_cluster", "default_workers",
           "process_environment", "configure_process", "runs_like_a_worker", "POLL_S"]

# one BLAS thread per process: parallelism comes from the workers, and sums come out in the same
# order in every process (bit-identical results locally and on Dask, which sets the same)
_ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def default_workers() -> int:
    """The number of cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def process_environment(one_thread=True) -> dict:
    """The environment variables of a worker process: one BLAS thread (unless `one_thread` is
    False), the compilation cache (:mod:`jaxpose.batch.cache`); variables already set are left alone."""
    from . import cache

    wanted = {**(_ONE_THREAD if one_thread else {}), **cache.environment()}
    return {k: v for k, v in wanted.items() if k not in os.environ}


def configure_process(one_thread=True) -> bool:
    """Apply :func:`process_environment` to this process if NumPy and JAX are not imported yet
    (the command line does this first); returns whether it did."""
    import sys

    global _CONFIGURED

    if "numpy" in sys.modules or "jax" in sys.modules:
        return False
    os.environ.update(process_environment(one_thread))
    _CONFIGURED = True
    return True


_CONFIGURED = False  # configure_process ran before NumPy was imported


def runs_like_a_worker() -> bool:
    """Whether this process computes as its worker processes do: :func:`configure_process` set it
    up before NumPy was imported (as the command line does), with the workers' one BLAS thread."""
    return _CONFIGURED and all(os.environ.get(name) == value for name, value in _ONE_THREAD.items())


_HEAD_POLL_S = 0.01  # how often wait() looks at the head start's thread


class _Thread:
    """Tasks run one after another in one daemon thread of this process: a one-thread
    ``concurrent.futures.ThreadPoolExecutor`` (``submit(fn, *args) -> Future``, ``shutdown(wait,
    cancel_futures)``) whose thread the interpreter does not wait for at exit.

    A KeyboardInterrupt that lands in the caller's thread inside one of a future's methods, after
    ``Condition.__enter__`` took the future's lock and before the ``with`` block that releases it,
    leaves that lock held for good (CPython checks for signals there). The thread, setting the
    task's result, then waits for ever; ``concurrent.futures`` joins its own threads at
    interpreter exit, so a script that called :func:`jaxpose.batch.batch.run_batch` and was
    interrupted never ended. This thread is a daemon: the interpreter ends without it.
    """

    def __init__(self, name):
        self._tasks = queue.SimpleQueue()
        self._closed = False
        self._thread = threading.Thread(target=self._work, name=name, daemon=True)
        self._thread.start()

    def submit(self, fn, *args) -> cf.Future:
        if self._closed:
            raise RuntimeError("cannot submit a task after shutdown")
        future = cf.Future()
        self._tasks.put((future, fn, args))
        return future

    def _work(self):
        while (task := self._tasks.get()) is not None:
            future, fn, args = task
            task = None
            if not future.set_running_or_notify_cancel():  # cancelled while queued
                continue
            try:
                value = fn(*args)
            except BaseException as exc:  # as ThreadPoolExecutor: the task's error is its result
                future.set_exception(exc)
            else:
                future.set_result(value)
            future = value = None

    def shutdown(self, wait=True, cancel_futures=False):
        """No more tasks: with `cancel_futures` the queued ones are cancelled; with `wait`, the
        thread is joined once it has run the rest."""
        self._closed = True
        if cancel_futures:
            while True:
                try:
                    task = self._tasks.get_nowait()
                except queue.Empty:
                    break
                task[0].cancel()
        self._tasks.put(None)
        if wait:
            self._thread.join()


class LocalExecutor:
    """``workers`` == 1 without a time limit: a (daemon) thread of this process; else worker processes
    (:class:`jaxpose.batch.pool.ProcessPool`: fresh interpreters, each stopped on its own when its task
    runs past `timeout` or it dies, the others going on).

    With `head_start` (worker processes, no time limit) the first task runs in a thread of this
    process, which has its modules imported already, while the worker processes start (each
    imports NumPy and SciPy first): the first result comes that much sooner. Give it only
    for a task that cannot block (a regular file, not a FIFO) in a process that
    :func:`runs_like_a_worker`.

    Worker processes get :func:`process_environment` (one BLAS thread, the compilation cache);
    each new one runs `warm_up` first, outside the time limit but within `start_timeout`
    (:class:`jaxpose.batch.pool.ProcessPool`). With `fork` (a process that
    :func:`runs_like_a_worker`) the first workers are forked from this one when that is safe
    (:class:`~jaxpose.batch.pool.ProcessPool`), after `warm_up` ran here.
    """

    def __init__(self, workers, timeout=None, head_start=False, warm_up=None, start_timeout=None, fork=False):
        self.workers = workers
        self.timeout = timeout
        self._head = None
        if workers == 1 and timeout is None:
            self._pool = _Thread("jaxpose-worker")
        else:
            self._pool = ProcessPool(workers, environment=process_environment(), timeout=timeout, warm_up=warm_up,
                                     start_timeout=start_timeout, fork=fork)
            if head_start and timeout is None:
                self._head = _Thread("jaxpose-head-start")

    def submit(self, fn, *args):
        if self._head is not None and not hasattr(self, "_head_future"):
            self._head_future = self._head.submit(fn, *args)
            return self._head_future
        return self._pool.submit(fn, *args)

    def wait(self, pending):
        if isinstance(self._pool, ProcessPool):
            head = getattr(self, "_head_future", None)
            waiting_for_head = head is not None and head in pending and not head.done()
            return self._pool.wait(pending, timeout=_HEAD_POLL_S if waiting_for_head else POLL_S)
        return cf.wait(pending, timeout=POLL_S, return_when=cf.FIRST_COMPLETED)[0]

    def result(self, future):
        """The task's value; WorkerLost / TaskTimeout when its worker died or ran past the limit."""
        if isinstance(self._pool, ProcessPool) and not isinstance(future, cf.Future):
            return self._pool.result(future)
        return future.result()

    def close(self, kill=False):
        """Stop; with `kill`, drop queued tasks and kill running worker processes at once.

        A thread (the one of ``workers`` == 1, the head start's) cannot be killed: with `kill` it is
        not waited for either, but finishes its task on its own, a daemon thread that does not
        hold up the interpreter's exit. It only computes (the caller writes every output), and a
        signal that interrupts the caller inside one of its future's methods can leave that
        future's lock held here, so that the thread, setting its result, waits for ever (a Ctrl-C
        seen to hang a run this way; :class:`_Thread`). Without `kill` it is joined."""
        if isinstance(self._pool, ProcessPool):
            self._pool.close(kill=kill)
            if self._head is not None:
                self._head.shutdown(wait=not kill, cancel_futures=kill)
        else:
            self._pool.shutdown(wait=not kill, cancel_futures=kill)


# A local cluster for this work: no MALLOC_TRIM_THRESHOLD_ (Dask's default of 64 KiB turns every large
# NumPy array into an mmap and page faults: +50 % CPU on the voxel solids), no stack profiler (it
# samples every worker thread every 10 ms).
_DASK_LOCAL = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
               "distributed.worker.profile.enabled": False}


def local_cluster(workers):
    """A new dask.distributed ``LocalCluster`` of `workers` single-threaded worker processes, set
    up for this work: the workers' environment of :func:`process_environment`, no dashboard (its
    scheduler's HTTP server on a free port, so that several can run at once), and
    neither Dask's ``MALLOC_TRIM_THRESHOLD_`` nor its stack profiler. Close it when done (it is a
    context manager). ``--dask-local N`` runs on one of these; start one yourself to keep its
    workers warm across runs and pass its ``scheduler_address`` as ``--scheduler``.

    Raises:
      InvalidInputError: dask.distributed is not installed.
      JaxposeError: the cluster could not start.

    Example (a script: the cluster's worker processes start by importing the script's
    ``__main__`` again, so the cluster starts under the guard, as with ``multiprocessing``)::

        from jaxpose import normalize_files
        from jaxpose.batch.workers import local_cluster

        if __name__ == "__main__":
            with local_cluster(2) as cluster:
                normalize_files(["meshes/"], "out/", scheduler=cluster.scheduler_address)
    """
    distributed = _distributed()
    import dask

    cluster = None
    try:
        with _sigint_blocked():  # (a Ctrl-C meanwhile is held, and raised as the block ends)
            try:
                with dask.config.set(_DASK_LOCAL):
                    cluster = distributed.LocalCluster(
                        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                        scheduler_kwargs={"dashboard_address": ":0"},  # its metrics server: any free port
                        silence_logs=logging.ERROR, env=process_environment())
            except Exception as exc:  # distributed's own errors (RuntimeError, ...)
                raise JaxposeError(f"could not start a local Dask cluster of {workers} workers: {exc}") from None
        return cluster
    except BaseException:  # a Ctrl-C held while it started: the cluster is closed, not left running
        if cluster is not None:
            cluster.close()
        raise


@contextlib.contextmanager
def _sigint_blocked():
    """SIGINT blocked in this thread for the block (where the platform can: POSIX), and so in the
    threads and processes started inside it: a LocalCluster's event-loop thread, and the worker
    processes it starts from there, now and when it replaces one (the mask is inherited by threads,
    forks and ``exec``). A terminal's Ctrl-C reaches its whole foreground process group: Dask's
    worker processes died of it, each printing KeyboardInterrupt tracebacks (dozens of lines), while
    the command stopped them anyway. A SIGINT that comes inside the block is delivered as it ends."""
    import signal

    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    from multiprocessing import resource_tracker

    # its first start unblocks SIGINT in the thread that starts it (the event loop's, where the
    # workers are started from): started here first, it is not started again
    resource_tracker.ensure_running()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _distributed():
    """The ``distributed`` package, or a clear error naming the extra that installs it."""
    try:
        import distributed
    except ImportError:
        raise InvalidInputError("Dask runs need dask.distributed: pip install 'jaxpose[dask]'") from None
    return distributed


def check_scheduler(address):
    """A dask.distributed scheduler address as Dask reads it (a known scheme, a host and a port in
    [1, 65535] where the scheme takes them), before any work; returns it.

    Raises:
      UsageError: what Dask's Client would refuse (its raw ValueError: "invalid literal for int()
        with base 10: '8786x'", "unknown address scheme 'http'", "missing port number"), and a
        port beyond 65535 (which it would try to reach until its connect timeout).
    """
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    from ..errors import UsageError

    try:
        scheme, location = parse_address(address)
        get_backend(scheme)
        if scheme in ("tcp", "tls", "ws", "wss"):
            port = parse_host_port(location)[1]
            if not 0 < int(port) < 65536:
                raise ValueError(f"port {port} is not in [1, 65535]")
    except ValueError as exc:
        raise UsageError(f"scheduler (--scheduler) {address!r} is not a Dask scheduler address: "
                         f"{' '.join(str(exc).split())}; give one such as 'tcp://host:8786'") from None
    return address


CLOSE_S = 10
"""Seconds a Dask executor waits for its client and its local cluster to close (a worker blocked
opening a FIFO takes about 4)."""


class DaskExecutor:
    """Tasks on a dask.distributed cluster: a running one (`scheduler` address) or a new
    ``LocalCluster`` of `local` single-threaded worker processes (closed with the executor).

    A running cluster's workers keep their own configuration; Dask's default
    ``MALLOC_TRIM_THRESHOLD_`` costs this workload about half again its CPU time (page faults), so
    start them without it (``distributed.nanny.pre-spawn-environ``) where you can.

    A `scheduler` not reached within Dask's ``distributed.comm.timeouts.connect`` (30 s by
    default; ``dask.config.set`` or ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=5s``) is an error.

    Raises:
      InvalidInputError: dask.distributed is not installed, or the scheduler cannot be reached.
    """

    def __init__(self, scheduler=None, local=None):
        Client = _distributed().Client

        self.cluster = None
        if scheduler is not None:
            try:  # within Dask's own distributed.comm.timeouts.connect (its default: 30 s)
                self.client = Client(scheduler)
            except (OSError, TimeoutError) as exc:
                raise InvalidInputError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from None
        else:
            self.cluster = local_cluster(local)
            try:
                self.client = Client(self.cluster)
            except BaseException:  # (a Ctrl-C too): the cluster is not left running
                self.cluster.close()
                raise
        threads = sum(w.get("nthreads", 1) for w in self.client.scheduler_info()["workers"].values())
        self.workers = max(1, threads)

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False, retries=1)

    def wait(self, pending):
        import asyncio

        from distributed import wait

        try:
            return wait(list(pending), timeout=POLL_S, return_when="FIRST_COMPLETED").done
        except (TimeoutError, asyncio.TimeoutError):
            return set()

    def result(self, future):
        try:
            return future.result()
        except Exception as exc:  # KilledWorker and the like (a task's own errors are its result)
            raise WorkerLost(f"the Dask task failed: {' '.join(str(exc).split()) or type(exc).__name__}") from None
        finally:
            future.release()

    def close(self, kill=False):
        """The client closed, and the cluster this executor started, each within ``CLOSE_S``
        seconds: a second close after one a Ctrl-C interrupted half-way (the run's clean-up) waited
        on the first's shutdown forever. Past the limit it goes on (its processes end with this one)."""
        import asyncio

        for part in (self.client, self.cluster):  # each on its own (a client past the limit: the cluster still closed)
            if part is not None:
                try:
                    part.close(timeout=CLOSE_S)
                except (TimeoutError, asyncio.TimeoutError):
                    pass
