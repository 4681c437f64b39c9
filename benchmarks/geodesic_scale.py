"""An intrinsic (bending-invariant) size against V^(1/3) and sqrt(area) (issue 34, the dog's scale).

``python -m benchmarks.geodesic_scale [--variants plain,holes,outliers,points] [--classes ...]
[--k 64,128,256] [--sources fps,random,shared] [--knn 8,12] [--uniform] [--diagonals] [--heat K]
[--voxel] [--every K]
[--seed 0] [--json OUT]``, ``--jax K`` (alone) or ``--summary JSON...`` (the compact tables of earlier
records, nothing measured) from a source checkout with ../shared beside it.

The six dev classes as :mod:`benchmarks.bodies` loads them (rigid-core aligned; the variants made
as ``jaxpose evaluate`` makes them, seed 0, the class index within its dataset). For every shape:

* ``robust``: the default scale V^(1/3) of the robust solid
  (:func:`jaxpose.pose.estimators.robust_center_scale`); ``sqrt_area``: sqrt of the trimesh area of
  the whole input (``solid_sqrt_area``'s scale; meshes only);
* geodesic sizes on a graph: meshes: the edge graph (edge lengths Euclidean) of the connected
  component of the largest area, targets = its vertices weighted by their area share (a third of
  the area of their faces); point clouds: the symmetrised k-nearest-neighbour graph (edge lengths
  Euclidean) of the component with most points, targets weighted alike. From K source rows
  D[k, t] (Dijkstra, ``scipy.sparse.csgraph.dijkstra``) with source weights a_k:

  - ``mean``: sum_k a_k sum_t w_t D[k, t] (the mean geodesic distance between two surface points),
  - ``rms``: the same of D^2, square root,
  - ``ecc_max``: sum_k a_k max_t D[k, t] (the mean of the sources' farthest distance),
  - ``radius``: min_t sum_k a_k D[k, t] (the mean distance from the geodesic center, the point of
    least mean distance; D is symmetric, so the K rows give every vertex's mean distance),
  - ``diameter``: max D.

  Sources: ``fps``: geodesic farthest-point sampling, started at the vertex farthest from a seeded
  random vertex, each source weighted by the area share of its geodesic Voronoi cell (the targets
  nearest to it; an intrinsic quadrature: needs no correspondence); ``random``: K independent
  area-weighted vertices (seeded per instance), equal weights; ``shared`` (plain only): the same
  vertex indices in every pose of a class, chosen once area-weighted on the class's first mesh
  (uses the correspondence, which a library does not have: the limit of what the size itself
  allows). The first K of each sequence for each K of ``--k``.
* ``--diagonals``: the same sizes on the edge graph plus each flip diagonal (the two vertices
  opposite a shared edge, Euclidean), fps sources: whether the edge graph's zig-zag overestimate is
  pose dependent (the ratio edge / edge+diagonal per pose, and its cv).
* ``--heat K``: the same sizes from heat-method geodesics (``potpourri3d``, installed by hand; not
  a jaxpose dependency) from the first K fps sources: whether the edge graph is what varies.
* ``--jax K`` (alone): the fps rows of each class's first plain mesh by a min-plus relaxation over
  the edge list in JAX (:func:`minplus_rows`, run to its fixed point), against Dijkstra: the steps
  a fixed-iteration version needs, the error, the seconds.
* ``--voxel``: the inner distance: the same sizes on the robust solid's voxels (26-neighbour graph,
  steps of pitch x 1, sqrt 2, sqrt 3), fps sources, every voxel weighted alike (what a JAX version
  on the library's own solid would compute; works alike on meshes, clouds, holes and stray parts).

cv = population std / mean over a class's poses (``jaxpose.evaluation.measures.scale_spread``).
Printed per variant and class; seconds per shape of the geodesic part beside. Nothing is asserted.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from jaxpose import baselines
from jaxpose.evaluation import make_class
from jaxpose.evaluation.measures import scale_spread
from jaxpose.pose.estimators import robust_center_scale

from .bodies import CLASSES, SHARED, dev_classes

SIZES = ("mean", "rms", "ecc_max", "radius", "diameter")


# ------------------------------------------------------------------ graphs
def _sym_graph(i, j, w, n):
    g = coo_matrix((np.r_[w, w], (np.r_[i, j], np.r_[j, i])), shape=(n, n)).tocsr()
    g.sum_duplicates()
    return g


def mesh_edges(vertices, faces, diagonals=False):
    """(i, j) unique undirected edges of a triangle mesh (plus each flip diagonal if asked)."""
    f = np.asarray(faces, np.int64)
    e = np.sort(np.vstack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    if diagonals:
        # the vertex opposite each (face, edge): faces sharing an edge give a diagonal
        opp = np.r_[f[:, 2], f[:, 0], f[:, 1]]
        order = np.lexsort((e[:, 1], e[:, 0]))
        es, os_ = e[order], opp[order]
        same = np.all(es[1:] == es[:-1], axis=1)
        d = np.sort(np.c_[os_[:-1][same], os_[1:][same]], axis=1)
        d = d[d[:, 0] != d[:, 1]]
        e = np.vstack([e, d])
    e = np.unique(e, axis=0)
    return e[:, 0], e[:, 1]


def mesh_graph(vertices, faces, diagonals=False):
    """The weighted edge graph of a mesh's component of the largest area: (csr graph, vertices
    (m, 3), target weights (m,) summing to 1, kept vertex indices, its faces (renumbered))."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    i, j = mesh_edges(v, f)
    n = len(v)
    ncomp, label = connected_components(_sym_graph(i, j, np.ones(len(i)), n), directed=False)
    fa = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    comp_area = np.bincount(label[f[:, 0]], weights=fa, minlength=ncomp)
    keep_c = int(np.argmax(comp_area))
    keep = np.flatnonzero(label == keep_c)
    remap = -np.ones(n, np.int64)
    remap[keep] = np.arange(len(keep))
    fk = remap[f[label[f[:, 0]] == keep_c]]
    vk = v[keep]
    va = np.bincount(fk.ravel(), weights=np.repeat(fa[label[f[:, 0]] == keep_c], 3) / 3.0, minlength=len(keep))
    i, j = mesh_edges(vk, fk, diagonals)
    w = np.linalg.norm(vk[i] - vk[j], axis=1)
    return _sym_graph(i, j, w, len(keep)), vk, va / va.sum(), keep, fk


