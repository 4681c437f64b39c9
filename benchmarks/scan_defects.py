"""The robust pose of real bodies with scan defects, against the same body without them.

``python -m benchmarks.scan_defects [--bodies faust,kid,dog,human] [--points] [--dev-edges] [--json OUT]``

Bodies: faust-dev's ``tr_reg_000`` (a 1.7 m person), kids-dev's ``kid_0001/pose_00``, tosca-dev's
``dog0`` (``../shared/data``) and the built-in ``make_object("human", 0, 0)``. Each defect is added to
the body (lengths in L, the body's largest extent; "up" its axis): far specks, a floor (a one-sided
sheet or a closed slab under the feet), a sphere between the legs, a second sphere of a share of
the body's area, a needle, a duplicate, degenerate and huge triangles, an unreferenced vertex. Each
row: the center's offset from the body's own robust center over the body's scale, the scale's
ratio, ``valid``, or the error's first words. ``--points`` adds the vertices as a point cloud with
far points, a far cluster and uniform noise, through ``normalize_mesh(PointCloud)`` and
``jaxpose.normalize(points)``. ``--dev-edges`` instead lists the plain dev meshes whose fine solid reaches
its grid's edge (cut by the first pass's box) and what that costs. Asserts nothing; docs/estimators.md ("Scan defects") quotes it.
"""
from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
BODIES = {"faust": "faust-dev/tr_reg_000.ply", "kid": "kids-dev/kid_0001/pose_00.ply", "dog": "tosca-dev/dog/dog0.ply"}


def load(name):
    import trimesh

    if name == "human":
        from jaxpose.datasets import make_object

        return make_object("human", 0, 0)
    return trimesh.load(DATA / BODIES[name], process=False)


def _cat(*parts):
    import trimesh

    vs, fs, n = [], [], 0
    for v, f in parts:
        vs.append(np.asarray(v, float))
        fs.append(np.asarray(f) + n)
        n += len(v)
    return trimesh.Trimesh(np.vstack(vs), np.vstack(fs), process=False)


def _sphere(c, r, sub=2):
    import trimesh

    s = trimesh.creation.icosphere(sub, r)
    return s.vertices + c, s.faces


