"""Local worker processes that are stopped one at a time: a task past its time limit, or a worker
killed from outside, costs that task alone while the other workers go on.

Each worker is a fresh Python interpreter started with ``python -c`` (not :mod:`multiprocessing`'s
spawn), so the caller's ``__main__`` is never imported again in it: a plain script without
``if __name__ == "__main__":`` may use the pool. With ``fork=True`` (the command line) the first
workers are instead copies of the caller made before it starts any thread, which saves each one
its interpreter start and imports. A worker runs one task at a time: the function
and its arguments (pickled) arrive on a pipe, the result (or the exception it raised) goes back on
another. The pool keeps the queue: a task is sent when a worker is free, and its clock starts
when the worker reports that it has started it (its "started" message, sent once the task has
been received and unpickled), so a worker still starting up or warming up, or not yet scheduled on
a loaded machine, never counts against a task's limit. Its start-up has a limit of its own
(``start_timeout``, :data:`START_TIMEOUT_S` by default): a worker that has not reported a task
started that long after it was sent (stuck in an import or in its warm-up) is killed, and the task
fails with :class:`WorkerLost` (``started`` False). A worker is in a process group of its own (a terminal's Ctrl-C reaches the parent only,
which stops the workers), and on Linux it dies with the parent, even when that is killed by SIGKILL.

Example::

    >>> pool = ProcessPool(2, timeout=60.0)
    >>> future = pool.submit(abs, -3)
    >>> while not pool.wait({future}): pass
    >>> pool.result(future)
    3
    >>> pool.close()
"""
from __future__ import annotations

import collections
import json
import os
import signal
import subprocess
import sys
import threading
import time
from multiprocessing.connection import Connection, wait as wait_for

__all__ = ["ProcessPool", "WorkerLost", "TaskTimeout", "POLL_S", "START_TIMEOUT_S"]

POLL_S = 0.5  # wait() returns at least this often, so the caller stays responsive to interrupts
START_TIMEOUT_S = 300.0  # seconds a worker may take from a task's sending to its "started" (start-up, warm-up)
_STARTED = "started"  # a worker's message when it begins a task; its result follows

# the worker's first lines: the caller's import path, then this module's loop
_BOOT = ("import sys, json; sys.path[:] = json.loads(sys.argv[1]); "
         "from jaxpose.batch.pool import _serve; _serve(*map(int, sys.argv[2:5]))")


class WorkerLost(Exception):
    """The process running a task died (out of memory, killed from outside, a native crash), or
    was killed because it did not start the task within the start-up limit.

    Attributes:
      started: whether the worker had reported the task started (False: it was lost while starting
        up or warming up, before the task itself ran).
    """

    def __init__(self, message, started=True):
        super().__init__(message)
        self.started = started


class TaskTimeout(Exception):
    """A task ran past the pool's time limit; its worker was killed (and is replaced)."""


class _Future:
    """A task's outcome: ``done()``, then ``value`` or ``error``."""

    __slots__ = ("value", "error", "finished")

    def __init__(self):
        self.value = self.error = None
        self.finished = False

    def done(self) -> bool:
        return self.finished

    def _set(self, value=None, error=None):
        self.value, self.error, self.finished = value, error, True


class _Forked:
    """A worker forked from this process, with the part of ``subprocess.Popen``'s interface the pool
    uses (``pid``, ``poll``, ``wait``, ``kill``; a return code -N for a process killed by signal N)."""

    def __init__(self, pid):
        self.pid = pid
        self.returncode = None

    def poll(self):
        if self.returncode is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout=None):
        if timeout is None:
            if self.returncode is None:
                self.returncode = os.waitstatus_to_exitcode(os.waitpid(self.pid, 0)[1])
            return self.returncode
        deadline = time.monotonic() + timeout
        while self.poll() is None:
            if time.monotonic() >= deadline:
                raise subprocess.TimeoutExpired(f"worker {self.pid}", timeout)
            time.sleep(0.01)
        return self.returncode

    def kill(self):
        if self.poll() is None:
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


class _Worker:
    """One worker process and its two pipes (tasks in, results out): a fresh interpreter, or with
    `fork` a copy of this process holding no file of it but its own pipe ends."""

    def __init__(self, environment, fork=False):
        task_read, task_write = os.pipe()
        result_read, result_write = os.pipe()
        try:
            if fork:
                parent = os.getpid()
                sys.stdout.flush()  # nothing buffered here is written twice
                sys.stderr.flush()
                pid = os.fork()
                if pid == 0:  # the worker; it never returns from here
                    _forked_worker(task_read, result_write, parent, environment)
                self.process = _Forked(pid)
            else:
                self.process = subprocess.Popen(
                    [sys.executable, "-c", _BOOT, json.dumps(sys.path), str(task_read), str(result_write),
                     str(os.getpid())],
                    stdin=subprocess.DEVNULL, pass_fds=(task_read, result_write), env={**os.environ, **environment},
                    process_group=0)
        except BaseException:
            for fd in (task_read, task_write, result_read, result_write):
                os.close(fd)
            raise
        os.close(task_read)  # the worker's ends: with them closed here, a dead worker reads as EOF
        os.close(result_write)
        self.tasks = Connection(task_write, readable=False)
        self.results = Connection(result_read, writable=False)

    @property
    def pid(self):
        return self.process.pid

    def death(self) -> str:
        """How the process ended, in words (it is waited for)."""
        try:
            code = self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            return "it stopped answering"
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            return f"killed by {name}"
        return f"exit status {code}"

    def kill(self):
        """Kill the process (if alive), wait for it and close the pipes."""
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        self.tasks.close()
        self.results.close()


