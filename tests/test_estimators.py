"""Named estimators: closed forms against trimesh and analytic solids, the robust default,
independent center/scale choices, and clear errors where an estimator does not apply."""
import warnings

import numpy as np
import pytest
import trimesh

from jaxpose import InvalidInputError, JaxposeError, baselines
from jaxpose.pose import estimators
from jaxpose._validate import OpenMeshWarning


def _box(extents=(2.0, 1.0, 0.5), at=(0.3, -0.2, 0.1)):
    box = trimesh.creation.box(extents)
    box.apply_translation(at)
    return box


def _holed(mesh, fraction=0.05):
    keep = mesh.triangles_center[:, 2] < mesh.bounds[1, 2] - fraction * np.ptp(mesh.bounds[:, 2])
    return trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False)


def test_solid_moments_match_trimesh_and_analytic():
    mesh = trimesh.creation.capsule(height=1.5, radius=0.4, count=[24, 24])
    mesh.apply_translation([0.5, 2.0, -3.0])
    props = trimesh.triangles.mass_properties(mesh.triangles)
    volume, center, _ = baselines.solid_moments(mesh)
    assert volume == pytest.approx(props["volume"], rel=1e-10)
    np.testing.assert_allclose(center, props["center_mass"], atol=1e-12)
    gyr = np.sqrt(np.trace(props["inertia"]) / (2.0 * props["mass"]))
    assert baselines.gyration_radius(mesh) == pytest.approx(gyr, rel=1e-10)
    far = mesh.copy()  # moments about the vertex mean: no digits lost far from the origin
    far.apply_translation([1e6, 0.0, 0.0])
    assert baselines.gyration_radius(far) == pytest.approx(gyr, rel=1e-9)
    np.testing.assert_allclose(baselines.solid_centroid(far) - [1e6, 0, 0], center, atol=1e-8)
    box = _box()
    np.testing.assert_allclose(baselines.solid_centroid(box), [0.3, -0.2, 0.1], atol=1e-12)
    assert baselines.gyration_radius(box) == pytest.approx(np.sqrt((4 + 1 + 0.25) / 12), rel=1e-12)
    about = np.array([0.3, -0.2, 1.1])  # one unit off the centroid
    assert baselines.gyration_radius(box, about) == pytest.approx(np.sqrt((4 + 1 + 0.25) / 12 + 1.0), rel=1e-12)
    assert baselines.sqrt_area(box) == pytest.approx(np.sqrt(2 * (2 + 1 + 0.5)), rel=1e-12)


def test_closed_surface_estimators_warn_or_refuse_open_meshes_and_points():
    holed = _holed(trimesh.creation.icosphere(subdivisions=3))
    with pytest.warns(OpenMeshWarning, match="not closed"):
        baselines.solid_centroid(holed)
    with pytest.raises(InvalidInputError, match="strict"):
        baselines.solid_centroid(holed, strict=True)
    with pytest.raises(InvalidInputError, match="strict"):
        estimators.estimate(holed, "solid", strict=True)
    cloud = trimesh.PointCloud(np.random.default_rng(0).normal(size=(100, 3)))
    for name in ("sqrt_area", "gyration_radius"):
        with pytest.raises(InvalidInputError, match="points only"):
            estimators.estimate(cloud, center="vertex_mean", scale=name)
    with pytest.raises(InvalidInputError, match="points only"):
        estimators.estimate(cloud, "solid")


def test_robust_default_on_analytic_solids():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    sphere.apply_translation([5.0, -2.0, 1.0])
    pose = estimators.estimate(sphere)
    np.testing.assert_allclose(pose.center, [5.0, -2.0, 1.0], atol=0.01)
    assert float(pose.scale) == pytest.approx(sphere.volume ** (1 / 3), rel=0.01)
    box = _box()
    pose = estimators.estimate(box)
    np.testing.assert_allclose(pose.center, [0.3, -0.2, 0.1], atol=0.02)
    assert float(pose.scale) == pytest.approx(1.0, rel=0.02)  # V = 1


