"""``jaxpose normalize DIR -o OUT --workers W`` against a plain trimesh loop, side by side
(``python -m benchmarks.dataset_speed``).

Two datasets, written into a temporary folder before any timing:

real        48 real meshes of ../shared/data (the 20 FAUST registrations, the 16 TOSCA dogs and
            horses, the first 6 poses of each KIDS child; 25,200 vertices on average), each written
            by trimesh's exporters, alternately as text OFF and binary PLY (in that sorted order:
            both formats get meshes of every dataset)
synthetic   ``--synthetic`` files (default 2,000): small closed meshes (a deformed icosphere of
            642 or 2,562 vertices, a capsule, a box: random per seed), alternately OFF and PLY

and two commands, each a whole process timed from outside (start-up included), run in turn so that
a drift of the machine's speed hits both alike:

trimesh     the loop a user writes without jaxpose, in one process: ``trimesh.load(path,
            process=False)`` and its ``center_mass`` per file
jaxpose     ``python -m jaxpose normalize DIR -o OUT --workers W`` (a fresh OUT each run)

Printed per dataset: median wall seconds, meshes/s and CPU seconds (user + system, the workers
included) of each, jaxpose's speed over trimesh's per pair and their median (the figure that
survives a busy machine), the time from the command's start to its first output file, and each
worker's peak memory (the table's ``worker_peak_mb``). Nothing is asserted: the machine decides.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
FORMATS = ("off", "ply")  # text OFF, binary PLY


# --------------------------------------------------------------------------- datasets
def real_meshes(data=DATA, kids_poses=6):
    """The 48 source files: FAUST, TOSCA, the first poses of each KIDS child, in sorted order."""
    files = (sorted((data / "faust-dev").glob("*.ply")) + sorted((data / "tosca-dev").glob("*/*.ply"))
             + [f for child in sorted((data / "kids-dev").glob("*/")) for f in sorted(child.glob("*.ply"))[:kids_poses]])
    if len(files) != 20 + 16 + 2 * kids_poses:
        raise SystemExit(f"need the FAUST, TOSCA and KIDS dev meshes under {data}")
    return files


def write_real(folder, data=DATA):
    """The real dataset under `folder`: mesh i as FORMATS[i % 2]. Returns the paths."""
    import trimesh

    out = []
    for i, source in enumerate(real_meshes(data)):
        mesh = trimesh.load(source, process=False)
        path = folder / source.parent.name / f"{source.stem}.{FORMATS[i % 2]}"
        out.append(_write(mesh, path))
    return out


def write_synthetic(folder, count, seed=0):
    """`count` small random closed meshes under `folder` (100 per sub-folder). Returns the paths."""
    import trimesh

    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        kind = i % 4
        if kind in (0, 1):
            mesh = trimesh.creation.icosphere(subdivisions=3 + (kind == 1))
            mesh.vertices *= 1.0 + 0.15 * np.sin(mesh.vertices @ rng.normal(size=3))[:, None]
        elif kind == 2:
            mesh = trimesh.creation.capsule(height=rng.uniform(0.5, 2.0), radius=rng.uniform(0.2, 0.6), count=[16, 16])
        else:
            mesh = trimesh.creation.box(extents=rng.uniform(0.3, 2.0, 3))
            mesh = mesh.subdivide().subdivide()
        mesh.apply_transform(trimesh.transformations.random_rotation_matrix(rng.uniform(size=3)))
        mesh.apply_translation(rng.normal(scale=5.0, size=3))
        out.append(_write(mesh, folder / f"{i // 100:03d}" / f"mesh_{i:05d}.{FORMATS[i % 2]}"))
    return out


def _write(mesh, path):
    path.parent.mkdir(parents=True, exist_ok=True)
    data = mesh.export(file_type=path.suffix[1:])  # OFF: text; PLY: binary (trimesh's default)
    path.write_bytes(data.encode() if isinstance(data, str) else data)
    return path


# --------------------------------------------------------------------------- commands
def trimesh_loop(manifest):
    code = ("import sys, trimesh\n"
            "for line in open(sys.argv[1]):\n"
            "    mesh = trimesh.load(line.strip(), process=False)\n"
            "    mesh.center_mass\n")
    return [sys.executable, "-c", code, str(manifest)]


def jaxpose_command(folder, out, workers):
    return [sys.executable, "-m", "jaxpose", "normalize", str(folder), "-o", str(out), "--workers", str(workers)]


def timed(command, watch=None, suffixes=FORMATS):
    """(wall s, CPU s of the process and what it waited for, s to the first file under `watch`)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    first = None
    while process.poll() is None:
        if watch is not None and first is None and _any_output(watch, suffixes):
            first = time.perf_counter() - start
        time.sleep(0.01)
    seconds = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if process.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, command))} failed ({process.returncode}):\n{process.stderr.read()}")
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    return seconds, cpu, first


