"""Worker processes and a real dask.distributed LocalCluster give the same table and files."""
import filecmp
import os
import time

import pytest

import jaxpose
from jaxpose.batch import batch
from jaxpose import cli
from jaxpose.batch.task import NormalizeOptions
from jaxpose._validate import InvalidInputError
from jaxpose.batch.workers import DaskExecutor, LocalExecutor, TaskTimeout, WorkerLost, local_cluster

from conftest import write_mesh_tree

distributed = pytest.importorskip("distributed")
FAST = NormalizeOptions(resolution=16)
TIMING = ("seconds", "worker", "worker_peak_mb")


@pytest.fixture(scope="module")
def cluster():
    # Dask's defaults but for ports: pytest-xdist may start this fixture in two processes at once, and
    # the scheduler's HTTP server would warn (an error here) that port 8787 is already in use.
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  scheduler_kwargs={"dashboard_address": ":0"}, silence_logs=50) as local:
        yield local


def stable(rows, root):
    return [{k: (v.replace(str(root), "") if isinstance(v, str) else v) for k, v in row._asdict().items()
             if k not in TIMING} for row in rows]


def test_dask_and_local_processes_give_the_same_results(tmp_path, cluster):
    tree = write_mesh_tree(tmp_path / "scans")
    local = batch.run_batch([tmp_path / "scans"], tmp_path / "local", FAST, workers=2, progress=False)
    dask = batch.run_batch([tmp_path / "scans"], tmp_path / "dask", FAST, scheduler=cluster.scheduler_address,
                           progress=False)
    assert stable(local.rows, tmp_path / "local") == stable(dask.rows, tmp_path / "dask")  # bit for bit
    assert len({r.worker for r in local.rows}) == 2 and len(local.peak_mb) == 2
    pids = {int(r.worker.rpartition(":")[2]) for r in dask.rows}
    assert 1 <= len(pids) <= 2 and os.getpid() not in pids  # the cluster's worker processes did the work
    for path in tree["good"]:
        relative = path.relative_to(tmp_path / "scans")
        assert filecmp.cmp(tmp_path / "local" / relative, tmp_path / "dask" / relative, shallow=False)
    assert (local.failed, dask.failed) == (3, 3)


def test_cli_on_a_dask_scheduler(tmp_path, cluster, capsys):
    write_mesh_tree(tmp_path / "scans")
    out = tmp_path / "out"
    code = cli.main(["normalize", str(tmp_path / "scans" / "a"), "-o", str(out), "--scheduler",
                     cluster.scheduler_address, "--resolution", "16", "--fail-fast", "--glob", "*.ply"])
    assert code == 0, capsys.readouterr().err
    assert [r.ok for r in jaxpose.read_transforms(out / "transforms.parquet")] == [True]
    code = cli.main(["normalize", str(tmp_path / "scans"), "-o", str(out), "--scheduler", "tcp://127.0.0.1:1",
                     "--workers", "2"])
    assert code == 2 and "workers (--workers) is for local runs" in capsys.readouterr().err  # usage


@pytest.mark.parametrize("address, why", [
    ("localhost:8786x", r"invalid literal for int\(\) with base 10: '8786x'"),
    ("tcp://", "missing port number"),
    ("127.0.0.1", "missing port number"),
    ("http://localhost:8786", "unknown address scheme 'http'"),
    ("tcp://localhost:99999", r"port 99999 is not in \[1, 65535\]"),  # Dask tried it until its connect timeout
])
def test_a_scheduler_address_dask_cannot_read_is_a_usage_error(tmp_path, capsys, address, why):
    """Refused before any work, naming --scheduler (exit 2); it was Dask's raw ValueError from
    Client(), exit 1 ('jaxpose: error: ValueError: invalid literal for int() with base 10: ...')."""
    import re

    from jaxpose.errors import UsageError

    write_mesh_tree(tmp_path / "scans")
    message = rf"scheduler \(--scheduler\) '{re.escape(address)}' is not a Dask scheduler address: {why}"
    with pytest.raises(UsageError, match=message):
        jaxpose.normalize_files(tmp_path / "scans", tmp_path / "out", scheduler=address, progress=False)
    assert cli.main(["normalize", str(tmp_path / "scans"), "-o", str(tmp_path / "out"), "--scheduler", address]) == 2
    assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "out").exists()


