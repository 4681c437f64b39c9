"""Render the README figures into docs/figures/ (the paper's Fig. 3, 5, 6, 7, 8 on our data).

    python docs/make_figures.py            # 12 classes x 6 instances, 600 samples (a few minutes on 2 cores)
    python docs/make_figures.py --small    # 4 classes x 4 instances, 300 samples (about a minute)

Writes regions.png (Fig. 3), centers.png, sweep_average.png (Fig. 5), sweep_per_class_nu.png and
sweep_per_class_gamma.png (Fig. 6), sigma_scale_bars.png (Fig. 7: OCSVM against the surface's mean
distance), consistency_plain.png (every method per class) and overlay_pairs.png (Fig. 8).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(HERE / "figures"))
    ap.add_argument("--small", action="store_true", help="4 classes x 4 instances, 300 samples")
    ap.add_argument("--instances", type=int, default=6)
    ap.add_argument("--count", type=int, default=600)
    ap.add_argument("--resolution", type=int, default=24, help="grid resolution of jaxpose.normalize")
    args = ap.parse_args(argv)

    import jaxpose
    from jaxpose import baselines, datasets, evaluation, plot
    from jaxpose.mesh import example_shape
    from matplotlib.figure import Figure

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    opts = {"resolution": args.resolution}
    classes = datasets.CLASSES[:4] if args.small else datasets.CLASSES
    instances, count = (4, 300) if args.small else (args.instances, args.count)

    def say(msg):
        print(f"[{time.perf_counter() - start:6.1f}s] {msg}", file=sys.stderr, flush=True)

    # Fig. 3: the region for the paper's two settings, on the example shape
    shape = example_shape()
    points = np.asarray(jaxpose.sample_surface(shape, count, 0))
    fig = Figure(figsize=(11, 6.5), layout="constrained")
    axes = fig.subplots(2, 3)
    plot.region_slices(points, 15.0, 0.02, ax=axes[0], **opts)
    plot.region_slices(points, 45.0, 0.8, ax=axes[1], **opts)
    fig.suptitle("OCSVM region (orange, f >= 0) through its center: γ=15, ν=0.02 (top), γ=45, ν=0.8 (bottom)")
    fig.savefig(out / "regions.png", dpi=70)
    say("regions.png")
    plot.centers_plot(shape, count=count, path=out / "centers.png", **opts)
    say("centers.png")

    # Fig. 5, 6, 7 on the procedural dataset
    data = datasets.make_dataset(seed=0, instances=instances, classes=classes)
    result = evaluation.evaluate(data, count=count, sweep=True, progress=say, **opts)
    print(evaluation.format_table(result))
    for p in plot.evaluation_figures(result, out):
        say(p.name)
    plot.scale_bars(result, path=out / "sigma_scale_bars.png")  # Fig. 7: two scales of the same kind
    say("sigma_scale_bars.png")

    # Fig. 8: pairs (reference, a deformed instance) normalized by OCSVM and by the surface
    # for each class, the instance whose surface centroid moved most from the reference's
    names = [c for c in ("human", "guitar", "horse", "dolphin", "chair") if c in data][:3]
    pairs = []
    for c in names:
        ref = baselines.center(data[c][0], "surface_centroid")
        moved = [np.linalg.norm(baselines.center(m, "surface_centroid") - ref) for m in data[c]]
        pairs.append((data[c][0], data[c][int(np.argmax(moved))]))
    ocsvm, surface = [], []
    for pair in pairs:
        ocsvm.append([jaxpose.normalize(np.asarray(jaxpose.sample_surface(m, count, 0)), method="ocsvm", **opts) for m in pair])
        surface.append([(c, baselines.scale(m, "mean_distance", c))
                        for m in pair for c in [baselines.center(m, "surface_centroid")]])
    plot.overlay_pairs(pairs, {"OCSVM": ocsvm, "surface": surface}, labels=names, path=out / "overlay_pairs.png")
    say("overlay_pairs.png")
    for p in sorted(out.glob("*.png")):
        print(f"{p}  {p.stat().st_size / 1024:.0f} KB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
