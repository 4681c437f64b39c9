"""Ctrl-C at random moments of command-line runs (``python -m benchmarks.interrupts``).

Each trial starts ``jaxpose normalize`` in its own process group, waits a uniformly random time
within the duration of an uninterrupted run, then sends SIGINT to the whole group (what a
terminal's Ctrl-C does; SIGTERM with ``--signal TERM``). A trial passes when the exit code is
130 (143), stderr ends with one ``jaxpose: error:`` line (other lines only ``jaxpose: failed:``
reports of bad inputs) and holds no traceback, no temporary file is left, and every output file
present is complete (it loads and equals its input under the transform recorded for it). A run
that ended before the signal (or was exiting: exit 0, nothing on stderr) is not a trial: it is
repeated with another moment. A signal in the first milliseconds, while Python itself starts and
before jaxpose has run a line, ends the process by the signal itself (exit -2 / -15 here, which a
shell reports as 130 / 143), with nothing written: such a trial is reported as it is.

Modes: ``one`` (a 60k-vertex KIDS mesh, ``-o out.ply``, the single-file form) and ``many`` (the 20
FAUST meshes, ``-o OUTDIR --workers 2``).
"""
from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def command(mode, out):
    base = [sys.executable, "-m", "jaxpose", "normalize"]
    if mode == "one":
        return base + [str(DATA / "kids-dev" / "kid_0001" / "pose_00.ply"), "-o", str(out / "out.ply")]
    return base + [str(DATA / "faust-dev"), "-o", str(out / "normalized"), "--workers", "2"]


def check(out, code, expected, err):
    """Problems found after one trial (an empty list when it passed)."""
    from jaxpose import mesh
    from jaxpose.io.atomic import is_temporary
    from jaxpose.batch.transforms import Transform

    problems = []
    if code != expected:
        problems.append(f"exit {code}")
    lines = err.strip().splitlines()
    if not lines or not lines[-1].startswith("jaxpose: error:") or "Traceback" in err or \
            not all(line.startswith("jaxpose: failed: ") for line in lines[:-1]):
        problems.append(f"stderr: {err.strip()[-300:]!r}")
    files = [p for p in out.rglob("*") if p.is_file()]
    problems += [f"temporary {p}" for p in files if is_temporary(p.name)]
    journal = out / "normalized" / ".jaxpose" / "journal.jsonl"
    if journal.exists():
        records = {}
        for line in journal.read_text().splitlines():
            record = json.loads(line)
            if record["status"] == "ok":
                records[record["output"]] = record
        for path in files:
            if path.suffix == ".ply":
                row = Transform.from_record(records[str(path)]) if str(path) in records else None
                if row is None:
                    problems.append(f"unrecorded {path}")
                    continue
                expected_vertices = row.apply(mesh.load(row.input).vertices).astype(np.float32)
                if not np.array_equal(mesh.load(path).vertices.astype(np.float32), expected_vertices):
                    problems.append(f"partial or wrong {path}")
    elif (out / "out.ply").exists():  # one file: written only at the end, whole (it must load)
        if len(mesh.load(out / "out.ply").vertices) == 0:
            problems.append("empty out.ply")
    return problems


def run(mode="one", trials=20, seed=0, sig="INT"):
    number = signal.SIGINT if sig == "INT" else signal.SIGTERM
    expected = 128 + int(number)
    rng = random.Random(seed)
    work = Path(tempfile.mkdtemp(prefix="jaxpose-interrupts-"))
    try:
        start = time.perf_counter()
        subprocess.run(command(mode, work), capture_output=True, check=False)
        duration = time.perf_counter() - start
        results, late = [], 0
        while len(results) < trials:
            out = work / f"t{len(results)}"
            out.mkdir()
            delay = rng.uniform(0.0, duration)
            process = subprocess.Popen(command(mode, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                       text=True, start_new_session=True)
            time.sleep(delay)
            if process.poll() is not None:  # finished first: not a trial
                late += 1
                process.communicate()
                shutil.rmtree(out)
                continue
            os.killpg(process.pid, number)
            _, err = process.communicate(timeout=120)
            if process.returncode == 0 and not err.strip():  # it had ended, or was exiting: not a trial
                late += 1
                shutil.rmtree(out)
                continue
            problems = check(out, process.returncode, expected, err)
            results.append({"delay_s": round(delay, 3), "exit": process.returncode, "problems": problems})
            shutil.rmtree(out)
        return {"mode": mode, "signal": sig, "trials": trials, "run_s": duration, "finished_first": late,
                "passed": sum(not r["problems"] for r in results), "results": results}
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mode", choices=("one", "many"), default="one")
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--signal", choices=("INT", "TERM"), default="INT")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    result = run(args.mode, args.trials, args.seed, args.signal)
    for r in result["results"]:
        print(f"delay {r['delay_s']:6.3f} s  exit {r['exit']}  {'ok' if not r['problems'] else r['problems']}")
    print(f"{result['mode']}: {result['passed']} of {result['trials']} trials passed (SIG{result['signal']}, "
          f"uninterrupted run {result['run_s']:.2f} s, {result['finished_first']} runs finished before the signal)")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return 0 if result["passed"] == result["trials"] else 1


if __name__ == "__main__":
    sys.exit(main())
