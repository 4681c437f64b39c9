"""Write the notebooks of this folder (without outputs): ``python notebooks/_build.py``.

Every notebook starts with a parameter cell (sizes); the tests run every notebook as written, at
that size, so each stays within a few minutes on 2 CPU cores.
"""
from __future__ import annotations

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).resolve().parent

PARAMS = '''COUNT = 1500        # surface samples per object (OCSVM)
RESOLUTION = 32     # grid resolution of the OCSVM volume integrals'''

SETUP = '''%matplotlib inline
import numpy as np
import matplotlib.pyplot as plt
import jaxpose
from jaxpose import plot'''

QUICKSTART = [
    new_markdown_cell("# jaxpose quickstart\n\n"
                      "A canonical position and size for a 3D shape. The default estimator (`robust`) weighs a robust "
                      "solid of the shape by its depth: the deep part, which moves least when a body articulates, sets "
                      "the center, and the solid's volume sets the scale; it works on closed meshes, meshes with holes "
                      "or stray parts, and point clouds. The paper's one-class SVM method is `method=\"ocsvm\"`: the "
                      "centroid of the *volume* the OCSVM encloses (eq. 4) and its mean distance (eq. 5)."),
    new_code_cell(PARAMS),
    new_code_cell(SETUP),
    new_markdown_cell("## A shape with an outlying arm\n\nA capsule body with a thin arm and a ball at its end: "
                      "the kind of part that drags centroids away from the body."),
    new_code_cell('''from jaxpose.mesh import example_shape
shape = example_shape()
normalized, pose = jaxpose.normalize_mesh(shape)                 # the robust default
_, paper = jaxpose.normalize_mesh(shape, method="ocsvm", count=COUNT, resolution=RESOLUTION)
print("robust center", np.round(pose.center, 4), "scale", round(float(pose.scale), 4))
print("ocsvm  center", np.round(np.asarray(paper.center), 4), "scale", round(float(paper.scale), 4))'''),
    new_markdown_cell("## Before and after\n\n`normalize_mesh` returns the transformed copy: center at the origin, "
                      "volume 1 for the robust scale."),
    new_code_cell('''fig, axes = plt.subplots(1, 2, figsize=(9, 4.5), subplot_kw={"projection": "3d"})
plot.mesh_3d(shape, axes[0], title="input")
plot.mesh_3d(normalized, axes[1], color="tab:blue", title="normalized (robust)")
axes[1].scatter([0], [0], [0], c="k", marker="+", s=60)
fig'''),
    new_markdown_cell("## The OCSVM region for two settings (the paper's Fig. 3)\n\n"
                      "Slices of the decision function through the region's center; orange: f ≥ 0, black "
                      "dots: samples near the slice. A small γ gives a smooth, sphere-like region; a large ν "
                      "lets the region drop a large share of the samples."),
    new_code_cell('''points = np.asarray(jaxpose.sample_surface(shape, COUNT, seed=0))
fig, axes = plt.subplots(2, 3, figsize=(12, 7), layout="constrained")
plot.region_slices(points, 15.0, 0.02, ax=axes[0], pixels=100, resolution=RESOLUTION)
plot.region_slices(points, 45.0, 0.8, ax=axes[1], pixels=100, resolution=RESOLUTION)
fig'''),
    new_markdown_cell("## Every center at once\n\nThe dashed circle has the OCSVM scale as its radius."),
    new_code_cell('''plot.centers_plot(shape, paper, count=COUNT)'''),
    new_code_cell('''from jaxpose.pose import estimators
for method in ("robust", "ocsvm", "surface_centroid", "solid", "bbox", "min_ball"):
    fit = dict(count=COUNT, ocsvm={"resolution": RESOLUTION}) if method == "ocsvm" else {}  # (the OCSVM's options)
    p = estimators.estimate(shape, method, **fit)
    print(f"{method:18s}", np.round(np.asarray(p.center, float), 4), round(float(p.scale), 4))'''),
]

