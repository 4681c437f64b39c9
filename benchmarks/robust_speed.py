"""The robust estimator through JAX (host solid, then depth, weights and moments in JAX) against the
NumPy/SciPy reference, side by side in one process, and its derivative in the power.

``python -m benchmarks.robust_speed [--json OUT] [--repeats 7] [--meshes PATH ...] [--no-gradients]``

1. Speed: on one FAUST and one KIDS mesh (``../shared``; the built-in example shape without it),
   per mesh and interleaved (the cases share the machine's state): the NumPy reference (the robust
   solid, ``scipy.ndimage.distance_transform_edt``, the depth^4-weighted centroid in NumPy: the
   package's code before the JAX pipeline, frozen here as :func:`numpy_robust`), the JAX path
   (the host solid, then ``moments.solid_moments``) and the package's host estimator
   (``estimators.robust_center_scale``, NumPy); medians of warm runs, their ratio, the first call's extra
   time (compilation, once per grid bucket: a bucket not seen before is timed separately), and
   the parts: the host solid alone, the NumPy depth + centroid, the JAX depth + weights + moments.
2. Agreement: the two centers (relative to the scale) and scales.
3. Gradients: ``jax.jacfwd`` of the center and ``jax.grad`` of the scale in the power at p = 4,
   against central differences at 1 % of p.

Prints markdown; asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy import ndimage

from benchmarks.common import faust_dir, interleaved, now

ROOT = Path(__file__).resolve().parents[1]
KIDS = ROOT.parent / "shared" / "data" / "kids-dev" / "kid_0001" / "pose_00.ply"
POWER = 4.0


def default_meshes():
    """[(name, path or None)]: FAUST tr_reg_000 and a KIDS mesh when ../shared is there, else the example shape."""
    out = []
    d = faust_dir()
    if d is not None:
        out.append(("faust/tr_reg_000", d / "tr_reg_000.ply"))
    if KIDS.exists():
        out.append(("kids/kid_0001/pose_00", KIDS))
    return out or [("example_shape", None)]


def numpy_robust(geometry, power=POWER):
    """The robust center and scale as the package computed them before the JAX pipeline (frozen
    reference): the host solid, scipy's distance transform minus the solid's bias, the
    depth^p-weighted centroid and the solid's volume in NumPy float64."""
    from jaxpose.pose import estimators
    from jaxpose.occupancy import solid

    sol = estimators._robust_solid(geometry, solid.RESOLUTION)
    return numpy_moments(sol, power)


def numpy_moments(sol, power=POWER):
    d = np.maximum(ndimage.distance_transform_edt(sol.inside) - sol.bias, 0.0) * sol.pitch
    d = d[sol.inside]
    w = (d / d.max()) ** float(power) if d.max() > 0 else np.ones_like(d)
    return (w @ sol.centers()) / w.sum(), sol.volume() ** (1.0 / 3.0)


def jax_robust(geometry, power=POWER):
    """The robust center and scale through JAX: the host solid, then ``moments.solid_moments``
    (depth, weights and moments in JAX), mapped to the world in float64."""
    import jax

    from jaxpose import moments
    from jaxpose.occupancy import solid
    from jaxpose.pose import estimators

    sol = estimators._robust_solid(geometry, solid.RESOLUTION)
    mom = jax.block_until_ready(moments.solid_moments(sol, power))
    center = (sol.origin + sol.pitch * np.asarray(mom.center, np.float64)) @ sol.frame
    return center, (float(mom.volume) * sol.pitch**3) ** (1.0 / 3.0)


def host_robust(geometry, power=POWER):
    """The package's robust estimator on the host (``estimators.robust_center_scale``: NumPy, no JAX)."""
    from jaxpose.pose import estimators

    center, scale, _ = estimators.robust_center_scale(geometry, power)
    return center, scale


def speed(name, geometry, repeats):
    import jax

    from jaxpose import moments
    from jaxpose.pose import estimators
    from jaxpose.occupancy import solid
    from jaxpose.depth import to_bucket

    sol = estimators._robust_solid(geometry, solid.RESOLUTION)
    bucket = to_bucket(sol.inside)[0].shape
    cases = {
        "numpy": lambda: numpy_robust(geometry),
        "jax": lambda: jax_robust(geometry),
        "host (package)": lambda: host_robust(geometry),
        "solid (host)": lambda: estimators._robust_solid(geometry, solid.RESOLUTION),
        "numpy depth+centroid": lambda: numpy_moments(sol),
        "jax depth+weights+moments": lambda: jax.block_until_ready(moments.solid_moments(sol, POWER)),
    }
    t = now()
    jax.block_until_ready(moments.solid_moments(sol, POWER))  # this bucket's first call: compiles
    compile_s = now() - t
    stats, last = interleaved(cases, repeats)
    (c0, s0), (c1, s1) = last["numpy"], last["jax"]
    return {"mesh": name, "grid": list(sol.inside.shape), "bucket": list(bucket), "voxels": int(sol.inside.sum()),
            "first_call_s": compile_s, "stats": stats, "ratio": stats["jax"]["median_s"] / stats["numpy"]["median_s"],
            "center_diff_rel": float(np.max(np.abs(np.asarray(c1) - np.asarray(c0))) / s0),
            "scale_diff_rel": float(abs(s1 / s0 - 1.0))}