def test_an_unreachable_scheduler_gives_up_after_dasks_own_connect_timeout(tmp_path):
    """The scheduler's connect timeout is Dask's setting ``distributed.comm.timeouts.connect``
    (default 30 s; here 1 s), not a fixed 30 s: a real address where nothing listens (a port held
    bound, not listening: refused on every try) fails in seconds with the library's error."""
    import re
    import socket

    import dask

    write_mesh_tree(tmp_path / "scans")
    with socket.socket() as closed:
        closed.bind(("127.0.0.1", 0))  # held: nobody else can listen there while the test runs
        address = f"tcp://127.0.0.1:{closed.getsockname()[1]}"
        start = time.monotonic()
        with dask.config.set({"distributed.comm.timeouts.connect": "1s"}), \
                pytest.raises(InvalidInputError, match=f"cannot reach the Dask scheduler {re.escape(address)}: .* after 1 s"):
            jaxpose.normalize_files(tmp_path / "scans", tmp_path / "out", scheduler=address, progress=False)
        assert time.monotonic() - start < 15  # 30 s and more with the timeout fixed at 30 s
    assert not (tmp_path / "out").exists()


def worker_malloc_trim(scheduler_address):
    with distributed.Client(scheduler_address) as client:
        return sorted(client.run(lambda: os.environ.get("MALLOC_TRIM_THRESHOLD_")).values(), key=str)


def test_dask_local_cluster_is_configured_and_gives_the_same_results(tmp_path, cluster):
    assert worker_malloc_trim(cluster.scheduler_address) == ["65536", "65536"]  # Dask's own default
    with local_cluster(1) as own:
        assert worker_malloc_trim(own.scheduler_address) == [os.environ.get("MALLOC_TRIM_THRESHOLD_")]
    write_mesh_tree(tmp_path / "scans")
    new = batch.run_batch([tmp_path / "scans"], tmp_path / "new", FAST, dask_local=1, progress=False)
    running = batch.run_batch([tmp_path / "scans"], tmp_path / "running", FAST,
                              scheduler=cluster.scheduler_address, progress=False)
    assert stable(new.rows, tmp_path / "new") == stable(running.rows, tmp_path / "running")
    assert (new.written, new.failed) == (4, 3)


def test_a_worker_dying_in_the_middle_of_sending_costs_its_task_only():
    """A worker that dies halfway through sending a result (Ctrl-C kills, out of memory) leaves
    part of a message on its pipe: that task is lost (WorkerLost), the next tasks run in a fresh
    worker, and close(kill=True) returns."""
    import threading

    executor = LocalExecutor(2)
    try:
        futures = [executor.submit(_send_half_then_die), executor.submit(abs, -3)]
        done = set()
        deadline = time.monotonic() + 120
        while len(done) < 2 and time.monotonic() < deadline:
            done |= executor.wait(set(futures) - done)
        with pytest.raises(WorkerLost, match="died while working on it: exit status 9"):
            executor.result(futures[0])
        assert executor.result(futures[1]) == 3
        again = executor.submit(abs, -4)
        while not executor.wait({again}):
            pass
        assert executor.result(again) == 4
        sleepers = [executor.submit(time.sleep, 60) for _ in range(2)]
        executor.wait(set(sleepers))
    finally:
        closer = threading.Thread(target=executor.close, kwargs={"kill": True}, daemon=True)
        closer.start()
        closer.join(timeout=60)
    assert not closer.is_alive(), "close(kill=True) hangs"


def _send_half_then_die():
    """In a worker: a message header on the result pipe, part of the body, then death."""
    import struct
    import sys

    result_fd = int(sys.argv[3])  # the worker's command line: path, task pipe, result pipe, parent
    os.write(result_fd, struct.pack("!i", 1 << 20) + b"part of a result")
    os._exit(9)


def test_a_dead_worker_process_fails_its_task_and_the_others_go_on(tmp_path):
    executor = LocalExecutor(2)
    try:
        futures = [executor.submit(_die), executor.submit(time.sleep, 1.0), executor.submit(abs, -3)]
        done = set()
        while len(done) < 3:
            done |= executor.wait(set(futures) - done)
        with pytest.raises(WorkerLost, match="died"):
            executor.result(futures[0])
        assert executor.result(futures[1]) is None and executor.result(futures[2]) == 3
    finally:
        executor.close(kill=True)