def knn_graph(points, k):
    """The symmetrised k-NN graph of a point cloud's component with most points: (graph, points,
    uniform weights, kept indices)."""
    p = np.asarray(points, np.float64)
    dist, idx = cKDTree(p).query(p, k + 1)
    i = np.repeat(np.arange(len(p)), k)
    j = idx[:, 1:].ravel()
    w = dist[:, 1:].ravel()
    g = _sym_graph(i, j, w, len(p))
    coo = g.tocoo()
    g = coo_matrix((np.linalg.norm(p[coo.row] - p[coo.col], axis=1), (coo.row, coo.col)), shape=g.shape).tocsr()
    ncomp, label = connected_components(g, directed=False)
    keep = np.flatnonzero(label == np.argmax(np.bincount(label)))
    g = g[keep][:, keep]
    return g, p[keep], np.full(len(keep), 1.0 / len(keep)), keep


_OFFSETS = np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)
                     if (a, b, c) > (0, 0, 0)])


def voxel_graph(sol):
    """The 26-neighbour graph of the robust solid's kept voxels (steps pitch x |offset|)."""
    inside = np.asarray(sol.inside, bool)
    idx = np.argwhere(inside)
    lab = -np.ones(inside.shape, np.int64)
    lab[tuple(idx.T)] = np.arange(len(idx))
    ii, jj, ww = [], [], []
    for o in _OFFSETS:
        q = idx + o
        ok = np.all((q >= 0) & (q < inside.shape), axis=1)
        nb = np.full(len(idx), -1)
        nb[ok] = lab[tuple(q[ok].T)]
        m = nb >= 0
        ii.append(np.flatnonzero(m))
        jj.append(nb[m])
        ww.append(np.full(m.sum(), sol.pitch * np.linalg.norm(o)))
    g = _sym_graph(np.concatenate(ii), np.concatenate(jj), np.concatenate(ww), len(idx))
    ncomp, label = connected_components(g, directed=False)
    keep = np.flatnonzero(label == np.argmax(np.bincount(label)))
    g = g[keep][:, keep]
    return g, idx[keep] * sol.pitch, np.full(len(keep), 1.0 / len(keep)), keep