def test_robust_is_similarity_equivariant_and_ignores_a_stray_part():
    body = trimesh.creation.capsule(height=2.0, radius=0.5)
    arm = trimesh.creation.cylinder(radius=0.15, height=1.2)
    arm.apply_translation([0.6, 0.0, 0.5])
    shape = trimesh.util.concatenate([body, arm])
    p0 = estimators.estimate(shape)
    moved = shape.copy()
    moved.apply_scale(3.0)
    moved.apply_translation([10.0, -5.0, 2.0])
    p1 = estimators.estimate(moved)
    np.testing.assert_allclose(p1.center, 3.0 * np.asarray(p0.center) + [10, -5, 2], atol=0.03)
    assert float(p1.scale) == pytest.approx(3.0 * float(p0.scale), rel=2e-3)
    stray = trimesh.creation.icosphere(radius=0.2)
    stray.apply_translation([3.0, 0.0, 0.0])
    p2 = estimators.estimate(trimesh.util.concatenate([shape, stray]))
    np.testing.assert_allclose(p2.center, p0.center, atol=1e-9)
    assert float(p2.scale) == pytest.approx(float(p0.scale), rel=1e-9)
    # the deep part weighs most: the arm pulls the robust center less than the solid centroid
    assert np.linalg.norm(p0.center) < np.linalg.norm(baselines.solid_centroid(shape))


def test_robust_handles_holes_and_point_clouds():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    keep = np.ones(len(sphere.faces), bool)
    keep[np.random.default_rng(1).choice(len(sphere.faces), 200, replace=False)] = False
    pose = estimators.estimate(trimesh.Trimesh(sphere.vertices, sphere.faces[keep], process=False))
    np.testing.assert_allclose(pose.center, 0.0, atol=0.02)
    assert float(pose.scale) == pytest.approx(sphere.volume ** (1 / 3), rel=0.02)
    points, _ = trimesh.sample.sample_surface(sphere, 20000, seed=0)
    pose = estimators.estimate(trimesh.PointCloud(points))
    np.testing.assert_allclose(pose.center, 0.0, atol=0.02)
    assert float(pose.scale) == pytest.approx(sphere.volume ** (1 / 3), rel=0.03)


def test_flat_sheet_is_a_clear_error():
    sheet = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2], [1, 3, 2]], process=False)
    with pytest.raises(JaxposeError, match="encloses no volume"):
        estimators.estimate(sheet)


def test_center_and_scale_are_chosen_independently():
    box = _box()
    pose = estimators.estimate(box, center="solid_centroid", scale="sqrt_area")
    np.testing.assert_allclose(pose.center, [0.3, -0.2, 0.1], atol=1e-12)
    assert float(pose.scale) == pytest.approx(baselines.sqrt_area(box), rel=1e-12)
    assert estimators.resolve("solid", scale="robust_volume") == ("solid_centroid", "robust_volume")
    with pytest.raises(InvalidInputError, match="unknown method"):
        estimators.resolve("median")
    # evaluate's "name:power" given to the single-method functions: named with its spelling here
    with pytest.raises(InvalidInputError, match=r"unknown method 'robust:2'; .* here pass method='robust', power=2\)$"):
        estimators.resolve("robust:2")
    with pytest.raises(InvalidInputError, match="unknown scale"):
        estimators.resolve(scale="height")
    with pytest.raises(InvalidInputError, match="unknown option"):
        estimators.estimate(box, gamma2=1.0)


