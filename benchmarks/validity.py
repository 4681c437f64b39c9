"""Which OCSVM poses are valid on real bodies (FAUST dev meshes), and the ratios behind the status.

For each case: the scale, the status, and the three ratios :mod:`jaxpose.pose.validity` compares
(sample spacing and finest cell in kernel widths, the region's mean distance over the samples'
median distance from its centroid), computed here again from the same pre-scaled samples.

Usage::

    python -m benchmarks.validity [--data /work/shared/data/faust-dev]

No timing; the figures go to ``docs/design.md`` (Errors and validity).
"""
from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import jax.numpy as jnp
import numpy as np

DATA = Path("/work/shared/data/faust-dev")


def ratios(points, gamma, nu, resolution):
    """(spacing, cell, spread) ratios of one case, as jaxpose.pose.validity computes them."""
    from jaxpose.config import GridConfig, SolverConfig
    from jaxpose.pose.frame import host_frame, prescale
    from jaxpose.moments import region_moments
    from jaxpose.occupancy.svdd import solve_svdd
    from jaxpose.pose.validity import median_distance, median_spacing

    c, s = host_frame(points)
    y = prescale(jnp.asarray((points - c) / s, jnp.float32))[0]
    svdd = solve_svdd(y, gamma, nu, None, None, SolverConfig())
    grid = GridConfig(resolution=resolution)
    mom = region_moments(svdd, grid)
    width = 1.0 / np.sqrt(2.0 * gamma)
    return (float(median_spacing(y)) / width, float(jnp.max(mom.cell)) / grid.refine / width,
            float(mom.mean_distance) / float(median_distance(y, mom.center)))


def main(argv=None):
    import jaxpose
    from jaxpose import mesh

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=DATA)
    args = p.parse_args(argv)
    files = sorted(args.data.glob("*.ply"))
    if not files:
        raise SystemExit(f"no meshes in {args.data}")
    warnings.simplefilter("ignore")
    body = mesh.load(files[0])
    print(f"{files[0].name}: count gamma nu resolution -> scale, status (spacing, cell, spread ratios)")
    cases = [(2000, 47.0, 0.5, 64), (2000, 47.0, 0.5, 16), (2000, 300.0, 0.5, 64), (2000, 1e3, 0.5, 32),
             (2000, 1e3, 0.5, 64), (2000, 1e4, 0.5, 64), (2000, 1e4, 0.5, 96), (4, 47.0, 0.5, 64),
             (5, 47.0, 0.5, 64), (16, 47.0, 0.5, 64), (64, 47.0, 0.5, 64), (2000, 47.0, 0.99, 64),
             (2000, 47.0, 1.0, 64)]
    for count, gamma, nu, res in cases:
        pts = np.asarray(jaxpose.sample_surface(body, count, seed=0))
        pose = jaxpose.normalize(pts, method="ocsvm", gamma=gamma, nu=nu, resolution=res)
        sp, cell, spread = ratios(pts, gamma, nu, res)
        print(f"  {count:5d} {gamma:7g} {nu:5g} {res:3d} -> {float(pose.scale):8.4f} "
              f"{jaxpose.Status(int(pose.status)).name:<17} ({sp:.2f}, {cell:.2f}, {spread:.2f})")
    print("every mesh at the defaults (2000 samples, gamma 47, nu 0.5):")
    worst = [0.0, 0.0, np.inf]
    for f in files:
        pts = np.asarray(jaxpose.sample_surface(mesh.load(f), 2000, seed=0))
        pose = jaxpose.normalize(pts, method="ocsvm")
        sp, cell, spread = ratios(pts, 47.0, 0.5, 64)
        worst = [max(worst[0], sp), max(worst[1], cell), min(worst[2], spread)]
        if int(pose.status):
            print(f"  {f.name}: {jaxpose.Status(int(pose.status)).name}")
    print(f"  {len(files)} meshes; largest spacing {worst[0]:.2f} and cell {worst[1]:.2f} kernel widths, "
          f"smallest spread ratio {worst[2]:.2f}")


if __name__ == "__main__":
    main()