# ------------------------------------------------------------------ sources and sizes
def fps_rows(g, w, kmax, rng, with_sources=False):
    """Geodesic farthest-point sampling: (kmax, n) distance rows, started at the farthest vertex
    from an area-weighted random one."""
    start = int(rng.choice(len(w), p=w))
    d0 = dijkstra(g, directed=False, indices=start)
    s = int(np.argmax(np.where(np.isfinite(d0), d0, -1)))
    rows = np.empty((kmax, g.shape[0]))
    sources = np.empty(kmax, np.int64)
    mind = np.full(g.shape[0], np.inf)
    for k in range(kmax):
        rows[k] = dijkstra(g, directed=False, indices=s)
        sources[k] = s
        mind = np.minimum(mind, rows[k])
        s = int(np.argmax(mind))
    return (rows, sources) if with_sources else rows


def sizes(rows, w, a):
    """{size: value} of distance rows (K, n), target weights w (n,), source weights a (K,) (sum 1)."""
    tw = rows @ w
    return {"mean": float(a @ tw), "rms": float(np.sqrt(a @ ((rows ** 2) @ w))),
            "ecc_max": float(a @ rows.max(axis=1)), "radius": float((a @ rows).min()),
            "diameter": float(rows.max())}


def voronoi_weights(rows, w):
    """Each source's share of the target weight (targets given to their nearest source)."""
    return np.bincount(np.argmin(rows, axis=0), weights=w, minlength=rows.shape[0])


def all_sizes(g, w, ks, schemes, rng, shared=None):
    """{f"{scheme}{K}:{size}": value} for each scheme and K (first K of the sequence), and the
    seconds of the K = max(ks) Dijkstra runs per scheme."""
    kmax = max(ks)
    out, sec = {}, {}
    for scheme in schemes:
        t0 = time.perf_counter()
        if scheme == "fps":
            rows = fps_rows(g, w, kmax, rng)
        elif scheme == "random":
            src = rng.choice(len(w), size=kmax, p=w)
            uniq, inv = np.unique(src, return_inverse=True)
            rows = dijkstra(g, directed=False, indices=uniq)[inv]
        elif scheme == "shared":
            if shared is None:
                continue
            uniq, inv = np.unique(shared[:kmax], return_inverse=True)
            rows = dijkstra(g, directed=False, indices=uniq)[inv]
        sec[scheme] = time.perf_counter() - t0
        if not np.all(np.isfinite(rows)):
            raise RuntimeError("graph not connected")
        for k in ks:
            r = rows[:k]
            a = voronoi_weights(r, w) if scheme == "fps" else np.full(k, 1.0 / k)
            for name, val in sizes(r, w, a).items():
                out[f"{scheme}{k}:{name}"] = val
    return out, sec