def _any_output(folder, suffixes):
    if not folder.is_dir():
        return False
    for _root, _dirs, names in os.walk(folder):
        if any(n.rsplit(".", 1)[-1] in suffixes and not n.startswith(".") for n in names):
            return True
    return False


def peaks(table):
    import jaxpose

    rows = jaxpose.read_transforms(table)
    found = {}
    for row in rows:
        found[row.worker] = max(found.get(row.worker, 0.0), row.worker_peak_mb or 0.0)
    return {"rows": len(rows), "failed": sum(not r.ok for r in rows), "peak_mb": sorted(found.values())}


# --------------------------------------------------------------------------- runs
def compare(name, files, folder, work, repeats, workers):
    """Both commands on one dataset, `repeats` times in turn."""
    manifest = work / f"{name}.txt"
    manifest.write_text("".join(f"{f}\n" for f in files))
    runs = {"trimesh": [], "jaxpose": []}
    table = None
    for i in range(repeats):
        wall, cpu, _ = timed(trimesh_loop(manifest))
        runs["trimesh"].append({"wall_s": wall, "cpu_s": cpu})
        out = work / f"{name}-out{i}"
        wall, cpu, first = timed(jaxpose_command(folder, out, workers), watch=out)
        runs["jaxpose"].append({"wall_s": wall, "cpu_s": cpu, "first_s": first})
        table = peaks(out / "transforms.parquet" if (out / "transforms.parquet").exists() else out / "transforms.csv")
        shutil.rmtree(out, ignore_errors=True)
    n = len(files)
    result = {"files": n, "repeats": repeats, "workers": workers, **table}
    for key, values in runs.items():
        wall = statistics.median(v["wall_s"] for v in values)
        result[key] = {"wall_s": wall, "per_s": n / wall, "cpu_s": statistics.median(v["cpu_s"] for v in values),
                       "runs_s": [round(v["wall_s"], 3) for v in values]}
    ratios = [t["wall_s"] / j["wall_s"] for t, j in zip(runs["trimesh"], runs["jaxpose"])]
    result["speedup"] = statistics.median(ratios)
    result["speedups"] = [round(r, 3) for r in ratios]
    result["jaxpose"]["first_s"] = statistics.median(v["first_s"] for v in runs["jaxpose"])
    return result


def run(repeats=3, workers=2, synthetic=2000, synthetic_repeats=1, data=DATA, skip_real=False):
    work = Path(tempfile.mkdtemp(prefix="jaxpose-dataset-speed-"))
    try:
        result = {"cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
                  "load_before": os.getloadavg()[0]}
        if not skip_real:
            files = write_real(work / "real", data)
            result["real"] = compare("real", files, work / "real", work, repeats, workers)
            result["real"]["mean_vertices"] = _mean_vertices(files)
        if synthetic:
            files = write_synthetic(work / "synthetic", synthetic)
            result["synthetic"] = compare("synthetic", files, work / "synthetic", work, synthetic_repeats, workers)
        result["load_after"] = os.getloadavg()[0]
        return result
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _mean_vertices(files):
    import trimesh

    return float(np.mean([len(trimesh.load(f, process=False).vertices) for f in files]))


def format_result(r):
    lines = [f"{r['cores']} cores; load average {r['load_before']:.1f} before, {r['load_after']:.1f} after"]
    for name in ("real", "synthetic"):
        if name not in r:
            continue
        x = r[name]
        extra = f", {x['mean_vertices']:,.0f} vertices on average" if "mean_vertices" in x else ""
        lines += [f"\n{name}: {x['files']} files{extra}, jaxpose --workers {x['workers']}, median of {x['repeats']} "
                  f"(whole commands, start-up included)",
                  "| command | wall s | meshes/s | CPU s | first result s | peak MiB per worker |",
                  "|---|---|---|---|---|---|"]
        for key in ("trimesh", "jaxpose"):
            y = x[key]
            first = f"{y['first_s']:.2f}" if y.get("first_s") is not None else ""
            peak = ", ".join(f"{p:.0f}" for p in x["peak_mb"]) if key == "jaxpose" else ""
            lines.append(f"| {key} | {y['wall_s']:.2f} | {y['per_s']:.1f} | {y['cpu_s']:.2f} | {first} | {peak} |")
        lines.append(f"jaxpose / trimesh speed: {x['speedup']:.2f}x (pairs: {', '.join(map(str, x['speedups']))}); "
                     f"failed: {x['failed']} of {x['rows']}")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs of each command on the real dataset")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--synthetic", type=int, default=2000, help="files of the synthetic dataset (0: none)")
    parser.add_argument("--synthetic-repeats", type=int, default=1)
    parser.add_argument("--no-real", action="store_true", help="only the synthetic dataset")
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--json", help="write the result here")
    args = parser.parse_args(argv)
    result = run(args.repeats, args.workers, args.synthetic, args.synthetic_repeats, args.data, args.no_real)
    print(format_result(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
