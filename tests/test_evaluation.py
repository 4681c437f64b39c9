"""Within-class spread measures, evaluation driver, sweeps and rigid-core alignment."""
import os
from pathlib import Path

import numpy as np
import pytest
import trimesh

import jaxpose
import jaxpose.pose.pose  # the module the fixtures patch (not imported by "import jaxpose" alone)
from jaxpose import datasets, evaluation
from jaxpose._validate import InvalidInputError
from jaxpose.evaluation import align_core, evaluate, format_per_class, format_table, scale_spread, spread, sweep
from jaxpose.pose.result import Pose

SHARED = next((p for p in (Path(__file__).resolve().parents[1] / ".." / "shared", Path("/work/shared"))
               if (p / "data" / "faust-dev").is_dir()), None)


def _sample(mesh, count, seed):
    from jaxpose.mesh import sample_surface

    return sample_surface(mesh, count, seed)


@pytest.fixture
def fake_normalize(monkeypatch):
    """jaxpose.normalize replaced by: center = mean of the points + (gamma, 0, 0), scale = 1 + nu
    (equivariant under translation, as the estimators expect: they run on a moved copy)."""
    calls = []

    def normalize(points, method="ocsvm", *, gamma=47.0, nu=0.5, **options):
        assert method == "ocsvm"
        calls.append(options)
        center = np.asarray(points).mean(axis=0) + np.array([gamma, 0.0, 0.0])
        return Pose.from_center_scale(center, 1.0 + nu)

    _patch_normalize(monkeypatch, normalize)
    return calls


def _patch_normalize(monkeypatch, normalize):
    """``normalize`` where the library looks it up: the pose module (the estimators import it from
    there when an estimator needs it, so the default needs no JAX)."""
    monkeypatch.setattr(jaxpose.pose.pose, "normalize", normalize)


def _boxes():
    """Two boxes: centers (0,0,0), (2,0,0); extents 1, 3 (hand-checkable spreads)."""
    a = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    b = trimesh.creation.box(extents=(3.0, 3.0, 3.0))
    b.apply_translation((2.0, 0.0, 0.0))
    return [a, b]


# ------------------------------------------------------------------ measures
def test_spread_by_hand():
    # mean (.5,.5,.5); squared distances .75, 2.75, 2.75, 2.75 -> mean 2.25 -> 1.5
    # per axis: values (0,2,0,0) -> population variance .75 on every axis
    out = spread([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, 2]])
    assert out["sigma_tr"] == pytest.approx(1.5, rel=1e-14)
    assert out["sigma_tr_axis"] == pytest.approx(np.sqrt(0.75), rel=1e-14)
    out = spread([[0, 0, 0], [2, 0, 0]])
    assert out == pytest.approx({"sigma_tr": 1.0, "sigma_tr_axis": 1.0 / 3.0})
    assert spread([[1.0, 2.0, 3.0]]) == {"sigma_tr": 0.0, "sigma_tr_axis": 0.0}


def test_scale_spread_by_hand():
    assert scale_spread([1.0, 3.0]) == pytest.approx({"sigma_scale": 1.0, "cv_scale": 0.5})
    # (2, 4, 6): mean 4, population variance 8/3
    assert scale_spread([2.0, 4.0, 6.0]) == pytest.approx({"sigma_scale": np.sqrt(8 / 3), "cv_scale": np.sqrt(8 / 3) / 4})


@pytest.mark.parametrize("bad", [np.zeros((3, 2)), np.zeros((0, 3)), [[0, 0, np.nan]], "abc", [["a", "b", "c"]]])
def test_spread_rejects(bad):  # (strings: float()'s raw ValueError)
    with pytest.raises(InvalidInputError):
        spread(bad)


@pytest.mark.parametrize("bad", [[], [1.0, -1.0], [[1.0, 2.0]], [1.0, np.inf], ["a"], [True, True]])
def test_scale_spread_rejects(bad):  # (strings: float()'s raw ValueError; bools were taken as 1)
    with pytest.raises(InvalidInputError):
        scale_spread(bad)


# ------------------------------------------------------------------ alignment
def _rigid(rng):
    rot = trimesh.transformations.random_rotation_matrix(rng.uniform(size=3))[:3, :3]
    return rot, rng.normal(size=3)


def test_align_core_recovers_a_rigid_copy():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(300, 3))
    rot, t = _rigid(rng)
    out = align_core([v, v @ rot.T + t, v @ rot.T @ rot.T + 2 * t])
    for mesh in out:
        np.testing.assert_allclose(mesh.vertices, v, atol=1e-10)
    np.testing.assert_array_equal(out[0].metadata["core_transform"], np.eye(4))
    matrix = out[1].metadata["core_transform"]
    np.testing.assert_allclose(matrix[:3, :3], rot.T, atol=1e-12)  # the inverse motion
    np.testing.assert_allclose(matrix[:3, 3], -rot.T @ t, atol=1e-12)


def test_align_core_ignores_moved_vertices():
    rng = np.random.default_rng(1)
    v = rng.uniform(-1, 1, size=(500, 3))
    moved = rng.permutation(500)[:200]  # 40% of the vertices articulated away
    copies = [v]
    for _ in range(3):
        rot, t = _rigid(rng)
        w = v.copy()
        w[moved] += rng.normal(scale=0.5, size=(200, 3))
        copies.append(w @ rot.T + t)
    out = align_core(copies)
    still = np.setdiff1d(np.arange(500), moved)
    for mesh in out[1:]:
        np.testing.assert_allclose(mesh.vertices[still], v[still], atol=1e-9)
    # on all vertices a single Kabsch fit would not get there
    naive = align_core(copies, keep=1.0)
    assert np.abs(naive[1].vertices[still] - v[still]).max() > 1e-3