# ------------------------------------------------------------------ the same in JAX (--jax)
def minplus_rows(g, sources, iterations=None):
    """Geodesic rows (K, n) by min-plus (Bellman-Ford) relaxation over the directed edge list in
    JAX, float32: every step d[v] = min(d[v], min over edges (u, v) of d[u] + w); ``iterations``
    None: until nothing changes (a while loop), else that many steps (a fori loop, fixed shapes).
    Returns (rows, steps taken, seconds after compilation)."""
    import jax
    import jax.numpy as jnp

    coo = g.tocoo()
    u, v, w = (jnp.asarray(coo.row), jnp.asarray(coo.col), jnp.asarray(coo.data, jnp.float32))
    n = g.shape[0]
    d0 = jnp.full((n, len(sources)), jnp.inf, jnp.float32).at[jnp.asarray(sources), jnp.arange(len(sources))].set(0.0)

    def step(d):
        return jnp.minimum(d, jax.ops.segment_min(d[u] + w[:, None], v, num_segments=n))

    if iterations is None:
        def cond(c):
            return c[2]

        def body(c):
            d, k, _ = c
            e = step(d)
            return e, k + 1, jnp.any(e < d)

        run = jax.jit(lambda d: jax.lax.while_loop(cond, body, (d, 0, True))[:2])
    else:
        run = jax.jit(lambda d: (jax.lax.fori_loop(0, iterations, lambda _, d: step(d), d), iterations))
    jax.block_until_ready(run(d0))
    t0 = time.perf_counter()
    d, k = jax.block_until_ready(run(d0))
    return np.asarray(d).T, int(k), time.perf_counter() - t0


