"""Worker processes forked from the caller (ProcessPool(fork=True), the command line's workers):
they answer like fresh ones, are replaced by fresh interpreters, and keep nothing of the caller's
exit handlers, signal handlers or open files. Run in a fresh interpreter (this one has JAX and threads)."""
from __future__ import annotations

import os
import subprocess
import sys

from conftest import ROOT

SCRIPT = r'''
import atexit, os, signal, sys, time
from jaxpose.batch.pool import ProcessPool, WorkerLost

marker, handled = sys.argv[1], sys.argv[2]
atexit.register(lambda: open(marker, "a").write(f"{os.getpid()}\n"))
signal.signal(signal.SIGTERM, lambda *_: open(handled, "a").write(f"{os.getpid()}\n"))

def run(pool, fn, *args):
    future = pool.submit(fn, *args)
    deadline = time.monotonic() + 120
    while not pool.wait({future}):
        assert time.monotonic() < deadline
    return pool.result(future)

held = open(marker + ".held", "w")  # a file of the caller's (as the run's lock and journal are)
pool = ProcessPool(2, fork=True)
assert pool.forked == 2, pool.forked
futures = [pool.submit(os.getpid) for _ in range(6)]
done = set()
while len(done) < 6:
    done |= pool.wait(set(futures) - done)
pids = {pool.result(f) for f in futures}
assert pids == set(pool.pids) and os.getpid() not in pids and len(pids) == 2, (pids, pool.pids)
if sys.platform.startswith("linux"):  # each worker holds stdin (null), stdout, stderr and its two pipes
    for pid in pids:
        links = [os.readlink(f"/proc/{pid}/fd/{fd}") for fd in os.listdir(f"/proc/{pid}/fd")]
        assert len(links) == 5 and links.count(os.devnull) == 1, links
        assert sum(link.startswith("pipe:") for link in links) >= 2 and not any(l.endswith(".held") for l in links), links
assert run(pool, divmod, 7, 2) == (3, 1)
try:
    run(pool, int, "x")
except ValueError:
    pass
else:
    raise AssertionError("a task's own error is its result")
victim = pool.pids[0]
os.kill(victim, signal.SIGTERM)  # the caller's SIGTERM handler is not the worker's: it dies of it
time.sleep(1.0)
futures = [pool.submit(divmod, i, 2) for i in range(2)]  # both workers are needed: the dead one is replaced
done = set()
while len(done) < 2:
    done |= pool.wait(set(futures) - done)
assert [pool.result(f) for f in futures] == [(0, 0), (0, 1)]
assert victim not in pool.pids and pool.forked == 1, (victim, pool.pids, pool.forked)
try:
    run(pool, os._exit, 3)
except WorkerLost as exc:
    assert "exit status 3" in str(exc), exc
else:
    raise AssertionError("a dead worker's task is lost")
assert run(pool, abs, -5) == 5  # a fresh worker took the dead one's place
pool.close()
print("ok")
'''


def test_forked_workers(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    marker, handled = tmp_path / "atexit.txt", tmp_path / "sigterm.txt"
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(marker), str(handled)], capture_output=True, text=True,
                         env=env, timeout=300, cwd=tmp_path)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-3000:]
    assert len(marker.read_text().split()) == 1  # the caller's exit handler ran in the caller only
    assert not handled.exists()  # and its SIGTERM handler in no worker