def _trunk_and_head(head_subdivisions, instances=4, seed=2):
    """A class of one body: a 4 x 1 x 1 box (the trunk, area 18) and a 0.6 box beside it (the head,
    area 2.16) that turns about its own neck in each instance; every instance moved rigidly. The
    head's faces are subdivided ``head_subdivisions`` times (more vertices, the same surface).
    Returns (meshes, trunk vertex indices, head vertex indices)."""
    from trimesh.remesh import subdivide

    rng = np.random.default_rng(seed)
    trunk = trimesh.creation.box(extents=(4.0, 1.0, 1.0))
    head = trimesh.creation.box(extents=(0.6, 0.6, 0.6))
    hv, hf = head.vertices + (2.6, 0.0, 0.0), head.faces
    for _ in range(head_subdivisions):
        hv, hf = subdivide(hv, hf)
    v = np.vstack([trunk.vertices, hv])
    f = np.vstack([trunk.faces, hf + len(trunk.vertices)])
    is_head = np.arange(len(v)) >= len(trunk.vertices)
    meshes = []
    for k in range(instances):
        w = v.copy()
        turn = trimesh.transformations.rotation_matrix(0.5 * k, (0, 0, 1), point=(2.2, 0.0, 0.0))
        w[is_head] = trimesh.transform_points(w[is_head], turn)
        rot, t = _rigid(rng) if k else (np.eye(3), np.zeros(3))
        meshes.append(trimesh.Trimesh(w @ rot.T + t, f, process=False))
    return meshes, np.flatnonzero(~is_head), np.flatnonzero(is_head)


def test_align_core_by_area_finds_the_larger_rigid_part_whatever_the_meshing():
    # the trunk is 89 % of the surface; subdivided 3 times, the head holds 96 % of the vertices
    meshes, trunk, head = _trunk_and_head(3)
    assert len(head) > 0.9 * (len(head) + len(trunk))
    first = meshes[0].vertices
    by_area = align_core(meshes, weight="area")
    by_count = align_core(meshes)  # weight="vertices": the densely meshed head is the core
    for k in range(1, len(meshes)):
        np.testing.assert_allclose(by_area[k].vertices[trunk], first[trunk], atol=1e-9)
        np.testing.assert_allclose(by_count[k].vertices[head], first[head], atol=1e-9)
        assert np.abs(by_count[k].vertices[trunk] - first[trunk]).max() > 0.1
    # the same body meshed coarsely: the same transforms by area (the same motions were drawn)
    coarse = align_core(_trunk_and_head(0)[0], weight="area")
    for a, b in zip(by_area, coarse):
        np.testing.assert_allclose(a.metadata["core_transform"], b.metadata["core_transform"], atol=1e-9)


def test_weighted_kabsch_matches_scipy():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(3)
    x = rng.normal(size=(40, 3))
    rot, t = _rigid(rng)
    y = x @ rot.T + t + rng.normal(scale=0.05, size=x.shape)
    w = rng.uniform(0.1, 2.0, size=40)
    r, t_fit = evaluation.kabsch(x, y, w)
    cx, cy = w @ x / w.sum(), w @ y / w.sum()  # the weighted fit's centroids map onto each other
    oracle, _ = Rotation.align_vectors(y - cy, x - cx, weights=w)
    np.testing.assert_allclose(r, oracle.as_matrix(), atol=1e-10)
    np.testing.assert_allclose(t_fit, cy - r @ cx, atol=1e-10)
    # equal weights: the unweighted fit
    np.testing.assert_allclose(evaluation.kabsch(x, y, np.full(40, 0.7))[0], evaluation.kabsch(x, y)[0], atol=1e-12)
    # refused by name (they were NumPy's matmul ValueError, an AttributeError for lists and strings, NaN for w = 0)
    for args, message in (((x[:, :2], y[:, :2]), r"^x must have shape \(m, 3\)"), ((x, y[:10]), "^x and y must have as many points"),
                          (("a", y), "^x must have shape"), ((x, y, w[:5]), r"^w must be \(40,\) finite weights >= 0"),
                          ((x, y, -w), "^w must be"), ((x, y, np.zeros(40)), "^w must be .* positive sum")):
        with pytest.raises(InvalidInputError, match=message):
            evaluation.kabsch(*args)
    np.testing.assert_array_equal(evaluation.kabsch(x.tolist(), y.tolist())[0], evaluation.kabsch(x, y)[0])  # lists are arrays