class ProcessPool:
    """`workers` worker processes, started as needed; tasks are queued here and run one per worker.

    Args:
      workers: how many processes at most.
      environment: variables set in the workers' environment (on top of this process's).
      timeout: seconds a task may run in its worker (from the worker's message that it has started
        it, not from when it was sent); past it the worker is killed and the task's ``result`` raises :class:`TaskTimeout`. None: no limit.
      warm_up: a function (picklable by reference: a module-level function or a functools.partial of
        one) each new worker runs before its first task, outside
        the time limit: the imports every task needs, so that a worker's start-up is not counted
        against its first task.
      start_timeout: seconds from a task's sending to its worker's "started" message (the
        interpreter's start, its imports, the warm-up); past it the worker is killed and the task's
        ``result`` raises :class:`WorkerLost` with ``started`` False. None: :data:`START_TIMEOUT_S`.
      fork: start the workers at once as copies of this process (``os.fork``: no interpreter
        start-up, no imports in them; `warm_up` runs here first), when that is safe: this process
        runs no other thread and has not imported JAX (whose runtime threads a fork would not
        copy). Otherwise, and for every worker started later (one replacing a lost worker), a
        fresh interpreter. Give it only where this process computes as a fresh worker would (the
        same environment before NumPy was imported: :func:`jaxpose.batch.workers.runs_like_a_worker`).

    A worker that dies makes its task's ``result`` raise :class:`WorkerLost`; the other tasks are
    not affected, and a new worker takes its place for the next task.
    """

    def __init__(self, workers, environment=None, timeout=None, warm_up=None, start_timeout=None, fork=False):
        self.workers = int(workers)
        self.timeout = timeout
        self.start_timeout = START_TIMEOUT_S if start_timeout is None else float(start_timeout)
        self.warm_up = warm_up
        self._environment = dict(environment or {})
        self._idle = []
        self._busy = {}  # worker -> (future, monotonic start: None until it reports, messages to skip, sent at)
        self._queue = collections.deque()  # (future, fn, args) not yet sent
        if fork and threading.active_count() == 1 and "jax" not in sys.modules:
            if self.warm_up is not None:
                self.warm_up()
            if "jax" not in sys.modules:  # a warm-up may import it
                for _ in range(self.workers):
                    self._idle.append(_Worker(self._environment, fork=True))

    @property
    def forked(self) -> int:
        """How many of the live workers were forked from this process."""
        return sum(isinstance(w.process, _Forked) for w in [*self._busy, *self._idle])

    def submit(self, fn, *args) -> _Future:
        """Queue ``fn(*args)`` (picklable, importable by name in a fresh interpreter)."""
        future = _Future()
        self._queue.append((future, fn, args))
        self._dispatch()
        return future

    def _dispatch(self):
        while self._queue and (self._idle or len(self._busy) < self.workers):
            fresh = not self._idle
            worker = _Worker(self._environment) if fresh else self._idle.pop()
            warm = fresh and self.warm_up is not None
            future, fn, args = self._queue.popleft()
            try:
                if warm:  # it runs first; the task's clock starts when its reply comes
                    worker.tasks.send((self.warm_up, ()))
                worker.tasks.send((fn, args))
            except (OSError, EOFError):  # it died while idle: this task never started
                worker.kill()
                self._queue.appendleft((future, fn, args))
                continue
            # a warm-up's two messages (started, its reply) are skipped; the task's "started" starts its clock
            self._busy[worker] = (future, None, 2 if warm else 0, time.monotonic())

    def wait(self, pending, timeout=POLL_S) -> set:
        """Wait up to `timeout` seconds for results; returns the finished futures among `pending`
        (any object with ``done()``).

        Also enforces the time limit and the start-up limit (a worker past either is killed) and
        sends queued tasks to free workers.
        """
        if self._busy:
            delay = min(timeout, max(0.0, min(self._deadline(*entry) for entry in self._busy.values())
                                     - time.monotonic()))
            by_pipe = {worker.results: worker for worker in self._busy}
            for pipe in wait_for(list(by_pipe), timeout=delay):
                self._collect(by_pipe[pipe])
            now = time.monotonic()
            for worker, (future, start, skip, sent) in list(self._busy.items()):
                if now < self._deadline(future, start, skip, sent):
                    continue
                del self._busy[worker]
                worker.kill()
                if start is None:
                    future._set(error=WorkerLost(
                        f"its worker process (pid {worker.pid}) had not started it {self.start_timeout:g} s after it "
                        "was sent (stuck starting up: an import or its warm-up?) and was killed", started=False))
                else:
                    future._set(error=TaskTimeout(
                        f"stopped after the time limit of {self.timeout:g} s (its worker, pid {worker.pid}, "
                        "was killed)"))
            self._dispatch()
        else:
            time.sleep(0 if any(f.done() for f in pending) else min(timeout, 0.05))
        return {future for future in pending if future.done()}

    def _deadline(self, future, start, skip, sent):
        """When a busy worker is stopped: the time limit from "started", the start-up limit before."""
        if start is None:
            return sent + self.start_timeout
        return float("inf") if self.timeout is None else start + self.timeout

    def _collect(self, worker):
        """Read the worker's messages that have arrived, up to its task's result."""
        while True:
            future, start, skip, sent = self._busy.pop(worker)
            try:
                message = worker.results.recv()
            except (EOFError, OSError):  # the process died; a half-sent result reads as EOF too
                how = worker.death()
                worker.kill()
                when = "while working on it" if start is not None else "before it started it"
                future._set(error=WorkerLost(f"its worker process (pid {worker.pid}) died {when}: "
                                             f"{how} (out of memory, or killed from outside?)", started=start is not None))
                return
            if skip:  # the warm-up's (an error in it shows again in the task)
                self._busy[worker] = (future, start, skip - 1, sent)
            elif message == _STARTED:  # the worker has the task and begins it: its clock starts now
                self._busy[worker] = (future, time.monotonic(), 0, sent)
            else:
                break
            if not worker.results.poll():
                return
        ok, value = message
        future._set(value=value) if ok else future._set(error=value)
        self._idle.append(worker)

    def result(self, future):
        """The task's return value; raises what it raised, or WorkerLost / TaskTimeout."""
        if not future.done():
            raise RuntimeError("result() of a task that has not finished")
        if future.error is not None:
            raise future.error
        return future.value

    @property
    def pids(self) -> list:
        """The process ids of the live workers (busy ones first)."""
        return [w.pid for w in [*self._busy, *self._idle]]

    def close(self, kill=False):
        """Stop every worker: at once with `kill` (queued and running tasks are dropped), else when
        their tasks are done (the caller has waited for them)."""
        self._queue.clear()
        workers = [*self._busy, *self._idle]
        self._busy, self._idle = {}, []
        if kill:
            for worker in workers:
                worker.kill()
            return
        for worker in workers:  # end of the task pipe: the worker's loop ends
            worker.tasks.close()
        for worker in workers:
            try:
                worker.process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                pass
            worker.kill()


