"""The real meshes the benchmarks measure: where they are looked for, and a converter that lays
out the public datasets as they expect (docs/data.md).

``python -m benchmarks.data faust|kids|tosca SOURCE [--out DIR] [--force]`` converts a download;
``python -m benchmarks.data classes faust-dev OUT`` makes FAUST's two people two class folders
(symbolic links, for ``jaxpose evaluate --data`` / ``jaxpose tune --data``);
``python -m benchmarks.data check [--out DIR]`` says what is there.

The data folder is ``$JAXPOSE_DATA``, else ``../shared/data`` beside the checkout. Layout:

* ``faust-dev/tr_reg_000.ply`` .. ``tr_reg_019.ply``: FAUST's first 20 training registrations
  (two people, ten poses each).
* ``kids-dev/kid_0001/pose_00.ply`` .. ``pose_15.ply``, ``kids-dev/kid_0002/...``: the two
  children of KIDS, sixteen poses each.
* ``tosca-dev/dog/dog0.ply`` .. ``dog7.ply``, ``tosca-dev/horse/horse{0,5,6,7,10,14,15,17}.ply``.

Every mesh is written as binary PLY with float32 coordinates and the source's vertex order and
faces (nothing is merged or reordered: a class's meshes share their vertex order, which
``--align-core`` relies on).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT.parent / "shared" / "data"
DATASETS = ("faust-dev", "kids-dev", "tosca-dev")
FAUST_COUNT = 20
KIDS_CHILDREN, KIDS_POSES = 2, 16
TOSCA = {"dog": (0, 1, 2, 3, 4, 5, 6, 7), "horse": (0, 5, 6, 7, 10, 14, 15, 17)}
MESH_SUFFIXES = (".ply", ".off", ".obj", ".stl")
HOWTO = "see docs/data.md: the public datasets (FAUST, KIDS, TOSCA), their licences, and `python -m benchmarks.data`"


def data_root() -> Path:
    """``$JAXPOSE_DATA`` when set, else ``../shared/data`` beside the source checkout."""
    env = os.environ.get("JAXPOSE_DATA")
    return Path(env) if env else DEFAULT


def missing(names=DATASETS, root=None) -> list:
    """The datasets of `names` that are not under `root` (default :func:`data_root`)."""
    root = data_root() if root is None else Path(root)
    return [n for n in names if not (root / n).is_dir()]


def require(names=DATASETS, root=None) -> Path:
    """The data root, or SystemExit(1) with a message saying where the data comes from."""
    root = data_root() if root is None else Path(root)
    gone = missing(names, root)
    if gone:
        raise SystemExit(f"error: no {', '.join(gone)} in {root} (set JAXPOSE_DATA to another folder); {HOWTO}")
    return root


# ------------------------------------------------------------------ reading the downloads
def read_mesh(path):
    """(vertices (n, 3) float64, faces (f, 3) int64) of a mesh file, or of TOSCA's ``NAME.vert``
    (one vertex ``x y z`` per line) with ``NAME.tri`` (one triangle per line, 1-based)."""
    path = Path(path)
    if path.suffix == ".vert":
        vertices = np.loadtxt(path, dtype=np.float64, ndmin=2)
        faces = np.loadtxt(path.with_suffix(".tri"), dtype=np.int64, ndmin=2) - 1
    else:
        import trimesh

        mesh = trimesh.load(path, force="mesh", process=False)
        vertices, faces = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    if vertices.shape[1:] != (3,) or faces.shape[1:] != (3,) or len(faces) == 0:
        raise SystemExit(f"error: {path} holds no triangle mesh")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise SystemExit(f"error: {path}: face indices out of range")
    return vertices, faces


def write_ply(vertices, faces, path, force=False):
    """Binary little-endian PLY, float32 coordinates, int32 indices; refuses to overwrite."""
    path = Path(path)
    if path.exists() and not force:
        raise SystemExit(f"error: {path} exists (use --force to overwrite)")
    path.parent.mkdir(parents=True, exist_ok=True)
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\nproperty float x\n"
              f"property float y\nproperty float z\nelement face {len(faces)}\n"
              "property list uchar int vertex_indices\nend_header\n").encode()
    rows = np.empty(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rows["n"], rows["i"] = 3, faces
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "wb") as f:
        f.write(header + np.asarray(vertices, "<f4").tobytes() + rows.tobytes())
    os.replace(tmp, path)


def _find(source, stem):
    """The mesh file of `source` named `stem` (any supported suffix, or .vert/.tri), searched recursively."""
    for suffix in (*MESH_SUFFIXES, ".vert"):
        found = sorted(Path(source).rglob(stem + suffix))
        if found:
            return found[0]
    raise SystemExit(f"error: no {stem} ({', '.join(MESH_SUFFIXES)} or .vert/.tri) under {source}; {HOWTO}")


def convert_faust(source, out, force=False):
    """FAUST's ``training/registrations/tr_reg_000..019.ply`` (found anywhere under `source`)."""
    for i in range(FAUST_COUNT):
        write_ply(*read_mesh(_find(source, f"tr_reg_{i:03d}")), Path(out) / "faust-dev" / f"tr_reg_{i:03d}.ply", force)
    return FAUST_COUNT