def test_a_task_past_the_time_limit_is_stopped_and_its_worker_replaced():
    executor = LocalExecutor(1, timeout=1.0)  # one worker, a process: the limit needs one
    try:
        slow, quick = executor.submit(time.sleep, 60), executor.submit(abs, -5)
        start = time.monotonic()
        while not executor.wait({slow}):
            pass
        assert time.monotonic() - start < 30
        with pytest.raises(TaskTimeout, match="time limit of 1 s"):
            executor.result(slow)
        while not executor.wait({quick}):
            pass
        assert executor.result(quick) == 5  # a fresh worker took it
    finally:
        executor.close(kill=True)


def _die():
    os._exit(9)


def _slow_start():
    time.sleep(3.0)


def test_a_new_workers_warm_up_is_outside_the_time_limit():
    from jaxpose.batch.pool import ProcessPool

    pool = ProcessPool(1, timeout=1.0, warm_up=_slow_start)  # 3 s to start, 1 s a task
    try:
        quick, slow = pool.submit(abs, -2), pool.submit(time.sleep, 30)
        done = set()
        while len(done) < 2:
            done |= pool.wait({quick, slow} - done)
        assert pool.result(quick) == 2  # its worker's start-up was not counted
        with pytest.raises(TaskTimeout):
            pool.result(slow)
    finally:
        pool.close(kill=True)


def test_a_slow_interpreter_start_is_outside_the_time_limit(tmp_path):
    """No warm-up at all: the clock starts at the worker's own "started" message, not when the task
    is sent, so an interpreter that takes 3 s to start (a loaded machine) does not fail a 1 s task."""
    from jaxpose.batch.pool import ProcessPool

    (tmp_path / "sitecustomize.py").write_text("import time\ntime.sleep(3.0)\n")  # runs at interpreter start
    pool = ProcessPool(1, timeout=1.0, environment={"PYTHONPATH": str(tmp_path)})
    try:
        quick, slow = pool.submit(abs, -2), pool.submit(time.sleep, 30)
        done = set()
        while len(done) < 2:
            done |= pool.wait({quick, slow} - done)
        assert pool.result(quick) == 2
        with pytest.raises(TaskTimeout):  # the limit still holds once a task has started
            pool.result(slow)
    finally:
        pool.close(kill=True)


def _hanging_start(folder):
    """A folder whose sitecustomize (imported at every interpreter's start) never returns."""
    (folder / "sitecustomize.py").write_text("import time\ntime.sleep(600)\n")
    return str(folder)


def _alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as handle:
            return handle.read().rpartition(")")[2].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="/proc")
@pytest.mark.parametrize("timeout", [None, 1.0])
def test_a_worker_stuck_in_its_start_up_is_killed_at_the_start_limit(tmp_path, timeout):
    """A worker that hangs before it reports its task started (here in an import at interpreter
    start) is killed once the start-up limit has passed, with or without a task time limit; its
    task fails with WorkerLost(started=False)."""
    from jaxpose.batch.pool import ProcessPool

    pool = ProcessPool(1, timeout=timeout, environment={"PYTHONPATH": _hanging_start(tmp_path)}, start_timeout=3.0)
    try:
        task = pool.submit(abs, -2)
        start = time.monotonic()
        pid = pool.pids[0]
        while not pool.wait({task}):
            assert time.monotonic() - start < 60, "the stuck worker was never stopped"
        waited = time.monotonic() - start
        with pytest.raises(WorkerLost, match=r"had not started it 3 s after it was sent") as lost:
            pool.result(task)
        assert lost.value.started is False
        assert 3.0 <= waited < 30.0
        assert not _alive(pid)  # killed and reaped
    finally:
        pool.close(kill=True)


def test_a_worker_lost_after_starting_its_task_says_so():
    from jaxpose.batch.pool import ProcessPool

    pool = ProcessPool(1, start_timeout=120.0)
    try:
        task = pool.submit(_die)
        while not pool.wait({task}):
            pass
        with pytest.raises(WorkerLost, match="died while working on it") as lost:
            pool.result(task)
        assert lost.value.started is True
    finally:
        pool.close(kill=True)


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="/proc")
def test_a_run_whose_workers_hang_in_start_up_records_each_input_and_ends(tmp_path, monkeypatch):
    """Every worker process hangs in its start-up: each input is recorded failed after three workers
    lost before starting it (not counted as tries), and the run ends."""
    from jaxpose.batch import pool

    import trimesh

    (tmp_path / "scans").mkdir()
    for i in range(2):
        trimesh.creation.box(extents=(1.0 + i, 0.6, 0.4)).export(tmp_path / "scans" / f"box{i}.ply")
    monkeypatch.setattr(pool, "START_TIMEOUT_S", 2.0)
    monkeypatch.setenv("PYTHONPATH", _hanging_start(tmp_path))
    start = time.monotonic()
    result = batch.run_batch([tmp_path / "scans"], tmp_path / "out", FAST, workers=2, progress=False)
    assert time.monotonic() - start < 240
    assert (result.written, result.failed, len(result.rows)) == (0, 2, 2)
    for row in result.rows:
        assert row.error.endswith("never run: 3 workers lost before starting it"), row.error
        assert "had not started it 2 s after it was sent" in row.error