GRADIENTS = [
    new_markdown_cell("# Gradients and tuning\n\n"
                      "`jaxpose.normalize` is a JAX function of (points, γ, ν): the pose can be differentiated "
                      "with respect to the parameters, and the parameters tuned by gradient descent on the "
                      "within-class spread of the centers."),
    new_code_cell(PARAMS + '''
SMALL = True                         # the sizes below the notebook runs at
CLASSES = 2 if SMALL else 4           # classes of the built-in dataset used below
INSTANCES = 3 if SMALL else 6         # objects per class
STEPS = 2 if SMALL else 15            # tuning steps'''),
    new_code_cell(SETUP + '''
import jax
from jaxpose import datasets, evaluation
from jaxpose.mesh import example_shape
points = np.asarray(jaxpose.sample_surface(example_shape(), COUNT, seed=0))'''),
    new_markdown_cell("## Derivatives of the pose in γ and ν\n\n"
                      "`jaxpose.pose.sensitivity.pose_sensitivity` gives d center / dγ, d scale / dγ and the same "
                      "for ν: by default the trend of the pose over γ(1 ± 1 %) and ν(1 ± 1 %) (secant slopes "
                      "of the SVDD solution; `derivative=\"exact\"` gives the local implicit derivative, see "
                      "docs/design.md). `jax.grad` of `jaxpose.normalize` gives the same derivatives."),
    new_code_cell('''from jaxpose.pose.sensitivity import pose_sensitivity
sens = pose_sensitivity(points, 47.0, 0.5, resolution=RESOLUTION)
for k in ("center", "scale", "dcenter_dgamma", "dscale_dgamma", "dcenter_dnu", "dscale_dnu"):
    print(f"{k:15s}", np.round(np.asarray(sens[k]), 5))'''),
    new_markdown_cell("The same with `jax.grad` directly, beside a central finite difference at a step of 1 % of γ. "
                      "They differ by the grid's steps: at `RESOLUTION = 32` cells the volume integrals move in small "
                      "jumps as γ changes, and a finite difference over ±1 % reads them (with the 1,500 samples above, 9 % "
                      "off `jax.grad`, which gives the secant trend of the cell above); at 64 cells they agree within 1 %:"),
    new_code_cell('''scale_of = lambda g: jaxpose.normalize(points, method="ocsvm", gamma=g, nu=0.5, resolution=RESOLUTION).scale
g0 = 47.0
h = 0.01 * g0
print("jax.grad           ", float(jax.grad(scale_of)(g0)))
print("finite difference  ", float((scale_of(g0 + h) - scale_of(g0 - h)) / (2 * h)))'''),
    new_markdown_cell("## How the pose moves with γ\n\nThe OCSVM center's x coordinate (the arm is along +x) and "
                      "the scale over γ; small γ approaches the minimum enclosing ball."),
    new_code_cell('''gammas = [2.0, 10.0, 30.0, 47.0] if SMALL else [1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 40.0, 47.0, 60.0]
poses = [jaxpose.normalize(points, method="ocsvm", gamma=g, nu=0.5, resolution=RESOLUTION) for g in gammas]
fig, axes = plt.subplots(1, 2, figsize=(9, 3.2), layout="constrained")
axes[0].plot(gammas, [float(p.center[0]) for p in poses], "o-")
axes[0].set(xlabel="γ", ylabel="center x")
axes[1].plot(gammas, [float(p.scale) for p in poses], "o-")
axes[1].set(xlabel="γ", ylabel="scale")
fig'''),
    new_markdown_cell("## σ_tr against γ and ν (the paper's Fig. 5) on a small subset\n\n"
                      "σ_tr is the RMS distance of a class's OCSVM centers from their mean (objects of a class "
                      "share the pose of their rigid core); blue OCSVM, red the surface centroid."),
    new_code_cell('''data = datasets.make_dataset(seed=0, instances=INSTANCES, classes=datasets.CLASSES[:CLASSES])
sweeps = {
    "gamma": evaluation.sweep(data, "gamma", values=[2.0, 10.0, 47.0] if SMALL else None,
                              count=COUNT, resolution=RESOLUTION),
    "nu": evaluation.sweep(data, "nu", values=[0.1, 0.5] if SMALL else None, count=COUNT, resolution=RESOLUTION),
}
plot.sweep_curves(sweeps)'''),
    new_markdown_cell("## Tuning γ and ν by gradient descent\n\n"
                      "`jaxpose.tuning.tune` minimises the mean within-class σ_tr with Adam in (log γ, logit ν), "
                      "sampling the meshes afresh at every step, and keeps the start unless the tuned parameters "
                      "lower the spread of held-out classes (here: a fresh draw of the same classes)."),
    new_code_cell('''from jaxpose import tuning
run = tuning.tune(data, steps=STEPS, lr=0.05, count=COUNT // 2, resolution=RESOLUTION)
traj = run["trajectory"]
fig, axes = plt.subplots(1, 3, figsize=(11, 3), layout="constrained")
for a, key in zip(axes, ("sigma_tr", "gamma", "nu")):
    a.plot([t["step"] for t in traj], [t[key] for t in traj], "o-")
    a.set(xlabel="step", ylabel=key)
print(f"gamma {run['gamma0']:g} -> {run['tuned']['gamma']:.3f}, nu {run['nu0']:g} -> {run['tuned']['nu']:.3f}, "
      f"sigma_tr {run['train']['sigma_tr_start']:.5f} -> {run['train']['sigma_tr_tuned']:.5f}")
print(run["verdict"])
fig'''),
]