def test_vertex_weights_are_the_area_share():
    from jaxpose.evaluation.alignment import vertex_weights

    mesh = trimesh.creation.icosphere(subdivisions=1)
    mesh.vertices[:, 0] *= 2.0
    other = mesh.copy()
    other.vertices[:, 1] *= 1.5
    w = vertex_weights([mesh, other], "area")
    expected = np.zeros(len(mesh.vertices))
    for m in (mesh, other):
        for face, area in zip(m.faces, m.area_faces):
            expected[face] += area / 3.0
    np.testing.assert_allclose(w, expected / expected.sum(), rtol=1e-12)
    np.testing.assert_allclose(vertex_weights([mesh], "vertices"), 1.0 / len(mesh.vertices))
    with pytest.raises(InvalidInputError, match="unknown core weight"):
        align_core([mesh, other], weight="faces")
    with pytest.raises(InvalidInputError, match="needs meshes with faces"):
        align_core([mesh.vertices, other.vertices], weight="area")
    with pytest.raises(InvalidInputError, match="unknown core weight"):
        evaluate({"a": [mesh, other]}, align_core=True, core_weight="volume", methods=["vertex_mean"])


def test_align_core_keeps_faces_and_checks_counts():
    box = trimesh.creation.box()
    moved = box.copy()
    moved.apply_transform(trimesh.transformations.rotation_matrix(0.3, (0, 0, 1), point=(1, 2, 3)))
    out = align_core([box, moved])
    np.testing.assert_array_equal(out[1].faces, box.faces)
    np.testing.assert_allclose(out[1].vertices, box.vertices, atol=1e-12)
    with pytest.raises(InvalidInputError, match="same vertex count"):
        align_core([box, trimesh.creation.icosphere()])
    with pytest.raises(InvalidInputError):
        align_core([box], keep=0.0)


def test_align_core_names_the_class_and_the_file_that_differs(tmp_path):
    """A class folder holding another body's file: the error names the class and the file."""
    from jaxpose.datasets import load_folder
    from jaxpose.evaluation import align_classes

    for name, mesh in [("a/0.ply", trimesh.creation.box()), ("a/1.ply", trimesh.creation.box()),
                       ("a/2.ply", trimesh.creation.icosphere(subdivisions=1)), ("b/0.ply", trimesh.creation.box()),
                       ("b/1.ply", trimesh.creation.box())]:
        (tmp_path / name).parent.mkdir(exist_ok=True)
        mesh.export(tmp_path / name)
    classes = load_folder(tmp_path)
    with pytest.raises(InvalidInputError, match=r"class 'a': .*same vertex count.* \(42, 3\) for mesh 2 \(2.ply\) and \(8, 3\) for mesh 0 \(0.ply\)"):
        align_classes(classes)
    with pytest.raises(InvalidInputError, match=r"class 'a': .*mesh 2 \(2.ply\)"):
        evaluate(classes, align_core=True, methods=["vertex_mean"])
    aligned = align_classes({"b": classes["b"]}, weight="area")
    np.testing.assert_allclose(aligned["b"][1].vertices, classes["b"][0].vertices, atol=1e-12)


