"""Worker processes and a real dask.distributed LocalCluster give the same table and files."""
import filecmp
import os

import pytest

import jaxpose
from jaxpose import batch, cli
from jaxpose.task import NormalizeOptions
from jaxpose._validate import InvalidInputError
from jaxpose.workers import DaskExecutor, LocalExecutor, WorkerLost, local_cluster

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
    assert code == 1 and "workers (--workers) is for local runs" in capsys.readouterr().err


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


def test_killing_the_workers_returns_with_a_partial_result_in_the_pipe():
    """Ctrl-C kills the worker processes wherever they are, possibly in the middle of sending a
    result: the pool's manager thread then waits for the rest of that message. close(kill=True)
    must still return (it once hung forever in shutdown)."""
    import struct
    import threading
    import time

    executor = LocalExecutor(2)
    futures = [executor.submit(time.sleep, 30) for _ in range(2)]
    deadline = time.monotonic() + 60
    while len(getattr(executor._pool, "_processes", None) or {}) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    writer = executor._pool._result_queue._writer  # as a worker killed mid-send leaves it:
    os.write(writer.fileno(), struct.pack("!i", 1 << 20) + b"part of a result")  # a header, then a cut
    time.sleep(0.5)  # the manager thread reads the header and waits for the rest
    closer = threading.Thread(target=executor.close, kwargs={"kill": True}, daemon=True)
    closer.start()
    closer.join(timeout=60)
    assert not closer.is_alive(), "close(kill=True) hangs"
    assert all(f.done() for f in futures)


def test_a_dead_worker_process_fails_its_input_and_the_run_goes_on(tmp_path):
    executor = LocalExecutor(2)
    try:
        future = executor.submit(_die)
        with pytest.raises(WorkerLost, match="died"):
            executor.result(future)
        executor.restart()
        assert executor.result(executor.submit(abs, -3)) == 3
    finally:
        executor.close(kill=True)


def _die():
    os._exit(9)


def test_worker_environment_one_blas_thread_and_the_compilation_cache(tmp_path, monkeypatch):
    from jaxpose import cache
    from jaxpose.workers import process_environment

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