def mesh_cases(m):
    """{name: Trimesh}: the body with each defect."""
    import trimesh
    from scipy.spatial import cKDTree

    v, f = np.asarray(m.vertices, float), np.asarray(m.faces)
    lo, hi = v.min(0), v.max(0)
    L, mid = float((hi - lo).max()), (lo + hi) / 2
    up = int(np.argmax(hi - lo))
    a1, a2 = [k for k in range(3) if k != up]
    e = np.eye(3)
    body = (v, f)
    rng = np.random.default_rng(0)

    def specks(n, r0, r1, size):
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return [_sphere(mid + L * x * t, size * L, 1) for x, t in zip(d, rng.uniform(r0, r1, n))]

    def floor(below, half, n, thick=0.0):
        z = lo[up] - below * L
        s = np.linspace(-half * L, half * L, n + 1)
        if thick:
            b_lo, b_hi = mid - half * L, mid + half * L
            b_lo[up], b_hi[up] = z - thick * L, z
            b = trimesh.creation.box(bounds=[b_lo, b_hi])
            return b.vertices, b.faces
        x, y = np.meshgrid(mid[a1] + s, mid[a2] + s, indexing="ij")
        w = np.zeros((x.size, 3))
        w[:, a1], w[:, a2], w[:, up] = x.ravel(), y.ravel(), z
        a = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
        return w, np.r_[np.c_[a, a + n + 2, a + 1], np.c_[a, a + n + 1, a + n + 2]]

    def needle(p0, length, r):
        c = trimesh.creation.cylinder(radius=r * L, sections=8, segment=[p0, p0 + length * L * e[a1]])
        return c.vertices, c.faces

    tree = cKDTree(v)  # the point under the middle farthest from the vertices: between the legs
    heights = [lo[up] + t * L for t in np.linspace(0.03, 0.45, 43)]
    gaps = [(tree.query(np.where(np.arange(3) == up, h, mid))[0], np.where(np.arange(3) == up, h, mid)) for h in heights]
    gap, legs = max(gaps, key=lambda g: g[0])
    side = mid.copy()
    side[a1] = hi[a1] + 0.05 * L
    far = mid + 50 * L * e[a1]
    out = {
        "10 specks (1 % L) 2-10 L away": _cat(body, *specks(10, 2, 10, 0.01)),
        "10 specks (1 % L) 20-100 L away": _cat(body, *specks(10, 20, 100, 0.01)),
        "floor sheet 2 L wide (20 x 20 squares) touching the feet": _cat(body, floor(0.0, 1.0, 20)),
        "floor sheet 6 L wide (2 triangles) 1 % L below": _cat(body, floor(0.01, 3.0, 1)),
        "floor slab 2 L wide, 1 % L thick, touching": _cat(body, floor(0.0, 1.0, 1, 0.01)),
        "floor slab 2 L wide, 5 % L thick, 1 % L below": _cat(body, floor(0.01, 1.0, 1, 0.05)),
        "sphere between the legs, half the gap": _cat(body, _sphere(legs, 0.5 * gap, 3)),
    }
    area = m.area
    for share in (0.45, 0.55):  # keep_main's ratio (0.5) is of boundary voxels, not of area
        r = np.sqrt(share * area / (4 * np.pi))
        c = mid.copy()
        c[a1] = hi[a1] + r + 0.3 * L
        out[f"second sphere, {share:g} of the area, 0.3 L off"] = _cat(body, _sphere(c, r, 3))
    shift = np.zeros(3)
    shift[a1] = 0.05 * L
    out.update({
        "needle 5 L long, 0.2 % L thick, 5 % L off": _cat(body, needle(side, 5, 0.002)),
        "needle 3 L long, 0.2 % L thick, through the body": _cat(body, needle(mid, 3, 0.002)),
        "duplicate in the same place": _cat(body, body),
        "duplicate shifted 5 % L": _cat(body, (v + shift, f)),
        "zero-area face 50 L away": _cat(body, (np.stack([far, far, far + 0.1 * L * e[up]]), [[0, 1, 2]])),
        "triangle of 10 L sides, 20 L away": _cat(body, (np.stack([mid + 20 * L * e[a1], mid + 20 * L * e[a1] + 10 * L * e[up],
                                                                    mid + 20 * L * e[a1] + 10 * L * e[a2]]), [[0, 1, 2]])),
        "unreferenced vertex 1000 L away": trimesh.Trimesh(np.vstack([v, mid + 1e3 * L * e[a1]]), f, process=False),
    })
    return out


def point_cases(m):
    """{name: (n, 3)}: the body's vertices with far points, a far cluster, noise."""
    v = np.asarray(m.vertices, float)
    lo, hi = v.min(0), v.max(0)
    L, mid = float((hi - lo).max()), (lo + hi) / 2
    rng = np.random.default_rng(1)

    def on_sphere(n):
        d = rng.normal(size=(n, 3))
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    x = np.array([1.0, 0, 0])
    return {
        "10 far points 2-10 L away": np.vstack([v, mid + L * rng.uniform(2, 10, (10, 1)) * on_sphere(10)]),
        "1 far point 30 L away": np.vstack([v, mid + 30 * L * x]),
        "1 far point 1000 L away": np.vstack([v, mid + 1e3 * L * x]),
        "300 points in a 3 % L ball 3 L away": np.vstack([v, mid + 3 * L * x + 0.03 * L * on_sphere(300)]),
        "100 noise points in a 3 L box": np.vstack([v, mid + L * rng.uniform(-1.5, 1.5, (100, 3))]),
        "1000 noise points in a 3 L box": np.vstack([v, mid + L * rng.uniform(-1.5, 1.5, (1000, 3))]),
    }