@pytest.mark.parametrize("call, message", [
    # one string was taken as its characters: "unknown method 'v'", "unknown variants ['p', 'l', ...]"
    (lambda: evaluate({"boxes": _boxes()}, methods="surface_centroid"), r"methods must be a list of names, got the "
                                                                         r"string 'surface_centroid': pass \['surface_centroid'\]"),
    (lambda: evaluate({"boxes": _boxes()}, methods=["surface_centroid"], variants="plain"), "variants must be a list of names"),
    (lambda: evaluation.evaluate_rotation({"boxes": _boxes()}, methods="pca_vertices"), "methods must be a list of names"),
    (lambda: evaluation.evaluate_rotation({"boxes": _boxes()}, methods=["pca_vertices"], variants="plain"),
     "variants must be a list of names"),
    # a string was truthy: align_core="no" aligned, sweep="no" ran both sweeps
    (lambda: evaluate({"boxes": _boxes()}, methods=["surface_centroid"], align_core="no"), "align_core must be True or False"),
    (lambda: evaluate({"boxes": _boxes()}, methods=["surface_centroid"], sweep="no"), "sweep must be True or False"),
    (lambda: evaluation.evaluate_rotation({"boxes": _boxes()}, methods=["pca_vertices"], frames="no"),
     "frames must be True or False"),
    # a progress that is not callable: 'int' object is not callable at its first call
    (lambda: evaluate({"boxes": _boxes()}, methods=["surface_centroid"], progress=5), "progress must be a callable or None"),
    (lambda: evaluation.evaluate_rotation({"boxes": _boxes()}, methods=["pca_vertices"], progress=5), "progress must be a callable"),
    (lambda: sweep({"boxes": _boxes()}, progress=5), "progress must be a callable or None"),
    (lambda: align_core(_boxes(), keep="0.3"), "keep must be a finite number > 0, got '0.3'"),  # '<'s TypeError
    # sweep: a fixed without the other parameter was KeyError 'nu'; values="47" swept 4 and 7
    (lambda: sweep({"boxes": _boxes()}, "gamma", fixed={"mu": 0.1}), r"fixed must give the other parameter, \{'nu'"),
    (lambda: sweep({"boxes": _boxes()}, "gamma", fixed={"nu": 0.1, "mu": 0.1}), r"keys 'gamma' and 'nu' only"),
    (lambda: sweep({"boxes": _boxes()}, "nu", fixed={"nu": 0.1}), r"fixed must give the other parameter, \{'gamma'"),
    (lambda: sweep({"boxes": _boxes()}, "gamma", values="47"), "values must be a list of numbers, got the string '47'"),
    # a name given twice ran twice: two rows, one timed 0.0 ms; a frame's class counted each instance twice
    (lambda: evaluate({"boxes": _boxes()}, methods=["bbox", "vertex_mean", "bbox"]), "methods names 'bbox' twice"),
    (lambda: evaluate({"boxes": _boxes()}, methods=["robust:2", "robust:2.0"]), r"'robust:2.0' twice \(as 'robust:2'; both are robust at power 2\)"),
    (lambda: evaluate({"boxes": _boxes()}, methods=["bbox"], variants=["plain", "plain"]), "variants names 'plain' twice"),
    (lambda: evaluation.evaluate_rotation({"boxes": _boxes()}, methods=["pca_vertices", "pca_vertices"]),
     "methods names 'pca_vertices' twice"),
    (lambda: evaluation.evaluate_rotation({"boxes": _boxes()}, methods=["pca_vertices"], variants=["holes", "holes"]),
     "variants names 'holes' twice"),
    # the built-in dataset: a class named twice was made once, none was an empty dataset
    (lambda: datasets.make_dataset(instances=2, classes=["human", "human"]), "classes names 'human' twice"),
    (lambda: datasets.make_dataset(instances=2, classes=[]), "classes names no class"),
    # a class that is not a list of meshes: TypeError (no len()) or AttributeError (no .vertices) in the run
    (lambda: evaluate({"box": _boxes()[0]}, methods=["bbox"]), r"class 'box' must be a list of meshes, got Trimesh: "
                                                               r"pass \{'box': \[...\]\}"),
    (lambda: evaluate({"boxes": (m for m in _boxes())}, methods=["bbox"]), "class 'boxes' must be a list of meshes, got generator"),
    (lambda: evaluate({"boxes": [_boxes()[0], np.zeros((8, 3))]}, methods=["bbox"]),
     "class 'boxes': object 1 must be a mesh .* got ndarray"),
    (lambda: evaluation.evaluate_rotation({"box": _boxes()[0]}, methods=["pca_vertices"]), "class 'box' must be a list"),
    (lambda: sweep({"boxes": [_boxes()[0], "a.ply"]}), "class 'boxes': object 1 must be a mesh .* got str"),
    # AttributeError ('list' has no 'items'), IndexError, float()'s ValueError, NumPy's errors
    (lambda: evaluation.align_classes(_boxes()), r"classes must be a dict \{class name: \[meshes\]\}, got list: pass"),
    (lambda: evaluation.alignment.vertex_weights([]), "vertex_weights needs at least one mesh"),
    (lambda: align_core(_boxes()[0]), "align_core needs a list of meshes, got Trimesh"),
    (lambda: align_core(["a.ply", "b.ply"]), "align_core needs meshes or \\(n, 3\\) arrays, got 'a.ply' for mesh 0"),
    (lambda: evaluation.variants.stray_mask(-1, 0, 0), "n must be >= 0, got -1"),
    (lambda: evaluation.variants.stray_mask(1.5, 0, 0), "n must be an int, got 1.5"),
])
def test_arguments_of_the_wrong_kind_are_refused_by_name(call, message):
    with pytest.raises(InvalidInputError, match=message):
        call()


def test_a_method_spelled_with_its_default_power_is_a_repeat():
    """``methods=["robust", "robust:4"]`` ran one estimator twice under two names (robust's power is
    4 unless given), as did ``depth_weighted_solid`` and ``depth_weighted_solid:2``: refused as a
    method named twice, both spellings named. Oracle: estimate_many's poses of an asymmetric solid
    (a cube with an arm) are equal for the two spellings and differ for another power."""
    from jaxpose.pose.estimators import estimate_many

    arm = trimesh.creation.box(extents=(3.0, 0.3, 0.3))
    arm.apply_translation((2.0, 0.0, 0.0))
    shape = trimesh.util.concatenate([trimesh.creation.box(extents=(1.0, 1.0, 1.0)), arm])
    poses = {**estimate_many(shape, ["robust", "robust:2", "depth_weighted_solid", "depth_weighted_solid:4"]),
             **estimate_many(shape, ["robust:4", "depth_weighted_solid:2"])}

    def same(a, b):
        return np.array_equal(poses[a].center, poses[b].center) and poses[a].scale == poses[b].scale

    assert same("robust", "robust:4") and same("depth_weighted_solid", "depth_weighted_solid:2")
    assert not same("robust", "robust:2") and not same("depth_weighted_solid", "depth_weighted_solid:4")
    for methods, message in (
            (["robust", "bbox", "robust:4"], "methods names 'robust:4' twice (as 'robust'; both are robust at power 4)"),
            (["depth_weighted_solid:2.0", "depth_weighted_solid"],
             "methods names 'depth_weighted_solid' twice (as 'depth_weighted_solid:2.0'; both are depth_weighted_solid "
             "at power 2)")):
        with pytest.raises(InvalidInputError) as info:
            evaluate({"boxes": _boxes()}, methods=methods)
        assert str(info.value) == message + "; give each once"
    # estimate_many: the same rule (it ran both), with the power of its options where given (review)
    with pytest.raises(InvalidInputError, match=r"^methods names 'robust:4' twice \(as 'robust'; both are robust at "
                                                r"power 4\); give each once$"):
        estimate_many(shape, ["robust", "robust:4"])
    with pytest.raises(InvalidInputError, match="both are robust at power 3"):
        estimate_many(shape, ["robust", "robust:3"], power=3)
    from jaxpose.pose.estimators import method_key

    for bad in (float("nan"), True, 10 ** 400):  # (method_key read them: 'robust at power nan', OverflowError; review)
        with pytest.raises(InvalidInputError, match="power must be"):
            method_key("robust", {"power": bad})
    powered = estimate_many(shape, ["robust", "robust:4"], power=3)  # robust at 3 and at 4: two methods
    assert not np.array_equal(powered["robust"].center, powered["robust:4"].center)
    np.testing.assert_array_equal(powered["robust:4"].center, poses["robust"].center)
    # another power is another method, kept under the name given
    methods = ["robust", "robust:2", "depth_weighted_solid", "depth_weighted_solid:4"]
    result = evaluate({"boxes": _boxes()}, methods=methods)
    assert [row["method"] for row in result["summary"]] == methods