def convert_kids(source, out, force=False):
    """`source` holds one sub-folder per child (the first two, sorted by name), each with the
    child's sixteen poses as mesh files, the null pose first when sorted by name."""
    children = sorted(p for p in Path(source).iterdir() if p.is_dir())[:KIDS_CHILDREN]
    if len(children) < KIDS_CHILDREN:
        raise SystemExit(f"error: {source} needs {KIDS_CHILDREN} sub-folders, one per child; {HOWTO}")
    n = 0
    for k, child in enumerate(children, start=1):
        poses = sorted(p for p in child.iterdir() if p.suffix.lower() in MESH_SUFFIXES)
        if len(poses) < KIDS_POSES:
            raise SystemExit(f"error: {child} holds {len(poses)} meshes, not {KIDS_POSES}; {HOWTO}")
        for j, pose in enumerate(poses[:KIDS_POSES]):
            write_ply(*read_mesh(pose), Path(out) / "kids-dev" / f"kid_{k:04d}" / f"pose_{j:02d}.ply", force)
            n += 1
    return n


def convert_tosca(source, out, force=False):
    """TOSCA high-resolution's ``dogK`` and ``horseK`` (``.vert`` + ``.tri``, or a mesh file)."""
    n = 0
    for name, numbers in TOSCA.items():
        for i in numbers:
            write_ply(*read_mesh(_find(source, f"{name}{i}")), Path(out) / "tosca-dev" / name / f"{name}{i}.ply", force)
            n += 1
    return n


def faust_classes(faust, out):
    """A folder of FAUST's two people as class sub-folders of symbolic links (nothing copied)."""
    faust, out = Path(faust), Path(out)
    for k, person in enumerate(("person_a", "person_b")):
        (out / person).mkdir(parents=True, exist_ok=True)
        for i in range(10 * k, 10 * k + 10):
            link = out / person / f"tr_reg_{i:03d}.ply"
            if not link.is_symlink():
                link.symlink_to((faust / f"tr_reg_{i:03d}.ply").resolve())
    return out


CONVERT = {"faust": convert_faust, "kids": convert_kids, "tosca": convert_tosca}


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.data", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    for name in CONVERT:
        c = sub.add_parser(name, help=f"convert a {name.upper()} download into the data folder")
        c.add_argument("source", help="the unpacked download")
        c.add_argument("--out", default=None, help=f"the data folder (default {data_root()})")
        c.add_argument("--force", action="store_true", help="overwrite converted files")
    c = sub.add_parser("classes", help="faust-dev's two people as two class folders of symbolic links")
    c.add_argument("dataset", choices=("faust-dev",))
    c.add_argument("out")
    c = sub.add_parser("check", help="say which datasets are in the data folder")
    c.add_argument("--out", default=None)
    args = p.parse_args(argv)
    if args.command in CONVERT:
        out = Path(args.out) if args.out else data_root()
        n = CONVERT[args.command](args.source, out, args.force)
        print(f"wrote {n} meshes under {out}")
    elif args.command == "classes":
        print(faust_classes(require(("faust-dev",)) / "faust-dev", args.out))
    else:
        root = Path(args.out) if args.out else data_root()
        gone = missing(root=root)
        for name in DATASETS:
            print(f"{name}: {'missing' if name in gone else 'present'} in {root}")
        if gone:
            print(HOWTO, file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