def gradients(name, geometry, step=0.01):
    import jax
    import jax.numpy as jnp

    from jaxpose import moments
    from jaxpose.pose import estimators
    from jaxpose.occupancy import solid

    sol = estimators._robust_solid(geometry, solid.RESOLUTION)

    def center_scale(p):  # world units (the affine map of the voxel units, in JAX's float)
        mom = moments.solid_moments(sol, p)
        frame = jnp.asarray(sol.frame, mom.center.dtype)
        return (sol.origin + sol.pitch * mom.center) @ frame, sol.pitch * mom.volume ** (1.0 / 3.0)

    grad_c = np.asarray(jax.jacfwd(lambda p: center_scale(p)[0])(POWER), float)
    grad_s = float(jax.grad(lambda p: center_scale(p)[1])(POWER))
    hi, lo = center_scale(POWER * (1 + step)), center_scale(POWER * (1 - step))
    fd_c = (np.asarray(hi[0], float) - np.asarray(lo[0], float)) / (2 * step * POWER)
    fd_s = (float(hi[1]) - float(lo[1])) / (2 * step * POWER)
    rel = float(np.linalg.norm(grad_c - fd_c) / max(np.linalg.norm(fd_c), 1e-300))
    return {"mesh": name, "grad_center": grad_c.tolist(), "fd_center": fd_c.tolist(), "center_rel_err": rel,
            "grad_scale": grad_s, "fd_scale": fd_s, "finite": bool(np.all(np.isfinite(grad_c)) and np.isfinite(grad_s))}


def load(path):
    from jaxpose.pose import estimators
    from jaxpose import mesh

    geometry = mesh.example_shape() if path is None else mesh.load(path)
    return estimators.centered(geometry)[0]


def run(meshes=None, repeats=7, with_gradients=True):
    import jax

    meshes = default_meshes() if meshes is None else meshes
    out = {"backend": jax.default_backend(), "x64": bool(jax.config.jax_enable_x64), "repeats": int(repeats),
           "speed": [], "gradients": []}
    for name, path in meshes:
        geometry = load(path)
        out["speed"].append(speed(name, geometry, repeats))
        if with_gradients:
            out["gradients"].append(gradients(name, geometry))
    return out


def markdown(result):
    lines = [f"backend {result['backend']}, x64 {result['x64']}, {result['repeats']} warm runs per case (medians, ms)", "",
             "| mesh | grid (bucket) | NumPy robust | JAX robust | ratio | first JAX call (compile) | host solid | "
             "NumPy depth+centroid | JAX depth+weights+moments | center diff / scale | scale diff |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["speed"]:
        s = r["stats"]
        ms = lambda k: f"{1e3 * s[k]['median_s']:.1f}"
        lines.append(f"| {r['mesh']} | {'x'.join(map(str, r['grid']))} ({'x'.join(map(str, r['bucket']))}) | "
                     f"{ms('numpy')} | {ms('jax')} | {r['ratio']:.2f} | {1e3 * r['first_call_s']:.0f} | "
                     f"{ms('solid (host)')} | {ms('numpy depth+centroid')} | {ms('jax depth+weights+moments')} | "
                     f"{r['center_diff_rel']:.1e} | {r['scale_diff_rel']:.1e} |")
    if result["gradients"]:
        lines += ["", "| mesh | d center / dp (jax) | d center / dp (1 % central differences) | rel. error | "
                      "d scale / dp (jax, differences) |", "|---|---|---|---|---|"]
        for g in result["gradients"]:
            fmt = lambda v: "[" + ", ".join(f"{x:.3e}" for x in v) + "]"
            lines.append(f"| {g['mesh']} | {fmt(g['grad_center'])} | {fmt(g['fd_center'])} | {g['center_rel_err']:.3f} | "
                         f"{g['grad_scale']:.1e}, {g['fd_scale']:.1e} |")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m benchmarks.robust_speed", description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", help="write the result here")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--meshes", nargs="*", help="mesh files (default: a FAUST and a KIDS mesh, or the example shape)")
    parser.add_argument("--no-gradients", action="store_true")
    args = parser.parse_args(argv)
    meshes = None if not args.meshes else [(Path(p).name, Path(p)) for p in args.meshes]
    result = run(meshes, args.repeats, not args.no_gradients)
    print(markdown(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