def test_an_empty_list_of_names_is_refused_alike():
    """evaluate(methods=[]) said "methods must not be empty", evaluate(variants=[]) "unknown variants
    []", evaluate_rotation(methods=[]) "unknown rotation methods []": one wording, check_names'
    ("methods names no method; give at least one"), as the command line's empty lists have."""
    from jaxpose.evaluation import evaluate_rotation

    for call, message in ((lambda: evaluate({"boxes": _boxes()}, methods=[]), "methods names no method"),
                          (lambda: evaluate({"boxes": _boxes()}, variants=()), "variants names no variant"),
                          (lambda: evaluate_rotation({"boxes": _boxes()}, methods=[]),
                           "methods names no rotation method")):
        with pytest.raises(InvalidInputError, match=f"^{message}; give at least one$"):
            call()


def test_align_core_iterations_follow_the_one_int_rule():
    """iterations is an int >= 0 as every count is (jaxpose._validate.check_int): 2.0 and True
    were taken as 2 and 1, None was int()'s TypeError."""
    import jax.numpy as jnp

    box = trimesh.creation.box()
    moved = box.copy()
    moved.apply_transform(trimesh.transformations.rotation_matrix(0.3, (0, 0, 1), point=(1, 2, 3)))
    two = align_core([box, moved], iterations=2)
    for same in (np.int64(2), jnp.int32(2)):
        out = align_core([box, moved], iterations=same)
        np.testing.assert_array_equal(out[1].vertices, two[1].vertices)
    for bad, message in ((2.0, "an int, got 2.0"), (True, "an int, got True"), (None, "an int, got None"),
                         (2.5, "an int, got 2.5"), (-1, ">= 0, got -1")):
        with pytest.raises(InvalidInputError, match=f"^iterations must be {message}$"):
            align_core([box, moved], iterations=bad)


# ------------------------------------------------------------------ evaluate
def test_evaluate_baselines_by_hand(fake_normalize):
    result = evaluate({"boxes": _boxes(), "same": _boxes()}, methods=["bbox", "min_ball", "surface_centroid"])
    assert [row["method"] for row in result["summary"]] == ["bbox", "min_ball", "surface_centroid"]
    cell = result["per_class"]["boxes"]["bbox"]
    np.testing.assert_allclose(cell["centers"], [[0, 0, 0], [2, 0, 0]], atol=1e-12)
    assert cell["scales"] == pytest.approx([1.0, 3.0])
    assert cell["sigma_tr"] == pytest.approx(1.0) and cell["sigma_tr_axis"] == pytest.approx(1 / 3)
    assert cell["sigma_scale"] == pytest.approx(1.0) and cell["cv_scale"] == pytest.approx(0.5)
    ball = result["per_class"]["boxes"]["min_ball"]
    assert ball["scales"] == pytest.approx([np.sqrt(3) / 2, 3 * np.sqrt(3) / 2])
    assert ball["sigma_tr"] == pytest.approx(1.0, abs=1e-9)
    centroid = result["per_class"]["boxes"]["surface_centroid"]
    np.testing.assert_allclose(centroid["centers"], [[0, 0, 0], [2, 0, 0]], atol=1e-12)
    summary = {row["method"]: row for row in result["summary"]}
    assert summary["bbox"]["sigma_tr"] == pytest.approx(1.0)  # same in both classes
    assert summary["bbox"]["seconds"] >= 0.0
    assert not fake_normalize  # ocsvm was not asked for
    import json

    json.dumps(result)


def test_evaluate_ocsvm_uses_samples_and_options(fake_normalize):
    boxes = _boxes()
    result = evaluate({"boxes": boxes}, gamma=2.0, nu=0.25, methods=["ocsvm"], count=500, seed=3,
                      resolution=16)
    cell = result["per_class"]["boxes"]["ocsvm"]
    expected = np.stack([_sample(m, 500, 3).mean(axis=0) + [2.0, 0.0, 0.0] for m in boxes])
    np.testing.assert_allclose(cell["centers"], expected, rtol=1e-12, atol=1e-12)
    assert cell["scales"] == [1.25, 1.25] and cell["sigma_scale"] == 0.0
    assert cell["sigma_tr"] == pytest.approx(spread(expected)["sigma_tr"])
    assert cell["sigma_tr"] == pytest.approx(1.0, rel=0.05)  # the box centers, 2 apart
    assert fake_normalize == [{"resolution": 16}] * 3  # a first call apart (compilation), then one per object
    assert result["params"]["normalize_options"] == {"resolution": 16}
    assert result["params"]["gamma"] == 2.0 and result["params"]["count"] == 500