@pytest.mark.parametrize("call, message", [
    # ignored: a power or a resolution the estimators do not read (normalize_mesh and "vertex_mean:2" refuse them)
    (lambda box: estimators.estimate(box, "vertex_mean", power=2.0), "power applies to the robust_depth and "
                                                                     "depth_weighted_solid centers, which the chosen "
                                                                     r"estimators \(center vertex_mean, "),
    (lambda box: estimators.estimate(box, "bbox", resolution=64), "resolution applies to the robust solid"),
    # the OCSVM's options where no OCSVM runs were ignored (normalize_mesh and the command line refuse them)
    (lambda box: estimators.estimate(box, "vertex_mean", gamma=3.0),
     r"^gamma is an option of the ocsvm estimator, which the chosen estimators \(center vertex_mean, scale "
     r"mean_distance\) do not use \(pass method='ocsvm', or center or scale 'ocsvm'; or leave it out\)$"),
    (lambda box: estimators.estimate(box, center="solid_centroid", nu=0.2, seed=1, ocsvm={"tol": 1e-4}),
     r"^nu, seed, ocsvm are options of the ocsvm estimator, .*center solid_centroid, scale robust_volume"),
    # values no method read went unchecked; a string was truthy
    (lambda box: estimators.estimate(box, "bbox", gamma=-1.0), "gamma must be a finite number > 0"),
    (lambda box: estimators.estimate(box, "bbox", ocsvm={"resolutoin": 32}), "unknown option resolutoin"),
    (lambda box: estimators.estimate(box, "bbox", ocsvm=5), "ocsvm must be a dict"),
    (lambda box: estimators.estimate(box, "vertex_mean", strict="no"), "strict must be True or False"),
    # ignored: strict=True where no closed-surface estimator reads it (the command line refused --strict so)
    (lambda box: estimators.estimate(box, "bbox", strict=True), "strict applies to the closed-surface estimators"),
    (lambda box: estimators.estimate(box, strict=True), r"\(center robust_depth, scale robust_volume\) do not use"),
    # one string was its characters ('unknown method 'r''); bad values were each method's row, not an error
    (lambda box: estimators.estimate_many(box, "robust"), r"methods must be a list of names, got the string 'robust'"),
    (lambda box: estimators.estimate_many(box, ["vertex_mean", "robust"], resolution=4), "resolution must be >= 8"),
    (lambda box: estimators.estimate_many(box, ["bbox"], ocsvm={"tol": -1.0}), "tol must be a finite number > 0"),
    # as estimate: an option none of the methods reads (they were taken and ignored)
    (lambda box: estimators.estimate_many(box, ["robust"], strict=True), "strict applies to the closed-surface"),
    (lambda box: estimators.estimate_many(box, ["bbox", "vertex_mean"], strict=True), "which the methods bbox, "),
    (lambda box: estimators.estimate_many(box, ["bbox"], power=2), "power applies to the robust_depth and"),
    (lambda box: estimators.estimate_many(box, ["robust:2", "solid"], power=2),
     r"which the method solid does not use and the method robust:2 replaces with its own; leave it out$"),
    # the OCSVM's options where none of the methods runs it were taken and ignored (estimate refused them)
    (lambda box: estimators.estimate_many(box, ["robust"], gamma=3.0, nu=0.2),
     r"^gamma, nu are options of the ocsvm estimator, which the method robust does not use \(pass 'ocsvm' among the "
     r"methods; or leave them out\)$"),
    (lambda box: estimators.estimate_many(box, ["bbox", "robust:2"], seed=1, ocsvm={}), "^seed, ocsvm are options of"),
    (lambda box: estimators.estimate_many(box, ["bbox", "solid"], resolution=64), "resolution applies to the robust"),
])
def test_bad_options_are_refused_before_any_work(call, message):
    with pytest.raises(InvalidInputError, match=message):
        call(_box())


def test_method_powers_are_checked():
    """"name:p": p a finite number >= 0, on a method whose center is depth weighted; estimate_many
    refuses the others before any work (robust:-1 was an n/a row, vertex_mean:2 the vertex mean)."""
    assert estimators.parse_method("robust") == ("robust", None)
    assert estimators.parse_method("depth_weighted_solid:4") == ("depth_weighted_solid", 4.0)
    for spec, fragment in (("robust:-1", "finite number >= 0"), ("robust:inf", "finite number >= 0"),
                           ("robust:x", "must be a number"), ("solid:2", "solid takes no power"),
                           ("median:2", "unknown method")):
        with pytest.raises(InvalidInputError, match=fragment):
            estimators.parse_method(spec)
        with pytest.raises(InvalidInputError, match=fragment):
            estimators.estimate_many(_box(), ["vertex_mean", spec])


