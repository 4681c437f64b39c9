"""Dataset throughput of ``jaxpose normalize INPUT... -o OUTDIR`` (``python -m benchmarks.dataset``).

Whole commands, timed from outside (start to exit, start-up included), in turn so that a drift of
the machine's speed hits each alike, on the same 48 real meshes (20 FAUST + the first 28 KIDS):

trimesh     the loop a user writes without jaxpose: ``trimesh.load`` + ``center_mass`` per file
            (a fresh ``python -c``), the yardstick
local       ``jaxpose normalize MANIFEST -o OUTDIR --workers W`` (a fresh OUTDIR each run)
dask        the same with ``--dask-local W`` (a new local dask.distributed cluster each run, its
            start and stop included; skipped without dask.distributed)
dask_running  the same with ``--scheduler ADDRESS`` on a cluster that is already running (started
            once, before the runs, by ``jaxpose.batch.workers.local_cluster(W)``): how a cluster is used.
            Its workers stay up between runs; their CPU time is not counted (only the client's)
single      one file, ``jaxpose normalize FILE -o OUT`` twice; the second run is the one reported
            (the persistent compilation cache filled; the default estimator compiles nothing)
single_ocsvm  the same with ``--method ocsvm`` and a fresh cache folder: the first run compiles,
            the second loads the compiled program

Printed: median wall seconds, meshes/s and CPU seconds (user + system, the workers included: on a
busy machine the CPU time says more than the wall time) of each, dask/local per pair, the compute-only rate
(files x workers / the workers' summed seconds, i.e. start-up excluded), each worker's peak memory
(from the table's ``worker_peak_mb``) and whether the dask and local tables agree bit for bit.
No figure is asserted: the machine decides them.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
TIMING = ("seconds", "worker", "worker_peak_mb")


def meshes(data=DATA, faust=20, kids=28):
    files = sorted((data / "faust-dev").glob("*.ply"))[:faust] + sorted((data / "kids-dev").glob("*/*.ply"))[:kids]
    if len(files) < faust + kids:
        raise SystemExit(f"need {faust} FAUST and {kids} KIDS meshes under {data}")
    return files


def wall(command, env=None, cpu=None):
    """Wall seconds of a whole command; its CPU seconds (user + system, with the processes it
    waited for: the workers) are appended to `cpu`."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    run = subprocess.run(command, capture_output=True, text=True, env={**os.environ, **(env or {})})
    seconds = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if run.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, command))} failed ({run.returncode}):\n{run.stderr}")
    if cpu is not None:
        cpu.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return seconds


def jaxpose_command():
    return [sys.executable, "-m", "jaxpose", "normalize"]


def trimesh_loop(manifest):
    code = ("import sys, trimesh\n"
            "for line in open(sys.argv[1]):\n"
            "    mesh = trimesh.load(line.strip(), process=False)\n"
            "    mesh.center_mass\n")
    return [sys.executable, "-c", code, str(manifest)]


def table_summary(table, workers):
    import jaxpose

    rows = jaxpose.read_transforms(table)
    peaks = {}
    for row in rows:
        peaks[row.worker] = max(peaks.get(row.worker, 0.0), row.worker_peak_mb or 0.0)
    busy = sum(row.seconds for row in rows)
    return {"rows": len(rows), "failed": sum(not r.ok for r in rows), "peak_mb": sorted(peaks.values()),
            "compute_rate": len(rows) * workers / busy if busy else None,
            "stable": [{k: v for k, v in r._asdict().items() if k not in TIMING and k != "output"} for r in rows]}