def test_evaluate_refuses_the_ocsvms_options_where_nothing_reads_them():
    """evaluate(classes, methods=['bbox'], gamma=3.0, tol=1e-9) ran bbox and recorded gamma 3.0 and
    tol in result['params'], neither read; refused now, as estimate_many and ``jaxpose evaluate
    --gamma`` refuse them. An ocsvm method or the sweep reads them; left out, the defaults are
    recorded as before."""
    from jaxpose.errors import InvalidInputError

    classes = {"boxes": _boxes()}
    with pytest.raises(InvalidInputError, match=r"^gamma, tol are options of the ocsvm estimator, which the method bbox "
                                                r"does not use \(pass 'ocsvm' among the methods \(the sweep sets gamma and "
                                                r"nu itself\); or leave them out\)$"):
        evaluate(classes, methods=["bbox"], gamma=3.0, tol=1e-9)
    with pytest.raises(InvalidInputError, match=r"^tol is an option of the ocsvm estimator, .* \(pass 'ocsvm' among "
                                                r"the methods, or sweep=True; or leave it out\)$"):
        evaluate(classes, methods=["bbox"], tol=1e-9)  # the sweep reads it
    with pytest.raises(InvalidInputError, match="^count is an option of the ocsvm estimator, which the methods bbox, "):
        evaluate(classes, methods=["bbox", "vertex_mean"], count=100)
    # the sweep reads count and the normalize options, and sets gamma and nu itself (gamma was taken, unread)
    with pytest.raises(InvalidInputError, match=r"^gamma is an option of the ocsvm estimator, which the method bbox does not "
                                                r"use \(pass 'ocsvm' among the methods \(the sweep sets gamma and nu itself\); "
                                                r"or leave it out\)$"):
        evaluate(classes, methods=["bbox"], gamma=3.0, count=100, sweep=True)
    params = evaluate(classes, methods=["bbox"])["params"]
    assert (params["gamma"], params["nu"], params["count"], params["normalize_options"]) == (47.0, 0.5, 2000, {})


def test_evaluate_calls_normalize_once_per_object(fake_normalize):
    result = evaluate({"boxes": _boxes()}, methods=["ocsvm"], count=200)
    assert len(fake_normalize) == 1 + 2  # the first call, timed apart, then once per object
    assert result["per_class"]["boxes"]["ocsvm"]["converged"] == [True, True]


def test_evaluate_align_core_and_progress(fake_normalize):
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    moved = box.copy()
    moved.apply_transform(trimesh.transformations.rotation_matrix(0.7, (1, 1, 0), point=(3, 0, 0)))
    messages = []
    plain = evaluate({"box": [box, moved]}, methods=["surface_centroid"])
    aligned = evaluate({"box": [box, moved]}, methods=["surface_centroid"], align_core=True,
                       progress=lambda done, total, message: messages.append((done, total, message)))
    assert plain["per_class"]["box"]["surface_centroid"]["sigma_tr"] > 0.1
    assert aligned["per_class"]["box"]["surface_centroid"]["sigma_tr"] < 1e-10
    assert messages[1] == (0, 1, "plain: box (2 objects)") and messages[-1][:2] == (1, 1)


@pytest.mark.parametrize("kwargs", [{"methods": ["ocsvm", "median"]}, {"methods": []}])
def test_evaluate_rejects(kwargs, fake_normalize):
    with pytest.raises(InvalidInputError):
        evaluate({"boxes": _boxes()}, **kwargs)
    with pytest.raises(InvalidInputError, match="at least 2"):
        evaluate({"boxes": _boxes()[:1]})
    with pytest.raises(InvalidInputError):
        evaluate({})
    # the OCSVM's parameters and options, before any work (they became each ocsvm cell's error, or
    # went unnoticed without ocsvm)
    for bad, named in (({"bogus": 1}, "unknown option bogus"), ({"gamma": -1.0}, "gamma"), ({"nu": 2.0}, "nu"),
                       ({"count": 3}, "count"), ({"seed": -1}, "seed"), ({"resolution": 4}, "resolution")):
        with pytest.raises(InvalidInputError, match=named):
            evaluate({"boxes": _boxes()}, methods=["surface_centroid"], **bad)


def test_sweep_with_fake_normalize(fake_normalize, monkeypatch):
    # sweep calls normalize on the samples themselves: a fake whose center is gamma * mean
    _patch_normalize(monkeypatch, lambda points, gamma=47.0, nu=0.5, **options: Pose.from_center_scale(
        gamma * np.asarray(points).mean(axis=0), 1.0 + nu))
    classes = {"boxes": _boxes()}
    out = sweep(classes, "gamma", values=[1.0, 3.0], count=300)
    assert out["param"] == "gamma" and out["values"] == [1.0, 3.0] and out["fixed"] == {"nu": 0.0}
    s1, s3 = out["per_class"]["boxes"]["sigma_tr"]
    assert s3 == pytest.approx(3.0 * s1, rel=1e-12)  # the fake center scales with gamma
    assert out["average"]["sigma_tr"] == [s1, s3]
    assert out["surface_centroid"]["average"]["sigma_tr"] == pytest.approx(1.0)
    # the swept parameter in fixed is overridden by each value (it was accepted so; a check refused it)
    both = sweep(classes, "gamma", values=[1.0, 3.0], fixed={"gamma": 47.0, "nu": 0.0}, count=300)
    assert both["fixed"] == {"nu": 0.0} and both["per_class"] == out["per_class"]
    out = sweep(classes, "nu", values=[0.1, 0.5], count=300)
    assert out["fixed"] == {"gamma": 47.0}
    assert out["average"]["sigma_scale"] == [0.0, 0.0]
    with pytest.raises(InvalidInputError):
        sweep(classes, "count")


