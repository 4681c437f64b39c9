"""Ctrl-C and SIGTERM for the command line: end a run at once, cleanly, with 128 + the signal.

Inside :class:`SignalGuard`, SIGINT raises ``KeyboardInterrupt`` and SIGTERM its subclass
:class:`Terminated` in the main thread, so every ``finally`` / ``except BaseException`` cleanup
runs on the way out: temporaries removed (:mod:`jaxpose.io.atomic`), worker processes stopped and the
batch table written (:mod:`jaxpose.batch.batch`). Only the first signal raises; later ones are noted
and do not interrupt the cleanup. A signal can land while Python runs a callback that swallows
exceptions (a garbage-collection callback prints "Exception ignored" and goes on); the guard
remembers it and :func:`check` raises it again at the next checkpoint, before anything is written.
Inside a :func:`deferred` block a signal is held until the block ends.

:func:`leave` ends the process with ``os._exit`` after flushing stdout and stderr: it skips the
interpreter's teardown, where native threads (XLA's) may still be running and crash it.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

__all__ = ["Terminated", "SignalGuard", "check", "deferred", "leave"]

_ACTIVE = []  # the guards in force in this process (a stack; signals are per process)
_DEFERRED = [0]  # depth of the deferred() blocks being run


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that the same cleanup runs."""


class SignalGuard:
    """Turn SIGINT and SIGTERM into exceptions while active (main thread only; a no-op elsewhere).

    Attributes:
      received: the first signal number received, or None.

    Example::

        with SignalGuard() as guard:
            run()                 # KeyboardInterrupt / Terminated on a signal
        guard.exit_code           # 130 after Ctrl-C, 143 after SIGTERM, None without
    """

    def __init__(self):
        self.received = None
        self._old = {}
        self._old_hook = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for number in (signal.SIGINT, signal.SIGTERM):
                self._old[number] = signal.signal(number, self._handle)
            self._old_hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        _ACTIVE.append(self)
        return self

    def __exit__(self, *exc):
        _ACTIVE.remove(self)
        for number, handler in self._old.items():
            signal.signal(number, handler)
        if self._old_hook is not None:
            sys.unraisablehook = self._old_hook
        return False

    def _unraisable(self, unraisable):
        # our own interrupt, swallowed by a callback: it is remembered (check() raises it again),
        # so no "Exception ignored" traceback; anything else goes to the usual hook
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and self.received is not None:
            return
        self._old_hook(unraisable)

    def _handle(self, number, frame):
        if self.received is not None:
            return  # the first one is being handled: let the cleanup finish
        self.received = number
        if not _DEFERRED[0]:  # else raised when the deferred() block ends
            self.check()

    def check(self):
        """Raise the exception of a signal received (again, if it was swallowed)."""
        if self.received == signal.SIGTERM:
            raise Terminated()
        if self.received is not None:
            raise KeyboardInterrupt()

    @property
    def exit_code(self):
        return None if self.received is None else 128 + int(self.received)


def check():
    """At a checkpoint: raise the pending interrupt of the active guard, if any."""
    for guard in _ACTIVE:
        guard.check()


@contextlib.contextmanager
def deferred():
    """A block that a signal does not cut in two: a SIGINT / SIGTERM that arrives inside is held
    and raised when the block ends (unless the block raised). For statements that must happen
    together, such as writing an output and appending its journal line.

    Example::

        with deferred():
            write_atomic(path, data)
            journal.append(record)
    """
    _DEFERRED[0] += 1
    try:
        yield
    finally:
        _DEFERRED[0] -= 1
    if not _DEFERRED[0]:
        check()


def leave(code: int):
    """Flush stdout and stderr, then end the process with `code` at once (``os._exit``).

    SIGINT and SIGTERM are blocked and ignored first: a signal that comes after the run has ended
    changes nothing (the exit code is the run's).

    A garbage collection first runs the finalizers of what the run dropped (multiprocessing's
    semaphores, which otherwise are reported as leaked).
    """
    import gc

    if hasattr(signal, "pthread_sigmask"):  # the run is over: a late signal must not interrupt the exit
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    if threading.current_thread() is threading.main_thread():
        # one delivered just before the mask may still be waiting for its Python handler: with the
        # handlers ignored, Python drops it (it would raise inside the collection below)
        for number in (signal.SIGINT, signal.SIGTERM):
            signal.signal(number, signal.SIG_IGN)
    gc.collect()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # a closed pipe: nothing more can be said
            pass
    os._exit(int(code))