def test_depth_weighted_solid_and_estimate_many_agree():
    mesh = trimesh.creation.capsule(height=2.0, radius=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        many = estimators.estimate_many(mesh, ["robust", "robust:8", "depth_weighted_solid",
                                               "depth_weighted_solid:4", "solid"])
    np.testing.assert_allclose(many["depth_weighted_solid"].center, baselines.depth_weighted_solid(mesh, 2.0),
                               atol=1e-12)
    np.testing.assert_allclose(many["depth_weighted_solid:4"].center, baselines.depth_weighted_solid(mesh, 4.0),
                               atol=1e-12)
    np.testing.assert_allclose(many["robust"].center, estimators.estimate(mesh).center, atol=1e-12)
    np.testing.assert_allclose(many["robust:8"].center, estimators.estimate(mesh, power=8.0).center, atol=1e-12)
    np.testing.assert_allclose(many["solid"].center, 0.0, atol=1e-9)
    # an option one of the methods reads: taken (by that one)
    mixed = estimators.estimate_many(mesh, ["bbox", "solid", "robust", "depth_weighted_solid:4"], strict=True,
                                     power=8.0, resolution=64)
    np.testing.assert_allclose(mixed["robust"].center, estimators.estimate(mesh, power=8.0, resolution=64).center,
                               atol=1e-12)
    np.testing.assert_allclose(mixed["solid"].center, many["solid"].center, atol=1e-12)
    cloud = trimesh.PointCloud(np.asarray(mesh.vertices))
    out = estimators.estimate_many(cloud, ["solid", "vertex_mean"])
    assert isinstance(out["solid"], InvalidInputError) and not isinstance(out["vertex_mean"], Exception)


# --------------------------------------------------------------------------- far from the origin
@pytest.mark.parametrize("offset", [1e6, 1e12])
def test_every_method_is_exact_under_translation(offset):
    """normalize_mesh, every method, at 1e6 and 1e12 (float64 vertices): the center within 1e-6
    of the scale of the un-offset result (plus the float spacing at the offset, all the returned
    center can hold), the scale within 1e-6. The un-offset mesh is the offset one moved back
    exactly (fl(v + o) - o is exact), so the comparison measures the library, not the input's own
    rounding (1.2e-4 at 1e12)."""
    from jaxpose.mesh import normalize_mesh

    o = offset * np.array([1.0, -0.7, 0.3])
    base = trimesh.creation.capsule(height=1.0, radius=0.5, count=[12, 12])  # closed
    far = trimesh.Trimesh(base.vertices + o, base.faces, process=False)
    near = trimesh.Trimesh(far.vertices - o, base.faces, process=False)
    for method in estimators.METHODS:
        kw = dict(count=400, resolution=32) if method == "ocsvm" else {}  # the pinned results' compilation
        p0 = normalize_mesh(near, method=method, **kw)[1]
        normalized, p = normalize_mesh(far, method=method, **kw)
        c, c0, s0 = np.asarray(p.center), np.asarray(p0.center), float(p0.scale)
        assert np.max(np.abs(c - o - c0)) <= 1e-6 * s0 + np.spacing(offset), (method, c - o - c0)
        assert float(p.scale) == pytest.approx(s0, rel=1e-6), method
        # the normalized mesh keeps its digits too (x - center, then / scale): up to the center's own spacing
        np.testing.assert_allclose(normalized.vertices, (near.vertices - c0) / s0, atol=1e-6 + np.spacing(offset) / s0)


# --------------------------------------------------------------------------- no silent fallback
def test_a_mesh_without_area_is_refused_by_name():
    """Faces of zero area are not silently taken as points (nor the vertex mean as a centroid)."""
    from jaxpose.mesh import normalize_mesh, sample_surface

    line = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0.0]], [[0, 1, 2], [1, 2, 3]], process=False)
    for method in (None, "surface_centroid", "ocsvm", "vertex_mean", "solid"):
        with pytest.raises(InvalidInputError, match="the mesh has no area"):
            normalize_mesh(line, method=method)
    with pytest.raises(InvalidInputError, match="the mesh has no area"):
        baselines.surface_centroid(line)
    with pytest.raises(InvalidInputError, match="the mesh has no area"):
        sample_surface(line, 100)
    # its vertices, given as points, are points
    np.testing.assert_allclose(baselines.surface_centroid(trimesh.PointCloud(line.vertices)), [1.5, 0, 0])


def test_one_type_policy_for_host_poses_of_every_method():
    """Host entry points return NumPy poses (floats float64) whatever the method, and a host pose's
    matrix is NumPy float64 computed without JAX (docs/api.md, jaxpose.pose.result.Pose)."""
    import subprocess
    import sys

    from jaxpose.pose.estimators import estimate

    box = trimesh.creation.box(extents=(1.0, 0.6, 0.3))
    for method in ("robust", "ocsvm", "surface_centroid"):
        pose = estimate(box, method, **({"count": 300} if method == "ocsvm" else {}))  # (the others refuse it)
        for name in ("center", "scale", "converged", "valid", "status"):
            value = getattr(pose, name)
            assert isinstance(value, np.ndarray), (method, name, type(value))
        assert pose.center.dtype == np.float64 and pose.scale.dtype == np.float64, method
        assert pose.valid.dtype == bool and pose.status.dtype == np.int64
        m = pose.matrix
        assert isinstance(m, np.ndarray) and m.dtype == np.float64
        np.testing.assert_allclose(pose.apply(pose.center[None]), 0.0, atol=1e-12)
        np.testing.assert_allclose(m[:3, :3] @ pose.center + m[:3, 3], 0.0, atol=1e-12)
    code = ("import sys, numpy as np; from jaxpose.pose.result import Pose; "
            "m = Pose.from_center_scale(np.array([1e9, 2.0, 3.0]), 2.0).matrix; "
            "assert m.dtype == np.float64 and m[0, 3] == -5e8, m; assert 'jax' not in sys.modules")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr


