"""Real subprocesses, real signals: SIGKILL in the middle of a run then a resume, Ctrl-C and
SIGTERM (exit 130 / 143, one line, nothing partial, no temporary left)."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose import mesh
from jaxpose.io.atomic import is_temporary
from jaxpose.batch.journal import OutputFolder
from jaxpose.batch.transforms import Transform

ROOT = Path(__file__).resolve().parents[1]
TIMING = ("seconds", "worker", "worker_peak_mb")


def dataset(root, count=16):
    """`count` small meshes in two folders and a corrupt file."""
    rng = np.random.default_rng(1)
    for i in range(count):
        shape = trimesh.creation.capsule(height=1.0 + 0.1 * i, radius=0.4, count=[10, 10]) if i % 2 else \
            trimesh.creation.box(extents=rng.uniform(0.5, 1.5, 3))
        shape.apply_translation(rng.normal(size=3))
        folder = root / ("odd" if i % 2 else "even")
        folder.mkdir(parents=True, exist_ok=True)
        shape.export(folder / f"shape_{i:02d}.ply")
    (root / "even" / "shape_03_corrupt.ply").write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n")
    return root


def start(args):
    args = [*args, "--resolution", "40"]  # about 50 ms a file: quick, yet a run lasts long enough to stop
    return subprocess.Popen([sys.executable, "-m", "jaxpose", "normalize", *map(str, args)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def wait_for_lines(out, count, process, timeout=120):
    journal = out / ".jaxpose" / "journal.jsonl"
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if journal.exists() and journal.read_bytes().count(b"\n") >= count:
            return
        assert process.poll() is None, process.communicate()
        time.sleep(0.01)
    pytest.fail("the run did not get going")


def files_under(folder):
    return [p for p in Path(folder).rglob("*") if p.is_file()]


def assert_outputs_complete(out, scans=None):
    """Every output present is whole: it loads and is its input under the journal's transform.
    With `scans` (after a SIGKILL, which can land between an output's rename and its journal
    line) one output may lack its record: it must then load whole, as many vertices as its input."""
    records = OutputFolder(out).records()
    outputs = [p for p in files_under(out) if p.suffix == ".ply"]
    by_output = {r["output"]: r for r in records.values() if r["status"] == "ok"}
    unrecorded = [p for p in outputs if str(p) not in by_output]
    if scans is not None and len(unrecorded) == 1:
        source = scans / unrecorded[0].relative_to(out)
        assert len(mesh.load(unrecorded[0]).vertices) == len(mesh.load(source).vertices)
        outputs.remove(unrecorded[0])
    for path in outputs:
        assert str(path) in by_output, f"{path} has no record"
        row = Transform.from_record(by_output[str(path)])
        expected = row.apply(mesh.load(row.input).vertices).astype(np.float32)
        np.testing.assert_array_equal(mesh.load(path).vertices.astype(np.float32), expected)
    return records


def stable(rows):
    return [{k: v for k, v in row._asdict().items() if k not in TIMING} for row in rows]


def test_sigkill_mid_run_then_resume(tmp_path):
    scans = dataset(tmp_path / "scans")
    out = tmp_path / "out"
    process = start([scans, "-o", out, "--workers", "1"])
    wait_for_lines(out, 3, process)
    os.killpg(process.pid, signal.SIGKILL)
    process.communicate()
    assert process.returncode == -signal.SIGKILL
    done_before = {k for k, r in assert_outputs_complete(out, scans).items() if r["status"] == "ok"}
    assert 0 < len(done_before) < 16
    resumed = start([scans, "-o", out, "--workers", "1"])  # the same command again
    _, err = resumed.communicate(timeout=120)
    assert resumed.returncode == 1 and "1 of 17 inputs failed" in err  # the corrupt file, again
    assert not [p for p in files_under(out) if is_temporary(p.name)]
    lines = (out / ".jaxpose" / "journal.jsonl").read_text().splitlines()
    assert len([line for line in lines if '"status":"ok"' in line]) == 16  # every good file once
    assert_outputs_complete(out)
    reference = start([scans, "-o", tmp_path / "reference", "--workers", "1"])
    reference.communicate(timeout=120)
    rows = jaxpose.read_transforms(out / "transforms.parquet")
    expected = jaxpose.read_transforms(tmp_path / "reference" / "transforms.parquet")
    assert stable(rows) == [{**r, "output": r["output"].replace("reference", "out")} for r in stable(expected)]


@pytest.mark.parametrize("sig, code, word, workers", [(signal.SIGINT, 130, "interrupted", 2),
                                                      (signal.SIGTERM, 143, "terminated", 1)])
def test_interrupt_mid_run_leaves_nothing_partial(tmp_path, sig, code, word, workers):
    scans = dataset(tmp_path / "scans")
    out = tmp_path / "out"
    process = start([scans, "-o", out, "--workers", workers])
    wait_for_lines(out, 1, process)
    os.killpg(process.pid, sig)  # as a terminal's Ctrl-C: the whole process group
    _, err = process.communicate(timeout=60)
    assert process.returncode == code
    lines = err.strip().splitlines()
    assert lines[-1].startswith(f"jaxpose: error: {word}"), err  # one line, no traceback
    assert all(line.startswith(("jaxpose: failed: ", "jaxpose normalize: [")) for line in lines[:-1]), err
    assert not [p for p in files_under(out) if is_temporary(p.name)]
    records = assert_outputs_complete(out)
    rows = jaxpose.read_transforms(out / "transforms.parquet")  # written on the way out
    assert sorted(r.input for r in rows) == sorted(records)


@pytest.mark.skipif(sys.platform != "linux", reason="a FIFO and process groups")
def test_a_terminals_ctrl_c_on_a_dask_local_run_is_one_line(tmp_path):
    """A terminal's Ctrl-C reaches the whole foreground process group, the --dask-local cluster's
    worker processes too: each died of it, printing KeyboardInterrupt tracebacks (dozens of lines
    on stderr, with "leaked semaphore" warnings) around the command's one line. Now they never see
    it (SIGINT blocked where they are started) and the command stops them. A FIFO that never
    delivers keeps the run going until the signal."""
    pytest.importorskip("distributed")
    scans = dataset(tmp_path / "scans", count=6)
    os.mkfifo(tmp_path / "pipe.ply")
    out = tmp_path / "out"
    process = start([scans, tmp_path / "pipe.ply", "-o", out, "--dask-local", "2"])
    wait_for_lines(out, 7, process, timeout=180)  # the 6 meshes and the corrupt file: only the FIFO is left
    os.killpg(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    lines = err.strip().splitlines()
    assert lines[-1] == "jaxpose: error: interrupted; nothing partial was left", err
    assert all(line.startswith(("jaxpose: failed: ", "jaxpose normalize: [")) for line in lines[:-1]), err
    assert not [p for p in files_under(out) if is_temporary(p.name)]
    assert_outputs_complete(out)


# --------------------------------------------------------------------------- the guard, in this process
def test_guard_turns_signals_into_exceptions_and_restores_handlers():
    from jaxpose.batch.interrupts import SignalGuard, Terminated, check

    before = signal.getsignal(signal.SIGTERM)
    with SignalGuard() as guard:
        with pytest.raises(Terminated):
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)
        assert guard.exit_code == 143
        os.kill(os.getpid(), signal.SIGINT)  # a second signal does not interrupt the cleanup
        with pytest.raises(Terminated):
            check()  # a swallowed interrupt is raised again at the next checkpoint
    assert signal.getsignal(signal.SIGTERM) is before
    check()  # no guard: nothing pending


def test_a_deferred_block_is_not_cut_by_a_signal():
    """An output and its journal line are written in a deferred() block: a signal inside is held
    until the block ends, then raised; an error of the block itself goes first."""
    from jaxpose.batch.interrupts import SignalGuard, Terminated, deferred

    done = []
    with SignalGuard() as guard:
        with pytest.raises(Terminated):
            with deferred():
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.2)  # the handler has run: nothing raised here
                done.append("output")
                with deferred():  # nested: held until the outermost block ends
                    done.append("journal line")
                done.append("rest")
        assert done == ["output", "journal line", "rest"] and guard.exit_code == 143
    with SignalGuard():
        with pytest.raises(ValueError):
            with deferred():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.2)
                raise ValueError("the block's own error")


def test_guard_silences_its_own_swallowed_interrupt(capsys):
    import gc

    from jaxpose.batch.interrupts import SignalGuard

    class Swallower:
        def __del__(self):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.5)  # the handler raises here, inside __del__: Python prints "Exception ignored"

    with SignalGuard() as guard:
        Swallower()
        gc.collect()
        assert guard.received == signal.SIGINT
        with pytest.raises(KeyboardInterrupt):
            guard.check()
    assert "Exception ignored" not in capsys.readouterr().err


# --------------------------------------------------------------------------- a library caller
_HELD_LOCK_SCRIPT = '''
import concurrent.futures as cf, signal, sys, threading, time
# Ctrl-C raises KeyboardInterrupt, as in a script started from a terminal: Python installs this handler
# at start only where SIGINT is not ignored, and a test run started in the background (`pytest ... &`
# from a script, nohup) passes SIGINT ignored to its children; the script then slept through the
# signal and the test timed out after 180 s
signal.signal(signal.SIGINT, signal.default_int_handler)
from jaxpose.batch import workers
workers.configure_process()  # as the command line, before NumPy: a run with workers takes a head start
from jaxpose.batch.batch import run_batch

held = []


def hold(future):
    """What a Ctrl-C can leave: this thread holding a task's future's lock for good (CPython looks
    for signals right after Condition.__enter__ takes it, before the with block that releases it: a
    loop of Future.done() under SIGINT, about one interrupt in three). That moment, made long: the
    lock taken, the signal awaited."""
    held.append(future)
    future._condition.acquire()
    print("holding", flush=True)
    time.sleep(120)


done, wait = cf.Future.done, cf.wait


def held_done(self):  # the head start's future, asked by the worker processes' wait
    if threading.current_thread() is threading.main_thread() and not held and not done(self):
        hold(self)
    return done(self)


def held_wait(fs, *args, **kwargs):  # the futures of the one thread (workers=1), asked by cf.wait
    for future in fs:
        if threading.current_thread() is threading.main_thread() and not held and not done(future):
            hold(future)
    return wait(fs, *args, **kwargs)


cf.Future.done, cf.wait = held_done, held_wait
run_batch([sys.argv[1]], sys.argv[2], workers=int(sys.argv[3]), table=sys.argv[2] + '/transforms.csv', progress=False)
print("finished", flush=True)
'''


@pytest.mark.parametrize("workers", [2, 1])  # the head start's thread; the one thread of workers=1
def test_a_script_interrupted_in_run_batch_ends(tmp_path, workers):
    """A script (not the command line, which leaves by os._exit) that calls run_batch and gets a
    Ctrl-C while its main thread holds the lock of a future a thread of the run will set: the
    thread then waits for that lock for ever. The script must still end (exit by SIGINT, the table
    written on the way out); it hung, in the interpreter's exit joining the head start's thread
    (concurrent.futures joins its threads at exit) or, with one worker, in the run's close."""
    import select

    scans = dataset(tmp_path / "scans", count=4)
    script = tmp_path / "run.py"
    script.write_text(_HELD_LOCK_SCRIPT)
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, str(script), str(scans), str(out), str(workers)], cwd=tmp_path,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                               env=env)
    try:
        ready = select.select([process.stdout], [], [], 300)[0]
        line = process.stdout.readline() if ready else ""
        assert line == "holding\n", (line, process.poll())  # the run's thread had not finished its task yet
        os.killpg(process.pid, signal.SIGINT)  # as a terminal's Ctrl-C
        _, err = process.communicate(timeout=180)  # about a second when it ends (generous: a loaded machine)
    except subprocess.TimeoutExpired:
        pytest.fail("the interrupted script did not end: its thread waits for the future's lock, and the "
                    "interpreter (or the run's close) for its thread")
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
    assert process.returncode == -signal.SIGINT and err.rstrip().endswith("KeyboardInterrupt"), err
    assert (out / "transforms.csv").exists()  # run_batch's finally: the table of what was done