def test_evaluate_with_sweep_flag(fake_normalize, monkeypatch):
    monkeypatch.setattr(evaluation.consistency, "SWEEP_VALUES", {"gamma": (1.0, 2.0), "nu": (0.1,)})
    result = evaluate({"boxes": _boxes()}, methods=["surface_centroid"], count=100, sweep=True)
    assert set(result["sweeps"]) == {"gamma", "nu"}
    assert result["sweeps"]["gamma"]["values"] == [1.0, 2.0]
    # the table printed no sweep (jaxpose evaluate --sweep showed nothing of it without --json or --plots)
    lines = format_table(result).splitlines()
    for param, fixed in (("gamma", "nu=0"), ("nu", "gamma=47")):
        block = result["sweeps"][param]
        start = lines.index(next(line for line in lines if line.startswith(f"sweep of the ocsvm method's {param} "
                                                                               f"({fixed}), averages over classes")))
        rows = [line.split() for line in lines[start + 3:start + 3 + len(block["values"])]]
        assert [float(r[0]) for r in rows] == block["values"]
        np.testing.assert_allclose([[float(r[1]), float(r[2])] for r in rows],
                                   np.transpose([block["average"]["sigma_tr"], block["average"]["sigma_scale"]]),
                                   atol=5e-6)


def test_the_formatters_name_the_result_they_take():
    """format_table of evaluate_rotation's result (and the reverse) was a KeyError deep in the table
    ('sigma_tr', 'summary'); each names the formatter the result belongs to."""
    boxes = {"boxes": _boxes()}
    centers = evaluate(boxes, methods=["surface_centroid"])
    frames = evaluation.evaluate_rotation(boxes, methods=["pca_vertices"])
    assert format_table(centers).startswith("1 class x 2 objects, ")  # (one class: "1 classes")
    assert evaluation.format_rotation_table(frames).startswith("1 class, ")
    for fmt in (format_table, format_per_class):
        with pytest.raises(InvalidInputError, match=r"result must be the dict evaluate\(\) returns: it is "
                                                    "evaluate_rotation's, formatted by format_rotation_table"):
            fmt(frames)
        with pytest.raises(InvalidInputError, match=r"result must be the dict evaluate\(\) returns, got \{\}$"):
            fmt({})
    for fmt in (evaluation.format_rotation_table, evaluation.format_rotation_per_class):
        with pytest.raises(InvalidInputError, match="it is evaluate's, formatted by format_table / format_per_class"):
            fmt(centers)


def test_format_table_per_variant():
    rows = lambda ref: [{"method": "robust", "sigma_tr": 0.0361, "sigma_scale": 0.01425, "cv_scale": 0.1,
                         "seconds": 1.5, "sigma_tr_vs_reference": 0.0361 / 0.0475 - 1},
                        {"method": ref, "sigma_tr": 0.0475, "sigma_scale": 0.01699, "cv_scale": 0.2,
                         "seconds": 1.0, "sigma_tr_vs_reference": 0.0},
                        {"method": "solid", "sigma_tr": None, "sigma_scale": None, "cv_scale": None,
                         "seconds": 0.0, "error": "points only"}]
    result = {"params": {"gamma": 47.0, "nu": 0.5, "count": 2000, "align_core": False}, "per_class": {"a": {}},
              "variants": {"plain": {"summary": rows("surface_centroid")}, "points": {"summary": rows("vertex_mean")}}}
    text = format_table(result)
    assert "variant plain" in text and "variant points" in text and "vs vertex_mean" in text
    assert "0.03610" in text and "-24.0%" in text and "n/a" in text


def test_format_table_explains_itself_and_names_gamma_only_with_the_ocsvm():
    row = {"method": "robust", "sigma_tr": 0.01, "sigma_scale": 0.002, "cv_scale": 0.02, "seconds": 2.0,
           "seconds_per_object": 0.02, "first_call_seconds": 3.5, "sigma_tr_vs_reference": -0.5}
    params = {"gamma": 47.0, "nu": 0.5, "count": 2000, "seed": 0, "align_core": False, "objects": {"a": 10}}
    result = {"params": {**params, "methods": ["robust"]}, "per_class": {"a": {}},
              "variants": {"plain": {"summary": [row]}}}
    text = format_table(result)
    header = text.splitlines()[0]
    assert "gamma" not in header and "nu=" not in header and header.startswith("1 class x 10 objects,")  # (was "1 classes")
    for term in ("sigma_tr ", "sigma_scale ", "cv_scale ", "ms/object ", "lower is better", "compilation", "units"):
        assert term in text, term
    line = next(l for l in text.splitlines() if l.startswith("robust"))
    assert line.split()[-2:] == ["20.0", "3.5"]  # ms per object after the first call; the first call's seconds
    result["params"]["methods"] = ["robust", "ocsvm"]
    assert "gamma=47.0" in format_table(result).splitlines()[0]