# --------------------------------------------------------------------------- in the worker
def _forked_worker(task_fd, result_fd, parent, environment):
    """The worker's side of a fork: a process of its own group, the signal handlers and mask of a
    fresh interpreter, no stdin, no file of the parent's but stdout, stderr and its own two pipe ends
    (not the pool's pipes to other workers, not the run's lock or journal); then :func:`_serve`, and
    ``os._exit`` (the parent's ``atexit`` handlers and buffered files are never run or flushed here)."""
    code = 1
    try:
        low, high = sorted((task_fd, result_fd))
        os.closerange(3, low)
        os.closerange(low + 1, high)
        os.closerange(high + 1, os.sysconf("SC_OPEN_MAX"))
        os.setpgid(0, 0)
        for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGPIPE):
            signal.signal(number, signal.default_int_handler if number == signal.SIGINT else
                          signal.SIG_IGN if number == signal.SIGPIPE else signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_SETMASK, set())
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        os.close(null)
        os.environ.update(environment)
        _serve(task_fd, result_fd, parent)
        code = 0
    finally:
        os._exit(code)


def _serve(task_fd, result_fd, parent):
    """The worker's loop: receive (fn, args), send "started", then (True, value) or (False, exception)."""
    _die_with_parent(parent)
    tasks = Connection(task_fd, writable=False)
    results = Connection(result_fd, readable=False)
    while True:
        try:
            fn, args = tasks.recv()
        except EOFError:  # the pool closed this worker, or the parent is gone
            return
        results.send(_STARTED)
        try:
            reply = (True, fn(*args))
        except BaseException as exc:  # the task's own error is its result
            reply = (False, exc)
        try:
            results.send(reply)
        except Exception as exc:  # an exception or result that does not pickle
            results.send((False, RuntimeError(f"{type(exc).__name__}: {exc} (sending {type(reply[1]).__name__})")))


def _die_with_parent(parent):
    """On Linux, SIGKILL this process when the parent dies (prctl PR_SET_PDEATHSIG)."""
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # 1: PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before the line above
        os._exit(0)