def jax_check(shape, k, rng):
    """The min-plus rows of the fps sources of one mesh against Dijkstra's: steps to the fixed
    point, the largest relative error, seconds (after compilation), and the mean geodesic."""
    v, f = baselines.split_geometry(shape)
    g, _, w, _, _ = mesh_graph(v, f)
    t0 = time.perf_counter()
    rows, src = fps_rows(g, w, k, rng, with_sources=True)
    t_dij = time.perf_counter() - t0
    mine, steps, t_jax = minplus_rows(g, src)
    err = float(np.max(np.abs(mine - rows) / np.maximum(rows, 1e-12 + rows.max() * 1e-6)))
    a = voronoi_weights(rows, w)
    return {"vertices": int(len(w)), "edges": int(g.nnz // 2), "steps": steps, "max_rel_error": err,
            "jax_seconds": t_jax, "dijkstra_fps_seconds": t_dij,
            "mean_dijkstra": sizes(rows, w, a)["mean"], "mean_jax": sizes(mine, w, a)["mean"]}


# ------------------------------------------------------------------ one shape, one class
def shape_sizes(shape, args, rng, shared=None):
    """{candidate: size} and {part: seconds} of one shape (module docs)."""
    ks = [int(k) for k in args.k.split(",")]
    out, sec = {}, {}
    t0 = time.perf_counter()
    _, scale, sol = robust_center_scale(shape)
    sec["robust"] = time.perf_counter() - t0
    out["robust"] = float(scale)
    v, f = baselines.split_geometry(shape)
    schemes = args.sources.split(",")
    if f is not None:
        out["sqrt_area"] = float(np.sqrt(shape.area))
        g, vk, w, keep, fk = mesh_graph(v, f)
        sh = None
        if shared is not None:
            sh = np.searchsorted(keep, shared)
            sh = sh if np.array_equal(keep[np.minimum(sh, len(keep) - 1)], shared) else None
        vals, s = all_sizes(g, w, ks, schemes, rng, sh)
        out.update({f"mesh:{key}": val for key, val in vals.items()})
        sec.update({f"mesh:{key}": val for key, val in s.items()})
        if args.uniform:  # the vertices weighted alike, as a point cloud's are (fps sources)
            vals, _ = all_sizes(g, np.full(len(w), 1.0 / len(w)), [max(ks)], ["fps"], rng)
            out.update({f"mesh_uniform:{key}": val for key, val in vals.items()})
        if args.heat:  # heat-method geodesics (potpourri3d, not a jaxpose dependency) from fps sources
            import potpourri3d as pp3d

            t0 = time.perf_counter()
            rows, src = fps_rows(g, w, args.heat, rng, with_sources=True)
            solver = pp3d.MeshHeatMethodDistanceSolver(vk, fk, use_robust=True)
            heat = np.array([solver.compute_distance(int(i)) for i in src])
            out.update({f"heat:fps{args.heat}:{key}": val for key, val in sizes(heat, w, voronoi_weights(heat, w)).items()})
            sec["heat"] = time.perf_counter() - t0
        if args.diagonals:
            g2, _, w2, _, _ = mesh_graph(v, f, diagonals=True)
            vals, s = all_sizes(g2, w2, [max(ks)], ["fps"], rng)
            out.update({f"diag:{key}": val for key, val in vals.items()})
            sec.update({f"diag:{key}": val for key, val in s.items()})
    else:
        for k in [int(x) for x in args.knn.split(",")]:
            t0 = time.perf_counter()
            g, pk, w, _ = knn_graph(v, k)
            vals, s = all_sizes(g, w, [max(ks)], ["fps"], rng)
            out.update({f"knn{k}:{key}": val for key, val in vals.items()})
            sec[f"knn{k}"] = time.perf_counter() - t0
    if args.voxel:
        t0 = time.perf_counter()
        g, _, w, _ = voxel_graph(sol)
        vals, _ = all_sizes(g, w, [args.voxel_k], ["fps"], rng)
        out.update({f"voxel:{key}": val for key, val in vals.items()})
        sec["voxel"] = time.perf_counter() - t0
        out["voxel:count"] = float(len(w))
    return out, sec


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.geodesic_scale")
    p.add_argument("--variants", default="plain")
    p.add_argument("--classes", default=",".join(CLASSES))
    p.add_argument("--k", default="64,128,256", help="numbers of sources (nested: the first K of one sequence)")
    p.add_argument("--sources", default="fps,random,shared", help="source schemes: fps, random, shared (plain only)")
    p.add_argument("--knn", default="8,12", help="k of the point clouds' k-NN graphs")
    p.add_argument("--uniform", action="store_true", help="meshes also with every vertex weighted alike (as clouds)")
    p.add_argument("--diagonals", action="store_true", help="also the edge graph with flip diagonals (zig-zag check)")
    p.add_argument("--heat", type=int, default=0,
                   help="also heat-method geodesics (potpourri3d; not a jaxpose dependency) from this many fps sources")
    p.add_argument("--voxel", action="store_true", help="also the inner distance in the robust solid's voxels")
    p.add_argument("--voxel-k", type=int, default=64)
    p.add_argument("--jax", type=int, default=0, metavar="K",
                   help="only: the JAX min-plus relaxation from K fps sources on the first plain mesh of each class "
                        "against Dijkstra (steps, error, seconds)")
    p.add_argument("--every", type=int, default=1)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", default=None)
    p.add_argument("--summary", nargs="+", default=None, metavar="JSON",
                   help="print the compact tables of earlier --json records (nothing measured)")
    args = p.parse_args(argv)
    if args.summary:
        record = {}
        for path in args.summary:
            for variant, classes in json.loads(Path(path).read_text()).items():
                record.setdefault(variant, {}).update(classes)
        summary(record)
        return 0
    if not SHARED.is_dir():
        print(f"no {SHARED}: nothing to measure", file=sys.stderr)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        classes = dev_classes(tmp, args.classes.split(","), args.every)
    record = {}
    if args.jax:
        for name, meshes in classes.items():
            out = jax_check(meshes[0], args.jax, np.random.default_rng([args.seed, CLASSES.index(name) % 2, 0]))
            record[name] = out
            print(name, "  ".join(f"{key} {val:.4g}" if isinstance(val, float) else f"{key} {val}" for key, val in out.items()))
            sys.stdout.flush()
        if args.json:
            Path(args.json).write_text(json.dumps(record, indent=1))
        return 0
    for variant in args.variants.split(","):
        record[variant] = {}
        for name, meshes in classes.items():
            k = CLASSES.index(name) % 2  # the class index of jaxpose evaluate on its dataset
            shapes = make_class(meshes, variant, 0, k)
            shared = None
            if variant == "plain" and "shared" in args.sources:
                m0 = meshes[0]
                va = np.bincount(np.asarray(m0.faces).ravel(), weights=np.repeat(m0.area_faces, 3) / 3.0,
                                 minlength=len(m0.vertices))
                kmax = max(int(x) for x in args.k.split(","))
                shared = np.random.default_rng([args.seed, k]).choice(len(va), size=kmax, p=va / va.sum())
            per, secs = [], []
            for i, shape in enumerate(shapes):
                rng = np.random.default_rng([args.seed, k, i])
                out, sec = shape_sizes(shape, args, rng, shared)
                per.append(out)
                secs.append(sec)
            cands = list(per[0])
            cv = {c: scale_spread(np.array([o[c] for o in per]))["cv_scale"] for c in cands}
            seconds = {key: float(np.mean([s[key] for s in secs])) for key in secs[0]}
            record[variant][name] = {"cv": cv, "values": {c: [o[c] for o in per] for c in cands},
                                     "seconds_per_shape": seconds}
            report(variant, name, cv, seconds, per)
            if args.json:
                Path(args.json).write_text(json.dumps(record, indent=1))
    return 0


def _cv(values):
    return scale_spread(np.asarray(values, np.float64))["cv_scale"]


def summary(record):
    """Compact tables of a record: per variant and class the cv of the baselines and of each
    candidate at its largest K, the best candidate's ratio to the best baseline; on plain meshes
    also the convergence in K, the pose dependence of the edge graph's overestimate (against the
    graph with diagonals and the heat method) and the seconds per shape."""
    if "points" in record and "plain" in record:
        print("\nshortcuts: per pose the k-NN graph's mean geodesic over the mesh's with the vertices weighted "
              "alike (mesh_uniform, same sources scheme); mean ratio, its cv, its min and max")
        for n, cell in record["points"].items():
            plain = record["plain"].get(n, {}).get("values", {})
            ref = next((c for c in plain if c.startswith("mesh_uniform:") and c.endswith(":mean")), None)
            if ref is None:
                continue
            parts = []
            for c in (c for c in cell["values"] if c.startswith("knn") and c.endswith(":mean")):
                r = np.asarray(cell["values"][c]) / np.asarray(plain[ref])
                parts.append(f"{c.split(':')[0]}: {r.mean():.4f} cv {_cv(r):.5f} [{r.min():.3f}, {r.max():.3f}]")
            print(f"  {n:9s} " + "  ".join(parts))
    for variant, classes in record.items():
        names = list(classes)
        cands = []
        for name in names:
            for c in classes[name]["cv"]:
                if c not in cands and not c.endswith(":count"):
                    cands.append(c)
        # keep each family's largest K only
        def fam(c):
            head, _, size = c.rpartition(":")
            stem = head.rstrip("0123456789")
            return stem, size, int(head[len(stem):] or 0)
        best_k = {}
        for c in cands:
            if ":" in c:
                stem, size, k = fam(c)
                best_k[stem, size] = max(best_k.get((stem, size), 0), k)
        shown = [c for c in cands if ":" not in c or fam(c)[2] == best_k[fam(c)[:2]]]
        print(f"\n## {variant}: cv per class (population std / mean over the poses)\n")
        print("| candidate | " + " | ".join(names) + " |")
        print("|---|" + "---|" * len(names))
        for c in shown:
            print(f"| {c} | " + " | ".join(f"{classes[n]['cv'][c]:.5f}" if c in classes[n]["cv"] else "n/a"
                                          for n in names) + " |")
        lows = {n: min(classes[n]["cv"][b] for b in ("robust", "sqrt_area") if b in classes[n]["cv"]) for n in names}
        geo = [c for c in shown if ":" in c]
        print("| best baseline (min of robust, sqrt_area) | " + " | ".join(f"{lows[n]:.5f}" for n in names) + " |")
        for n in names:
            have = [c for c in geo if c in classes[n]["cv"]]
            if have:
                c = min(have, key=lambda c: classes[n]["cv"][c])
                print(f"  {n}: best geodesic {c} cv {classes[n]['cv'][c]:.5f} = {classes[n]['cv'][c] / lows[n]:.2f} x the best baseline")
        if variant != "plain":
            continue
        print("\nconvergence (fps and random mean: cv at K; mean |value(K) / value(K max) - 1| over the poses)")
        for n in names:
            v = classes[n]["values"]
            for scheme in ("fps", "random", "shared"):
                ks = sorted(int(c.split(":")[1][len(scheme):]) for c in v if c.startswith(f"mesh:{scheme}") and c.endswith(":mean"))
                if not ks:
                    continue
                top = np.asarray(v[f"mesh:{scheme}{ks[-1]}:mean"])
                print(f"  {n:9s} {scheme:6s} " + "  ".join(
                    f"K={k}: cv {_cv(v[f'mesh:{scheme}{k}:mean']):.5f} dev {np.mean(np.abs(np.asarray(v[f'mesh:{scheme}{k}:mean']) / top - 1)):.4f}"
                    for k in ks))
        print("\nzig-zag: cv over the poses of the edge graph's mean geodesic over another's (pose dependence of the overestimate)")
        for n in names:
            v = classes[n]["values"]
            k = max(int(c.split(":")[1][3:]) for c in v if c.startswith("mesh:fps") and c.endswith(":mean"))
            mine = np.asarray(v[f"mesh:fps{k}:mean"])
            parts = []
            for other in [c for c in v if (c.startswith("diag:") or c.startswith("heat:")) and c.endswith(":mean")]:
                kk = int(other.split(":")[1][3:])
                base = np.asarray(v[f"mesh:fps{kk}:mean"]) if f"mesh:fps{kk}:mean" in v else mine
                r = base / np.asarray(v[other])
                parts.append(f"{other}: ratio {r.mean():.4f}, cv of the ratio {_cv(r):.5f}")
            print(f"  {n:9s} " + ";  ".join(parts))
        g = next((c for c in ("mesh:fps256:mean", "mesh:fps128:mean", "mesh:fps64:mean") if c in classes[names[0]]["values"]), None)
        if g is not None:
            ws = np.round(np.arange(0.0, 1.01, 0.1), 1)
            print(f"\nblend V^(w/3) G^(1-w) (G = {g}; w = 1 the robust scale): cv per w; corr and slope of log G "
                  "against log V^(1/3) and log sqrt(A)")
            print("| class | " + " | ".join(f"w={w}" for w in ws) + " | corr(G, V^1/3) | slope | corr(G, sqrtA) | slope |")
            print("|---|" + "---|" * (len(ws) + 4))
            for n in names:
                v = classes[n]["values"]
                lg, lv, la = (np.log(np.asarray(v[c])) for c in (g, "robust", "sqrt_area"))
                cells = [f"{_cv(np.exp(w * lv + (1 - w) * lg)):.5f}" for w in ws]
                extra = []
                for other in (lv, la):
                    cc = np.corrcoef(lg, other)[0, 1]
                    extra += [f"{cc:+.2f}", f"{np.polyfit(other, lg, 1)[0]:.2f}"]
                print(f"| {n} | " + " | ".join(cells + extra) + " |")
        print("\nseconds per shape")
        for n in names:
            print(f"  {n:9s} " + "  ".join(f"{k} {s:.2f}" for k, s in classes[n]["seconds_per_shape"].items()))


def report(variant, name, cv, seconds, per):
    base = {c: cv[c] for c in ("robust", "sqrt_area") if c in cv}
    low = min(base.values())
    print(f"\n{variant} {name}: n={len(per)}  " + "  ".join(f"{c} {v:.5f}" for c, v in base.items())
          + f"   (best baseline {low:.5f}; 1.05x = {1.05 * low:.5f})")
    rows = sorted((c for c in cv if c not in base and not c.endswith(":count")), key=lambda c: cv[c])
    for c in rows:
        print(f"  {c:28s} cv {cv[c]:.5f}  x{cv[c] / low:5.2f}  mean {np.mean([o[c] for o in per]):.4g}")
    print("  seconds/shape: " + "  ".join(f"{key} {v:.2f}" for key, v in seconds.items()))
    sys.stdout.flush()


if __name__ == "__main__":
    raise SystemExit(main())