def test_strict_refusal_has_one_wording():
    """strict=True where no closed-surface estimator reads it: estimate, estimate_many and the
    command line's --strict said it three ways (', not bbox_center / unit_cube', ', none of which
    the methods ... use', ', which --method bbox (...) does not use; drop it'); one helper now."""
    import argparse

    from jaxpose.cli.normalize import ignored_options

    rule = (r"strict applies to the closed-surface estimators \(solid_centroid, gyration_radius, depth_weighted_solid\), "
            r"which {} do not use; leave it out$")
    with pytest.raises(InvalidInputError, match="^" + rule.format(r"the chosen estimators \(center bbox_center, "
                                                                  r"scale unit_cube\)")):
        estimators.estimate(_box(), "bbox", strict=True)
    with pytest.raises(InvalidInputError, match="^" + rule.format("the methods bbox, vertex_mean")):
        estimators.estimate_many(_box(), ["bbox", "vertex_mean"], strict=True)
    args = argparse.Namespace(method="bbox", center=None, scale=None, rotation=None, strict=True,
                              **dict.fromkeys(("gamma", "nu", "count", "seed", "sampling")))
    import re
    assert re.match("^--" + rule.format(r"the chosen estimators \(center bbox_center, scale unit_cube\)"),
                    ignored_options(args)), ignored_options(args)


def test_power_and_resolution_refusals_have_one_wording():
    """normalize_mesh / normalize_files (mesh.check_arguments) said 'power applies to the
    robust_depth and depth_weighted_solid centers, not bbox_center' and 'resolution applies to the
    robust and ocsvm estimators (options) and to rotation='ocsvm', not bbox_center / unit_cube',
    estimate another way; one helper each now (normalize_mesh's resolution names the OCSVM too:
    there it is the OCSVM grid's). estimate_many(['robust:2', 'solid'], power=2) said 'which the
    methods robust:2, solid do not use': robust:2's center takes a power, its own. The command
    line's OCSVM options said 'drop it', its --strict 'leave it out': 'leave it out' both."""
    import argparse

    from jaxpose import mesh
    from jaxpose.cli.normalize import ignored_options

    power = (r"^power applies to the robust_depth and depth_weighted_solid centers, which the chosen estimators "
             r"\(center bbox_center, scale unit_cube\) do not use; leave it out$")
    for call in (lambda: estimators.estimate(_box(), "bbox", power=2.0), lambda: mesh.check_arguments(method="bbox", power=2),
                 lambda: mesh.normalize_mesh(_box(), method="bbox", power=2)):
        with pytest.raises(InvalidInputError, match=power):
            call()
    resolution = (r"^resolution applies to the robust solid \(the robust_depth center, the robust_volume scale\){}, "
                  r"which the chosen estimators \(center bbox_center, scale unit_cube\) do not use; {}$")
    with pytest.raises(InvalidInputError, match=resolution.format("", r"for ocsvm give it in ocsvm=\{'resolution': \.\.\.\}")):
        estimators.estimate(_box(), "bbox", resolution=64)
    with pytest.raises(InvalidInputError, match=resolution.format(", the core and head frames, and the ocsvm estimator and frame",
                                                                        "leave it out")):
        mesh.check_arguments(method="bbox", resolution=32)
    with pytest.raises(InvalidInputError, match=r"which the methods robust:2, depth_weighted_solid:3 replace with their "
                                                r"own; leave it out$"):
        estimators.estimate_many(_box(), ["robust:2", "depth_weighted_solid:3"], power=2)
    args = argparse.Namespace(method="bbox", center=None, scale=None, rotation=None, strict=False,
                              **dict(dict.fromkeys(("gamma", "nu", "count", "seed", "sampling")), gamma=3.0))
    assert ignored_options(args).endswith("does not use; leave it out"), ignored_options(args)