EVALUATION = [
    new_markdown_cell("# Consistency on the built-in dataset (the paper's sec. 4)\n\n"
                      "Procedural classes; inside a class every object shares the pose of its rigid core, so a "
                      "consistent normalization gives them all the same center and scale. Lower σ_tr (spread of the "
                      "centers) and cv_scale (relative spread of the scales) is better. Every method runs on the "
                      "meshes as given and on seeded variants: with a stray part, with holes, and as point clouds."),
    new_code_cell(PARAMS + '''
CLASSES = 4                          # of the 12 procedural classes
INSTANCES = 5                        # objects per class
METHODS = ["robust", "ocsvm", "surface_centroid", "solid", "solid_sqrt_area", "depth_weighted_solid:4"]
VARIANTS = ["plain", "big_outliers", "holes", "points"]'''),
    new_code_cell(SETUP + '''
from jaxpose import datasets, evaluation'''),
    new_code_cell('''data = datasets.make_dataset(seed=0, instances=INSTANCES, classes=datasets.CLASSES[:CLASSES])
result = evaluation.evaluate(data, methods=METHODS, variants=VARIANTS, count=COUNT, resolution=RESOLUTION)
print(evaluation.format_table(result))'''),
    new_markdown_cell("## Per variant: σ_tr and cv_scale of every method"),
    new_code_cell('''plot.variant_bars(result, metric="sigma_tr")'''),
    new_code_cell('''plot.variant_bars(result, metric="cv_scale")'''),
    new_markdown_cell("## Per class on the plain meshes (Fig. 7)"),
    new_code_cell('''plot.scale_bars(result, metric="sigma_tr", methods=METHODS)'''),
    new_markdown_cell("## The OCSVM's parameters (Fig. 5)\n\nσ_tr of the `ocsvm` center as γ varies (ν = 0, as in "
                      "the paper), on two classes; the red line is the surface centroid."),
    new_code_cell('''subset = dict(list(data.items())[:2])
sweeps = {"gamma": evaluation.sweep(subset, "gamma", values=[5.0, 20.0, 47.0], count=COUNT, resolution=RESOLUTION)}
plot.sweep_curves(sweeps)'''),
    new_markdown_cell("## Pairs of normalized objects overlaid (Fig. 8)\n\nThe reference object of a class and a "
                      "deformed instance, each normalized on its own; top the robust default, bottom the surface "
                      "centroid and mean distance."),
    new_code_cell('''from jaxpose.pose import estimators
names = list(data)[:3]
pairs = [(data[c][0], data[c][-1]) for c in names]
robust = [[estimators.estimate(m) for m in p] for p in pairs]
surface = [[estimators.estimate(m, "surface_centroid") for m in p] for p in pairs]
plot.overlay_pairs(pairs, {"robust": robust, "surface": surface}, labels=names)'''),
    new_markdown_cell("## All figures to files\n\nWhat `jaxpose evaluate --variants ... --plots DIR` writes:"),
    new_code_cell('''import tempfile
out = tempfile.mkdtemp()
for p in plot.evaluation_figures(result, out):
    print(p.name)'''),
]

NOTEBOOKS = {
    "01_quickstart.ipynb": QUICKSTART,
    "02_gradients_and_tuning.ipynb": GRADIENTS,
    "03_evaluation.ipynb": EVALUATION,
}


def build(folder=HERE):
    for name, cells in NOTEBOOKS.items():
        nb = new_notebook(cells=cells, metadata={
            "kernelspec": {"display_name": "Python 3", "language": "python", "name": "python3"},
            "language_info": {"name": "python"}})
        for i, cell in enumerate(nb.cells):  # stable ids: rebuilding gives the same files
            cell["id"] = f"{Path(name).stem[:2]}-{i:02d}"
        nbformat.validate(nb)
        nbformat.write(nb, Path(folder) / name)


if __name__ == "__main__":
    build()