def run(repeats=3, workers=2, dask=True, data=DATA, copies=1, with_single=True):
    files = meshes(data)
    work = Path(tempfile.mkdtemp(prefix="jaxpose-dataset-"))
    cluster = None
    try:
        if copies > 1:  # a bigger dataset of the same meshes (copies, so each is a file of its own)
            files = [_copy(f, work / "copies" / str(k) / f.parent.name / f.name) for k in range(copies) for f in files]
        manifest = work / "meshes.txt"
        manifest.write_text("".join(f"{f}\n" for f in files))
        try:
            import distributed  # noqa: F401
        except ImportError:
            dask = False
        names = ("trimesh", "local", "dask", "dask_running")
        times = {name: [] for name in names}
        cpus = {name: [] for name in names}
        tables = {}
        if dask:
            from jaxpose.batch.workers import local_cluster

            cluster = local_cluster(workers)
        for i in range(repeats):
            times["trimesh"].append(wall(trimesh_loop(manifest), cpu=cpus["trimesh"]))
            out = work / f"local{i}"
            times["local"].append(wall(jaxpose_command() + [manifest, "-o", out, "--workers", str(workers)],
                                       cpu=cpus["local"]))
            tables["local"] = table_summary(out / "transforms.parquet", workers)
            if dask:
                out = work / f"dask{i}"
                times["dask"].append(wall(jaxpose_command() + [manifest, "-o", out, "--dask-local", str(workers)],
                                          cpu=cpus["dask"]))
                tables["dask"] = table_summary(out / "transforms.parquet", workers)
                out = work / f"dask_running{i}"
                times["dask_running"].append(wall(jaxpose_command() + [manifest, "-o", out, "--scheduler",
                                                                       cluster.scheduler_address],
                                                  cpu=cpus["dask_running"]))
                tables["dask_running"] = table_summary(out / "transforms.parquet", workers)
        if cluster is not None:
            cluster.close()
            cluster = None
        single = {}
        for name, extra, env in [] if not with_single else (("single", [], {}), ("single_ocsvm", ["--method", "ocsvm"],
                                                      {"JAXPOSE_CACHE_DIR": str(work / "cache")})):
            cpu = []
            runs = [wall(jaxpose_command() + [files[0], "-o", work / f"{name}{k}.ply"] + extra, env, cpu)
                    for k in range(2)]
            single[name] = {"first_s": runs[0], "second_s": runs[1], "second_cpu_s": cpu[1]}
        n = len(files)
        result = {"files": n, "workers": workers, "cores": os.cpu_count(), "repeats": repeats, "single": single}
        for name, values in times.items():
            if values:
                result[name] = {"median_s": statistics.median(values), "runs_s": values,
                                "per_s": n / statistics.median(values), "cpu_s": statistics.median(cpus[name])}
        result["local"].update({k: tables["local"][k] for k in ("failed", "peak_mb", "compute_rate")})
        for name in ("dask", "dask_running") if dask else ():
            ratios = [d / l for d, l in zip(times[name], times["local"])]
            result[name].update({k: tables[name][k] for k in ("failed", "peak_mb", "compute_rate")},
                                over_local=statistics.median(ratios), ratios=ratios,
                                same_table=tables[name]["stable"] == tables["local"]["stable"])
        return result
    finally:
        if cluster is not None:  # a run failed (SystemExit) while it was up
            cluster.close()
        shutil.rmtree(work, ignore_errors=True)


def _copy(source, target):
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source, target)
    return target


def format_result(r):
    lines = [f"{r['files']} meshes, {r['workers']} workers, {r['cores']} cores, median of {r['repeats']} runs "
             "(whole commands, start-up included)",
             "| run | wall s (median) | meshes/s | CPU s (median) | compute-only meshes/s | peak MiB per worker |",
             "|---|---|---|---|---|---|"]
    for name in ("trimesh", "local", "dask", "dask_running"):
        if name in r:
            x = r[name]
            rate = f"{x['compute_rate']:.1f}" if x.get("compute_rate") else ""
            peak = ", ".join(f"{p:.0f}" for p in x.get("peak_mb", []))
            lines.append(f"| {name} | {x['median_s']:.2f} | {x['per_s']:.2f} | {x['cpu_s']:.2f} | {rate} | {peak} |")
    for name in ("dask", "dask_running"):
        if name in r:
            lines.append(f"{name} / local wall: {r[name]['over_local']:.3f} (pairs: "
                         f"{', '.join(f'{v:.3f}' for v in r[name]['ratios'])}); same table: {r[name]['same_table']}")
    if "dask_running" in r:
        lines.append("dask_running CPU: the client only (the running cluster's workers are not counted)")
    for name, s in r["single"].items():
        lines.append(f"{name}: first run {s['first_s']:.2f} s, second run {s['second_s']:.2f} s "
                     f"({s['second_cpu_s']:.2f} s CPU)")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-dask", action="store_true")
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--copies", type=int, default=1, help="each mesh this many times (a bigger dataset)")
    parser.add_argument("--no-single", action="store_true", help="skip the single-file runs")
    parser.add_argument("--json", help="write the result here")
    args = parser.parse_args(argv)
    result = run(args.repeats, args.workers, not args.no_dask, args.data, args.copies, not args.no_single)
    print(format_result(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