def test_a_resolution_where_only_the_frame_reads_one_is_the_frames():
    """With a center and scale that read no resolution (solid) and the head or core frame, a
    resolution is the frame's robust solid's (it was refused as read by nothing): the rotation is
    frame_of's at that resolution, the center and scale the method's own; without a frame that
    reads one it is refused, naming the frames."""
    from jaxpose import mesh
    from jaxpose.batch.task import NormalizeOptions
    from jaxpose.config import GridConfig, RobustConfig
    from jaxpose.mesh import example_shape
    from jaxpose.rotation.rotation import frame_of

    body = example_shape()
    _, plain = mesh.normalize_mesh(body, method="solid")
    for frame, resolution in (("head", 128), ("core", 64)):
        _, pose = mesh.normalize_mesh(body, method="solid", rotation=frame, resolution=resolution)
        want = frame_of(estimators.centered(body)[0], frame, resolution=resolution)
        np.testing.assert_array_equal(pose.rotation, np.asarray(want.rotation, np.float64))
        assert not np.array_equal(pose.rotation, mesh.normalize_mesh(body, method="solid", rotation=frame)[1].rotation)
        np.testing.assert_array_equal(pose.center, plain.center)
        assert float(pose.scale) == float(plain.scale)
    with pytest.raises(InvalidInputError, match=r"robust_volume scale\), the core and head frames, and the ocsvm "
                                                r"estimator and frame, which the chosen estimators \(center "
                                                r"solid_centroid, scale gyration_radius\) do not use"):
        mesh.normalize_mesh(body, method="solid", resolution=128)
    with pytest.raises(InvalidInputError, match=r"\(center solid_centroid, scale gyration_radius\) and the pca_vertices "
                                                r"frame do not use; leave it out$"):  # the chosen frame reads none either
        mesh.check_arguments(method="solid", rotation="pca_vertices", resolution=128)
    # a dataset's settings: the frame's default written out is the default left out
    robust = RobustConfig().resolution
    solid_head = NormalizeOptions(method="solid", rotation=True)
    assert solid_head.settings() == NormalizeOptions(method="solid", rotation=True, resolution=robust).settings()
    assert solid_head.settings() != NormalizeOptions(method="solid", rotation=True, resolution=128).settings()
    # the ocsvm frame reads the OCSVM grid's (64) where the center and scale read none: its default
    # written out was another dataset's options ("--resolution none there, 64 here")
    grid = GridConfig().resolution
    solid_ocsvm = NormalizeOptions(method="solid", rotation="ocsvm")
    assert solid_ocsvm.settings() == NormalizeOptions(method="solid", rotation="ocsvm", resolution=grid).settings()
    assert solid_ocsvm.settings()["resolution"] == grid != robust
    assert NormalizeOptions(method="solid").settings()["resolution"] is None  # nothing reads one


def test_evaluate_gives_estimate_many_only_the_options_its_methods_read():
    """evaluate passed the OCSVM's defaults to estimate_many whatever the methods; estimate_many
    refuses options none of its methods reads, so without an ocsvm method evaluate passes none."""
    from jaxpose.evaluation import evaluate

    classes = {"boxes": [_box(), _box(at=(1.0, 0.0, 0.0))]}
    result = evaluate(classes, methods=["bbox", "vertex_mean"])
    assert [row["method"] for row in result["summary"]] == ["bbox", "vertex_mean"]
    assert all(row.get("error") is None for row in result["summary"]), result["summary"]


def test_solid_center_volume_refuses_no_solid_and_an_empty_one():
    """solid_center_volume (estimators' __all__) read sol.inside: a tuple was an AttributeError, and a
    Solid with no voxel inside gave a center of no voxel (a number) beside a volume 0. Both are
    refused by name; a box's solid is still centered on the box (its closed form: the origin)."""
    from jaxpose.occupancy.solid import robust_solid

    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    sol = robust_solid(box.vertices, box.faces, resolution=16, with_depth=False)
    with pytest.raises(InvalidInputError, match="^sol must be a Solid"):
        estimators.solid_center_volume((sol.inside, sol.origin))
    with pytest.raises(InvalidInputError, match="^sol has no voxel inside"):
        estimators.solid_center_volume(sol._replace(inside=np.zeros_like(sol.inside)))
    center, volume = estimators.solid_center_volume(sol)
    np.testing.assert_allclose(center, 0.0, atol=2 * float(sol.pitch))
    assert volume == pytest.approx(1.0, rel=0.25)  # 2 x 1 x 0.5, at 16 voxels along its length