def test_evaluate_times_the_first_call_apart():
    boxes = [trimesh.creation.box(extents=(1.0, 2.0, 3.0)) for _ in range(3)]
    seen = []
    result = evaluate({"boxes": boxes}, methods=["robust", "solid"], progress=lambda d, t, m: seen.append(m))
    assert seen[0] == "plain: first call of each method (compiles)" and seen[-1] == "done"
    for row in result["summary"]:
        assert row["first_call_seconds"] > 0.0 and row["seconds"] > 0.0
        assert row["seconds_per_object"] == pytest.approx(row["seconds"] / 3)


def test_format_per_class_marks_each_class_lowest():
    def cell(sigma, cv):
        return {"sigma_tr": sigma, "cv_scale": cv}

    per_class = {"plain": {"dog": {"robust": cell(0.30, 0.010), "solid": cell(0.20, 0.0102)},
                           "man": {"robust": cell(0.10, 0.001), "solid": cell(0.40, 0.020)}},
                 "points": {"dog": {"robust": cell(0.50, 0.030), "solid": {"error": "points only"}},
                            "man": {"robust": cell(0.60, 0.040), "solid": {"error": "points only"}}}}
    summary = [{"method": "robust"}, {"method": "solid"}]
    result = {"params": {"objects": {"dog": 8, "man": 10}},
              "variants": {v: {"summary": summary, "per_class": per_class[v]} for v in per_class}}
    lines = format_per_class(result).splitlines()
    dog, man = lines.index("class dog (8 objects)"), lines.index("class man (10 objects)")
    row = lambda start, method: next(l for l in lines[start:] if l.startswith(method + " ")).split()
    # the average would favour robust; per class the dog's centre is solid's
    assert row(dog, "robust")[1:] == ["0.30000", "0.01000*", "0.50000*", "0.03000*"]
    assert row(dog, "solid")[1:] == ["0.20000*", "0.01020~", "n/a", "n/a"]
    assert row(man, "robust")[1:] == ["0.10000*", "0.00100*", "0.60000*", "0.04000*"]
    assert row(man, "solid")[1:] == ["0.40000", "0.02000", "n/a", "n/a"]


def test_evaluate_variants_and_inapplicable_methods():
    import json

    classes = {"boxes": [trimesh.creation.box(extents=(1.0, 2.0, 3.0)) for _ in range(2)]}
    result = evaluate(classes, methods=["robust", "solid", "surface_centroid", "vertex_mean"],
                      variants=["plain", "points", "outliers"])
    assert list(result["variants"]) == ["plain", "points", "outliers"]
    points = {r["method"]: r for r in result["variants"]["points"]["summary"]}
    assert points["solid"]["sigma_tr"] is None and "points only" in points["solid"]["error"]
    assert points["robust"]["reference"] == "vertex_mean"
    plain = {r["method"]: r for r in result["variants"]["plain"]["summary"]}
    assert plain["solid"]["sigma_tr"] == pytest.approx(0.0, abs=1e-12)  # identical boxes
    out = result["variants"]["outliers"]["per_class"]["boxes"]
    assert out["solid"]["sigma_tr"] > 0.01  # the stray part moves the solid centroid ...
    assert out["robust"]["sigma_tr"] < 1e-9  # ... and not the robust center
    json.dumps(result)


# ------------------------------------------------------------------ end to end
def test_evaluate_end_to_end_small():
    from jaxpose.datasets import make_dataset

    classes = make_dataset(seed=0, instances=3, classes=["chair", "pot"])
    # 400 samples at resolution 32 (incidental): the OCSVM pose at 448 rows is test_pinned.py's
    # float32 program at that grid (200 samples at resolution 24 compiled one of their own, 10 CPU s)
    result = evaluate(classes, methods=["ocsvm", "surface_centroid"], count=400, resolution=32)
    assert result["params"]["normalize_options"] == {"resolution": 32}
    for name, meshes in classes.items():
        cell = result["per_class"][name]["ocsvm"]
        assert len(cell["converged"]) == 3 and all(isinstance(c, bool) for c in cell["converged"])
        centers = np.asarray(cell["centers"])
        assert np.all(np.isfinite(centers)) and np.all(np.asarray(cell["scales"]) > 0)
        for c, m in zip(centers, meshes):
            assert np.all(c > m.bounds[0] - 1e-6) and np.all(c < m.bounds[1] + 1e-6)
        assert 0.0 <= cell["sigma_tr"] < 0.2
    assert "vs surface_centroid" in format_table(result)


@pytest.mark.shared
@pytest.mark.skipif(SHARED is None, reason="needs ../shared/data/faust-dev")
def test_faust_core_alignment(tmp_path):
    from jaxpose.datasets import load_folder

    (tmp_path / "person_a").mkdir()
    for i in range(3):
        name = f"tr_reg_{i:03d}.ply"
        os.symlink(SHARED / "data" / "faust-dev" / name, tmp_path / "person_a" / name)
    classes = load_folder(tmp_path)
    aligned = align_core(classes["person_a"])
    np.testing.assert_array_equal(aligned[0].vertices, classes["person_a"][0].vertices)
    for mesh in aligned:
        rot = mesh.metadata["core_transform"][:3, :3]
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(rot) == pytest.approx(1.0)
    result = evaluate(classes, methods=["surface_centroid", "bbox"], align_core=True)
    assert all(np.isfinite(row["sigma_tr"]) for row in result["summary"])