def measure(run, x, reference):
    """A row's cell: (center offset / scale, scale ratio, valid, status) or the error's first words."""
    try:
        pose = run(x)
    except Exception as error:  # noqa: BLE001 - a refusal is a result here
        return {"error": f"{type(error).__name__}: {str(error)[:110]}"}
    c, s = np.asarray(pose.center, float), float(pose.scale)
    return {"offset": float(np.linalg.norm(c - reference[0]) / reference[1]), "ratio": s / reference[1],
            "valid": bool(pose.valid), "status": int(pose.status)}


def dev_edges():
    """Rows (class, meshes cut, of, largest center shift / scale, scale changes) of the plain meshes
    of the built-in set (seed 0, 10 a class) and faust-dev, kids-dev, tosca-dev whose fine robust
    solid reaches its grid's edge, against the solid over the whole vertex box."""
    from jaxpose import datasets
    from jaxpose.occupancy import solid
    from jaxpose.pose.estimators import solid_center_volume

    sets = dict(datasets.make_dataset(0, instances=10))
    for folder in ("faust-dev", "kids-dev", "tosca-dev"):
        sets.update(datasets.load_folder(DATA / folder))
    near, rows = solid.near_solid, []
    for name, meshes in sets.items():
        found = []
        for m in meshes:
            v, f = np.asarray(m.vertices, float), np.asarray(m.faces)
            cut = solid.robust_solid(v, f, with_depth=False)
            if not solid.reaches_edge(cut.inside):
                continue
            solid.near_solid = lambda x, *a, **k: np.ones(len(x), bool)  # every vertex on the body: its whole box
            try:
                whole = solid.robust_solid(v, f, with_depth=False)
            finally:
                solid.near_solid = near
            (c0, v0), (c1, v1) = solid_center_volume(cut), solid_center_volume(whole)
            found.append((float(np.linalg.norm(c0 - c1)) / v1 ** (1 / 3), (v0 / v1) ** (1 / 3) - 1))
        if found:
            a = np.array(found)
            rows.append((name, len(found), len(meshes), float(a[:, 0].max()), float(a[:, 1].min()), float(a[:, 1].max())))
            print(f"| {name} | {len(found)} of {len(meshes)} | {a[:, 0].max():.4f} | "
                  f"{100 * a[:, 1].min():+.2f} ... {100 * a[:, 1].max():+.2f} % |", flush=True)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", default="faust,kid,dog,human")
    parser.add_argument("--points", action="store_true")
    parser.add_argument("--dev-edges", action="store_true", help="only the dev meshes whose solid reaches its grid's edge")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    if args.dev_edges:
        rows = dev_edges()
        if args.json:
            Path(args.json).write_text(json.dumps(rows, indent=1))
        return 0
    import trimesh

    import jaxpose

    mesh_run = lambda x: jaxpose.normalize_mesh(x)[1]  # noqa: E731
    runs = {"mesh": mesh_run}
    if args.points:
        runs["PointCloud"] = lambda x: jaxpose.normalize_mesh(trimesh.PointCloud(x))[1]
        runs["normalize"] = lambda x: jaxpose.normalize(x)
    rows = []
    for name in args.bodies.split(","):
        m = load(name)
        for path, run in runs.items():
            plain = m if path == "mesh" else np.asarray(m.vertices, float)
            ref = run(plain)
            reference = (np.asarray(ref.center, float), float(ref.scale))
            cases = mesh_cases(m) if path == "mesh" else point_cases(m)
            for case, x in cases.items():
                row = {"body": name, "input": path, "case": case, **measure(run, x, reference)}
                rows.append(row)
                cell = row.get("error") or (f"{row['offset']:.4f} | {row['ratio']:.4f} | "
                                            f"{'valid' if row['valid'] else 'invalid'} (status {row['status']})")
                print(f"| {name} | {path} | {case} | {cell} |", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