def test_worker_environment_one_blas_thread_and_the_compilation_cache(tmp_path, monkeypatch):
    from jaxpose.batch import cache
    from jaxpose.batch.workers import process_environment

    for name in ("JAX_COMPILATION_CACHE_DIR", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("JAXPOSE_CACHE_DIR", str(tmp_path / "c"))
    env = process_environment()
    assert env["JAX_COMPILATION_CACHE_DIR"] == str(tmp_path / "c") and env["OPENBLAS_NUM_THREADS"] == "1"
    assert "OMP_NUM_THREADS" not in process_environment(one_thread=False)
    monkeypatch.setenv("JAXPOSE_CACHE_DIR", "")  # off
    assert cache.cache_dir() is None and "JAX_COMPILATION_CACHE_DIR" not in process_environment()
    monkeypatch.delenv("JAXPOSE_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if os.name == "posix" and os.uname().sysname == "Linux":
        assert cache.cache_dir() == tmp_path / "xdg" / "jaxpose" / "jax"
    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", "/mine")  # the user's own setting wins
    assert "JAX_COMPILATION_CACHE_DIR" not in process_environment()


def test_without_dask_installed_the_error_names_the_extra(monkeypatch):
    """No dask.distributed: a clear error naming the extra, from the cluster and the executor alike."""
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    for start in (lambda: local_cluster(1), lambda: DaskExecutor(local=1), lambda: DaskExecutor("tcp://x:1")):
        with pytest.raises(InvalidInputError, match=r"pip install 'jaxpose\[dask\]'"):
            start()


def test_a_plain_script_without_a_main_guard_can_use_worker_processes(tmp_path):
    """Worker processes are fresh interpreters that never import the caller's __main__: a script
    calling normalize_files(..., workers=2) at its top level runs once and works."""
    import subprocess
    import sys
    from pathlib import Path

    write_mesh_tree(tmp_path / "scans")
    script = tmp_path / "script.py"
    script.write_text("import jaxpose\n"
                      "print('START', flush=True)\n"
                      "rows = jaxpose.normalize_files('scans', 'out', workers=2, resolution=16, progress=False)\n"
                      "print('ROWS', len(rows), sum(r.ok for r in rows), len({r.worker for r in rows}))\n")
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                          env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["START", "ROWS 7 4 2"]  # the script ran once; two workers did the work
    assert "Error" not in done.stderr and "Traceback" not in done.stderr


def test_head_start_runs_the_first_task_here_and_the_rest_in_workers():
    executor = LocalExecutor(2, head_start=True)
    try:
        futures = [executor.submit(os.getpid) for _ in range(4)]
        done = set()
        while len(done) < 4:
            done |= executor.wait(set(futures) - done)
        pids = [executor.result(f) for f in futures]
    finally:
        executor.close()
    assert pids[0] == os.getpid() and os.getpid() not in pids[1:]
    executor = LocalExecutor(2, timeout=30.0, head_start=True)  # a time limit: no task may run here
    try:
        future = executor.submit(os.getpid)
        while not executor.wait({future}):
            pass
        assert executor.result(future) != os.getpid()
    finally:
        executor.close()


def test_close_with_kill_does_not_wait_for_the_head_start_thread():
    """A Ctrl-C that lands inside one of the head future's methods (done(), the pool's wait) can
    leave that future's lock held by the caller; the head thread, setting its result, then waits
    for it, and a close that joins the thread waits for ever (seen once in a dataset run: its
    main thread in ``ThreadPoolExecutor.shutdown``, the head thread in ``Future.set_result``).
    close(kill=True) must return; a plain close still joins (the caller's lock released first)."""
    import threading

    started = threading.Event()

    def task():
        started.set()
        time.sleep(0.5)
        return os.getpid()

    executor = LocalExecutor(2, head_start=True)
    future = executor.submit(task)
    assert started.wait(30)
    future._condition.acquire()  # the state an interrupt leaves: the caller holds the future's lock
    closer = threading.Thread(target=executor.close, kwargs={"kill": True}, daemon=True)
    closer.start()
    closer.join(20)
    hung = closer.is_alive()
    future._condition.release()  # the head thread now sets its result and ends
    executor._head.shutdown(wait=True)
    assert not hung, "close(kill=True) waited for the head start's thread"
    assert future.result(timeout=30) == os.getpid()


def test_cli_head_start_gives_the_workers_results(tmp_path):
    """`jaxpose normalize DIR --workers 2`: the first file is done by the command's own process (its
    pid in the table) while the workers start, with the same numbers as a run done by workers only
    (OMP_NUM_THREADS other than the workers' 1 turns the head start off)."""
    import subprocess
    import sys

    import trimesh

    (tmp_path / "scans").mkdir()
    for i, suffix in enumerate(["off", "ply", "off", "ply"]):
        shape = trimesh.creation.icosphere(subdivisions=2) if i % 2 else trimesh.creation.box(extents=[1, 2, 3])
        shape.apply_translation([i, 0.5 * i, 0])
        shape.export(tmp_path / "scans" / f"shape{i}.{suffix}")
    tables = {}
    for name, threads in (("head", "1"), ("workers", "2")):
        env = {**os.environ, "OMP_NUM_THREADS": threads}
        process = subprocess.Popen([sys.executable, "-m", "jaxpose", "normalize", str(tmp_path / "scans"), "-o",
                                    str(tmp_path / name), "--workers", "2", "--resolution", "16"], env=env,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        _, err = process.communicate(timeout=300)
        assert process.returncode == 0, err
        rows = jaxpose.read_transforms(tmp_path / name / "transforms.parquet")
        tables[name] = rows
        pids = [int(r.worker.rsplit(":", 1)[1]) for r in rows]
        assert (process.pid in pids) == (name == "head")
    assert stable(tables["head"], tmp_path / "head") == stable(tables["workers"], tmp_path / "workers")


def test_read_ahead_asks_for_regular_files_only(tmp_path):
    """The run asks the kernel to read each input ahead of its worker: regular files only (a FIFO
    is never opened: its writer would see a reader come and go)."""
    import threading

    from jaxpose.batch.batch import read_ahead

    regular = tmp_path / "a.off"
    regular.write_bytes(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    assert read_ahead(regular) == hasattr(os, "posix_fadvise")
    assert read_ahead(tmp_path / "missing.off") is False
    fifo = tmp_path / "f.off"
    os.mkfifo(fifo)
    opened = threading.Event()
    writer = threading.Thread(target=lambda: (os.close(os.open(fifo, os.O_WRONLY)), opened.set()), daemon=True)
    writer.start()
    assert read_ahead(fifo) is False
    writer.join(timeout=1.0)
    assert not opened.is_set()  # no reader came: the writer still waits
    os.close(os.open(fifo, os.O_RDONLY | os.O_NONBLOCK))  # let it go
    writer.join(timeout=5.0)


def test_the_command_line_configures_its_process_before_numpy():
    """`python -m jaxpose normalize` sets the workers' environment (one BLAS thread, the
    compilation cache) before anything imports NumPy: importing the command line imports no NumPy."""
    import subprocess
    import sys

    code = "import sys, jaxpose.cli, jaxpose.__main__; print(sorted({'numpy', 'jax'} & set(sys.modules)))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.stdout.strip() == "[]", done.stdout + done.stderr


def test_a_dask_executor_closes_its_cluster_within_the_limit_even_when_its_client_does_not():
    """A Ctrl-C while a --dask-local run closed its cluster could hang the command for good (the
    clean-up's second close waited on the first's half-done shutdown): each close is bounded by
    workers.CLOSE_S, and a client past it does not keep the cluster from closing (reviewer: one try
    around both skipped the cluster's). Stand-ins for the client and cluster record the calls."""
    from jaxpose.batch import workers

    calls = []

    class Client:
        def close(self, timeout=None):
            calls.append(("client", timeout))
            raise TimeoutError("timed out")

    class Cluster:
        def close(self, timeout=None):
            calls.append(("cluster", timeout))

    executor = DaskExecutor.__new__(DaskExecutor)
    executor.client, executor.cluster = Client(), Cluster()
    executor.close(kill=True)
    assert calls == [("client", workers.CLOSE_S), ("cluster", workers.CLOSE_S)]
