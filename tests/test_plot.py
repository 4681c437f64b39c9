"""jaxpose.plot: every figure draws on small inputs and writes a non-empty PNG."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import sphere_with_arm
from jaxpose import Pose
from jaxpose.errors import InvalidInputError

plot = pytest.importorskip("jaxpose.plot")

PNG = b"\x89PNG\r\n\x1a\n"


def _png(path):
    data = path.read_bytes()
    assert data[:8] == PNG and len(data) > 1000
    return data


@pytest.fixture(scope="module")
def shape():
    from jaxpose.mesh import example_shape

    return example_shape()


@pytest.fixture(scope="module")
def fake_result():
    rng = np.random.default_rng(0)
    classes = ("a", "b", "c")
    methods = ("ocsvm", "surface_centroid", "vertex_mean", "bbox", "min_ball")
    keys = ("sigma_tr", "sigma_tr_axis", "sigma_scale", "cv_scale")

    def cell():
        return {**{k: float(rng.uniform(0.01, 0.05)) for k in keys},
                "centers": rng.normal(size=(4, 3)).tolist(), "scales": rng.uniform(0.5, 1, 4).tolist()}

    def sweep(param, values, fixed):
        per = {c: {"sigma_tr": rng.uniform(0.01, 0.05, len(values)).tolist(),
                   "sigma_scale": rng.uniform(0.01, 0.05, len(values)).tolist()} for c in classes}
        ref = {c: {"sigma_tr": 0.03, "sigma_scale": 0.02} for c in classes}
        return {"param": param, "values": list(values), "fixed": fixed, "per_class": per,
                "average": {k: np.mean([per[c][k] for c in classes], axis=0).tolist() for k in ("sigma_tr", "sigma_scale")},
                "surface_centroid": {"per_class": ref, "average": {"sigma_tr": 0.03, "sigma_scale": 0.02}}}

    per_class = {c: {m: cell() for m in methods} for c in classes}
    return {"params": {"gamma": 47.0, "nu": 0.5, "count": 100, "seed": 0, "methods": list(methods),
                       "classes": list(classes)},
            "summary": [{"method": m, **{k: 0.02 for k in keys}, "seconds": 1.0} for m in methods],
            "per_class": per_class,
            "sweeps": {"gamma": sweep("gamma", (1.0, 10.0, 47.0), {"nu": 0.0}),
                       "nu": sweep("nu", (0.1, 0.3, 0.5), {"gamma": 47.0})}}


def test_region_slices_points_and_svdd(tmp_path):
    import jax.numpy as jnp

    import jaxpose

    # 400 points at resolution 32 (incidental): the fit and the pose are test_pinned.py's float32
    # programs (_solve_svdd at 400 rows, the OCSVM pose at 448 rows on that grid); 80 points at
    # resolution 16 compiled two of their own
    pts = sphere_with_arm(400)
    fig = plot.region_slices(pts, 15.0, 0.1, pixels=30, resolution=32, path=tmp_path / "r.png")
    assert len(fig.axes) == 3
    _png(tmp_path / "r.png")
    svdd = jaxpose.fit_svdd(jnp.asarray(pts), 20.0, 0.2)
    fig = plot.region_slices(svdd, planes=("xz",), pixels=20, center=np.zeros(3), path=tmp_path / "s.png")
    assert len(fig.axes) == 1
    _png(tmp_path / "s.png")


def test_region_slices_into_given_axes():
    from matplotlib.figure import Figure

    fig = Figure()
    axes = fig.subplots(2, 3)
    pts = sphere_with_arm(400)  # the size and grid of the test above: its compiled fit and pose are reused
    assert plot.region_slices(pts, 10.0, 0.1, pixels=16, resolution=32, ax=axes[1]) is fig
    with pytest.raises(InvalidInputError, match="2 axes for 3 planes"):
        plot.region_slices(pts, 10.0, 0.1, pixels=16, resolution=32, ax=axes[0][:2])


def test_mesh_3d_mesh_and_points(tmp_path, shape):
    fig = plot.mesh_3d(shape, path=tmp_path / "m.png", max_faces=300, title="shape")
    assert fig.axes[0].name == "3d"
    _png(tmp_path / "m.png")
    plot.mesh_3d(sphere_with_arm(50), path=tmp_path / "p.png")
    _png(tmp_path / "p.png")
    with pytest.raises(InvalidInputError, match=r"got shape \(4, 2\)"):
        plot.mesh_3d(np.zeros((4, 2)))


def test_centers_plot(tmp_path, shape):
    pose = ((0.2, 0.0, 0.0), 0.8)  # given: no fit needed
    plot.centers_plot(shape, pose, count=200, path=tmp_path / "c.png")
    _png(tmp_path / "c.png")
    plot.centers_plot(shape, pose, count=200, plane=None, methods=("surface_centroid",), path=tmp_path / "c3.png")
    _png(tmp_path / "c3.png")


_POINTS = np.random.default_rng(0).normal(size=(60, 3))


@pytest.mark.parametrize("call, message", [
    # a plane's KeyError ('zx') after the fit; max()'s 'zero-size array' ValueError; reshape's ValueError
    (lambda shape: plot.region_slices(_POINTS, planes=("xy", "zx")), "planes must be one of 'xy', 'xz', 'yz', got 'zx'"),
    (lambda shape: plot.region_slices(_POINTS, planes="xz"), r"planes must be a list of names, got the string 'xz'"),
    (lambda shape: plot.region_slices(_POINTS, pixels=0), "pixels must be >= 2, got 0"),
    (lambda shape: plot.region_slices(_POINTS, center=(0.0, 0.0)), "center must be 3 finite numbers"),
    # the NaN was counted after the points were rescaled by their NaN mean: 'points has 61 rows ...'
    (lambda shape: plot.region_slices(np.vstack([_POINTS, [np.nan] * 3])), "points has 1 row with NaN"),
    (lambda shape: plot.centers_plot(shape, ((0.0, 0.0, 0.0), 1.0), count=200, plane="zx"), "plane must be one of"),
    (lambda shape: plot.centers_plot(shape, (np.zeros((2, 3)), np.ones(2)), count=200, methods=()),
     r"a pose must be one center \(3,\) and a scale \(\) > 0.*got shapes \(2, 3\) and \(2,\)"),
    # a scale <= 0 or a NaN center reported 'got shapes (3,) and ()', the right shapes
    (lambda shape: plot.centers_plot(shape, ((0.0, 0.0, 0.0), -1.0), count=200, methods=()),
     r"^a pose's scale must be > 0, got -1.0$"),
    (lambda shape: plot.centers_plot(shape, ((np.nan, 0.0, 0.0), 1.0), count=200, methods=()),
     r"^an invalid pose: its center \[nan, 0.0, 0.0\] and scale 1.0 must be finite"),
    (lambda shape: plot.centers_plot(shape, Pose.from_center_scale(np.array([np.nan, 0.0, 0.0]), 1.0), count=200,
                                     methods=()), r"^an invalid pose, status \d+ \(.+\): its center \[nan"),
    (lambda shape: plot.mesh_3d("body.ply"), "expected a mesh or an \\(n, 3\\) array of points, got 'body.ply'"),
])
def test_bad_arguments_are_refused_by_name(call, message, shape):
    """The module's contract: bad arguments raise InvalidInputError (they were KeyError, NumPy's
    ValueErrors, or a wrong count), before any fit."""
    with pytest.raises(InvalidInputError, match=message):
        call(shape)


def test_overlay_pairs_turns_a_pose_with_a_rotation(monkeypatch, shape):
    """A Pose's rotation was left out: a pair normalized with rotation=True was drawn unturned."""
    from jaxpose import Pose

    q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))
    r = q * np.sign(np.linalg.det(q))
    pose = Pose.from_center_scale(np.array([0.1, 0.2, 0.3]), 2.0, rotation=r)
    drawn = []
    monkeypatch.setattr(plot, "mesh_3d", lambda s, *a, **k: drawn.append(np.asarray(s.vertices)))
    plot.overlay_pairs([(shape, shape)], [(pose, ((0.1, 0.2, 0.3), 2.0))])
    np.testing.assert_allclose(drawn[0], pose.apply(np.asarray(shape.vertices)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(drawn[1], (np.asarray(shape.vertices) - [0.1, 0.2, 0.3]) / 2.0, rtol=0, atol=1e-12)


def test_rotation_overlay_refuses_a_center_scale_pair(shape):
    """A (center, scale) pair for a pose was an AttributeError ('tuple' object has no attribute
    'apply'); it has no frame to overlay: InvalidInputError naming the pose and what to pass. One
    pose per mesh (zip dropped the extra meshes silently)."""
    from jaxpose import Pose

    with pytest.raises(InvalidInputError, match=r"poses\[1\] must be a Pose with its rotation .*got tuple"):
        plot.rotation_overlay([shape, shape], [Pose.from_center_scale(np.zeros(3), 1.0), ((0, 0, 0), 1.0)])
    with pytest.raises(InvalidInputError, match="1 poses for 2 meshes"):
        plot.rotation_overlay([shape, shape], [Pose.from_center_scale(np.zeros(3), 1.0)])


def test_rotation_overlay_refuses_a_pose_without_a_frame(shape):
    """A Pose without a rotation was drawn in the input's axes, labelled as the canonical ones, without
    a word (normalize's default pose has none); a NaN pose was drawn as nothing, a batch's refused as
    'points must have shape (2, n, 3) for this pose'. Each refused, naming the pose and the fix; the
    identity given as the rotation draws the input's axes."""
    from jaxpose import Pose

    framed = Pose.from_center_scale(np.zeros(3), 1.0, rotation=np.eye(3))
    with pytest.raises(InvalidInputError, match=r"poses\[1\] has no rotation: .*rotation=True"):
        plot.rotation_overlay([shape, shape], [framed, Pose.from_center_scale(np.zeros(3), 1.0)])
    with pytest.raises(InvalidInputError, match=r"poses\[0\]: an invalid pose, status 7"):
        plot.rotation_overlay([shape], [Pose.from_center_scale(np.array([np.nan, 0, 0]), 1.0, rotation=np.eye(3))])
    batch = Pose.from_center_scale(np.zeros((2, 3)), np.ones(2), rotation=np.broadcast_to(np.eye(3), (2, 3, 3)))
    with pytest.raises(InvalidInputError, match=r"poses\[0\]: a pose must be one center .*index it"):
        plot.rotation_overlay([shape], [batch])
    plot.rotation_overlay([shape, shape], [framed, framed])


def test_rotation_overlay_draws_a_pose_like_object_through_its_apply(shape, monkeypatch):
    """An object with apply and rotation but no center or scale (the docstring takes any object with
    apply) was a TypeError 'cannot unpack non-iterable P object' from the finite-pose check: drawn
    through its apply."""
    class P:
        rotation = np.eye(3)

        def apply(self, v):
            return np.asarray(v, np.float64) * 2.0

    from matplotlib.axes import Axes

    drawn = []
    monkeypatch.setattr(Axes, "scatter", lambda self, x, y, **k: drawn.append(np.asarray(x)))
    plot.rotation_overlay([shape], [P()])
    assert len(drawn) == 2 and np.isin(drawn[0], 2.0 * np.asarray(shape.vertices, np.float64)[:, 1]).all()


def test_figures_of_a_result_name_the_result_they_take(tmp_path, fake_result):
    """An evaluate result given to the rotation figures (and an evaluate_rotation result to the
    others) was a KeyError deep in the figure ('raw', 'per_class'); each names where it belongs."""
    rotation_result = {"params": {}, "variants": {"plain": {"summary": [{"method": "core", "raw_mean": 1.0}],
                                                            "per_class": {}}}}
    for draw in (plot.scale_bars, plot.class_bars, lambda r: plot.evaluation_figures(r, tmp_path)):
        with pytest.raises(InvalidInputError, match="it is evaluate_rotation's, formatted by format_rotation_table"):
            draw(rotation_result)
    for draw in (plot.rotation_angles, lambda r: plot.rotation_figures(r, tmp_path)):
        with pytest.raises(InvalidInputError, match=r"result must be the dict evaluate_rotation\(\) returns: it is evaluate's"):
            draw(fake_result)


def test_sweep_curves_refuses_a_metric_or_param_it_has_not(fake_result):
    with pytest.raises(InvalidInputError, match="metric must be 'sigma_tr' or 'sigma_scale', got 'cv_scale'"):
        plot.sweep_curves(fake_result["sweeps"], metric="cv_scale")  # was KeyError 'cv_scale'
    with pytest.raises(InvalidInputError, match="param 'power' was not swept"):
        plot.sweep_curves(fake_result["sweeps"], param="power")  # was KeyError 'power'


def test_result_figures_refuse_what_the_result_does_not_hold(fake_result):
    """A variant, metric or methods the result has not (or a sweep of a result without sweeps)
    was a KeyError ('holes', 'sigma', 'average'), a TypeError, or "none of the methods is in the
    result" for a string's letters; NaN points were matplotlib's "Axis limits cannot be NaN"."""
    rotation = {"variants": {"plain": {"summary": [{"method": "core"}],
                                       "per_class": {"dog": {"core": {"raw": [1.0, 2.0], "sign_free": [1.0, 2.0],
                                                                      "ambiguity": [0.0, 0.0]}}}}}}
    no_sweeps = {k: v for k, v in fake_result.items() if k != "sweeps"}
    for call, message in (
            (lambda: plot.class_bars(fake_result, "holes"), r"^variant 'holes' is not in the result; it holds 'plain'$"),
            (lambda: plot.rotation_angles(rotation, "holes"), r"^variant 'holes' is not in the result; it holds 'plain'$"),
            (lambda: plot.variant_bars(fake_result, metric="sigma"), r"^metric must be one of 'sigma_tr', .*got 'sigma'$"),
            (lambda: plot.scale_bars(fake_result, metric="cv"), r"^metric must be one of 'sigma_tr', .*got 'cv'$"),
            (lambda: plot.scale_bars(fake_result, methods="ocsvm"), "methods must be a list of names, got the string"),
            (lambda: plot.sweep_curves(None), "result_sweeps must be evaluate"),
            (lambda: plot.sweep_curves({"gamma": 1.0}), "result_sweeps must be evaluate"),
            (lambda: plot.sweep_curves(no_sweeps), r"the result holds no sweeps \(evaluate\(..., sweep=True\)"),
            (lambda: plot.mesh_3d(np.full((4, 3), np.nan)), "expected finite coordinates, got 4 of 4 points")):
        with pytest.raises(InvalidInputError, match=message):
            call()
    assert len(plot.variant_bars(fake_result).axes) == 1  # a result without "variants" (was KeyError 'variants')


def test_sweep_curves(tmp_path, fake_result):
    fig = plot.sweep_curves(fake_result["sweeps"], path=tmp_path / "avg.png")
    assert len(fig.axes) == 2
    _png(tmp_path / "avg.png")
    fig = plot.sweep_curves(fake_result, per_class=True, path=tmp_path / "pc.png", ncols=2)
    assert len(fig.axes) == 4  # 3 classes on a 2 x 2 grid
    _png(tmp_path / "pc.png")
    fig = plot.sweep_curves(fake_result["sweeps"]["gamma"], metric="sigma_scale")
    assert len(fig.axes) == 1


def test_scale_bars(tmp_path, fake_result):
    plot.scale_bars(fake_result, path=tmp_path / "b.png")
    _png(tmp_path / "b.png")
    with pytest.raises(ValueError):
        plot.scale_bars(fake_result, methods=("nope",))


def test_overlay_pairs(tmp_path, shape):
    moved = shape.copy()
    moved.apply_translation([0.5, 0.0, 0.0])
    pairs = [(shape, moved)]
    poses = {"ocsvm": [[((0, 0, 0), 1.0), ((0.5, 0, 0), 1.0)]], "none": [[((0, 0, 0), 1.0)] * 2]}
    fig = plot.overlay_pairs(pairs, poses, labels=["example"], path=tmp_path / "o.png")
    assert len(fig.axes) == 2
    _png(tmp_path / "o.png")
    with pytest.raises(ValueError):
        plot.overlay_pairs(pairs, [])


def test_evaluation_figures(tmp_path, fake_result):
    paths = plot.evaluation_figures(fake_result, tmp_path / "figs")
    names = sorted(p.name for p in paths)
    assert names == sorted(["consistency_plain.png", "sweep_average.png", "sweep_per_class_gamma.png",
                            "sweep_per_class_nu.png"])
    for p in paths:
        _png(p)
    no_sweeps = {k: v for k, v in fake_result.items() if k != "sweeps"}
    assert len(plot.evaluation_figures(no_sweeps, tmp_path / "f2")) == 1


def test_figures_answer_one_question_each(tmp_path, fake_result):
    """Distinct colours for every method of the evaluation, the legend outside the axes (not over a
    bar), units on the axes, and one figure per variant plus one across variants."""
    from jaxpose.evaluation import METHODS

    colors = plot.method_colors([*METHODS, "depth_weighted_solid:3", "mystery"])
    assert len(set(map(str, colors.values()))) == len(METHODS) + 2
    import matplotlib.colors as mc

    rgb = [mc.to_rgb(c) for c in colors.values()]
    assert len({tuple(np.round(c, 3)) for c in rgb}) == len(rgb)
    two = {**fake_result, "variants": {v: {"summary": fake_result["summary"], "per_class": fake_result["per_class"]}
                                       for v in ("plain", "holes")}}
    paths = plot.evaluation_figures(two, tmp_path / "v")
    assert {"consistency_holes.png", "consistency_plain.png", "variants.png"} <= {p.name for p in paths}
    fig = plot.class_bars(two, "holes")
    top, bottom = fig.axes
    assert "mesh units" in top.get_ylabel() and "dimensionless" in bottom.get_ylabel()
    assert top.get_legend() is None and len(fig.legends) == 1  # the legend sits beside the axes
    fig.draw_without_rendering()  # runs the constrained layout
    legend = fig.legends[0].get_window_extent()
    for a in fig.axes:
        assert not legend.overlaps(a.bbox)
    bars = [p for p in top.patches]
    assert len({tuple(np.round(p.get_facecolor(), 3)) for p in bars}) == len(fake_result["params"]["methods"])


def test_rotation_angles_tells_classes_apart(tmp_path):
    cell = lambda k: {"raw": [10.0 * k, 40.0], "sign_free": [5.0, 20.0], "ambiguity": [0.0, 0.3]}
    result = {"variants": {"plain": {"summary": [{"method": "core"}, {"method": "pca_surface"}],
                                     "per_class": {"dog": {"core": cell(1), "pca_surface": cell(2)},
                                                   "cat": {"core": cell(3), "pca_surface": cell(4)}}}}}
    fig = plot.rotation_angles(result, path=tmp_path / "r.png")
    _png(tmp_path / "r.png")
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert {"dog", "cat", "flagged"} <= set(labels)
    assert "degrees" in fig.axes[0].get_ylabel()
    faces = {tuple(np.round(c.get_facecolor()[0], 3)) for c in fig.axes[0].collections if len(c.get_facecolor())}
    assert len(faces) >= 2  # the classes in different colours


def test_import_jaxpose_does_not_import_matplotlib():
    import subprocess
    import sys

    code = "import sys, jaxpose, jaxpose.plot; assert 'matplotlib' not in sys.modules, 'matplotlib loaded'"
    subprocess.run([sys.executable, "-c", code], check=True)
