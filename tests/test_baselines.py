"""Classical centers and scales: analytic values, miniball oracle, equivariance."""
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from jaxpose import baselines
from jaxpose._validate import InvalidInputError, OpenMeshWarning

miniball = pytest.importorskip("miniball")  # test-only oracle


def box(extents=(1.0, 2.0, 3.0), offset=(0.3, -0.2, 0.5)):
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation(offset)
    return mesh


def lumpy(seed=0):
    """A non-symmetric mesh: an icosphere with a bump and a translated arm."""
    body = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    body.vertices[:, 0] *= 1.0 + 0.3 * (body.vertices[:, 0] > 0)
    arm = trimesh.creation.box(extents=(2.0, 0.2, 0.2))
    arm.apply_translation([2.0, 0.5, 0.1])
    return trimesh.util.concatenate([body, arm])


# --------------------------------------------------------------------------- analytic
def test_box_values():
    offset = np.array([0.3, -0.2, 0.5])
    mesh = box(offset=offset)
    np.testing.assert_allclose(baselines.surface_centroid(mesh), offset, atol=1e-12)
    np.testing.assert_allclose(baselines.vertex_mean(mesh), offset, atol=1e-12)
    np.testing.assert_allclose(baselines.bbox_center(mesh), offset, atol=1e-12)
    assert baselines.unit_cube(mesh) == pytest.approx(3.0)
    half_diagonal = np.sqrt(1 + 4 + 9) / 2
    assert baselines.unit_sphere(mesh, offset) == pytest.approx(half_diagonal)
    c, r = baselines.min_ball(mesh)
    np.testing.assert_allclose(c, offset, atol=1e-12)
    assert r == pytest.approx(half_diagonal)


def test_surface_centroid_is_area_weighted():
    # two triangles of areas 1/2 and 2 in the plane z = 0
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [3, 0, 0], [5, 0, 0], [3, 2, 0]], float)
    mesh = trimesh.Trimesh(vertices, [[0, 1, 2], [3, 4, 5]], process=False)
    c1, c2 = vertices[:3].mean(0), vertices[3:].mean(0)
    expected = (0.5 * c1 + 2.0 * c2) / 2.5
    np.testing.assert_allclose(baselines.surface_centroid(mesh), expected, atol=1e-12)


def test_refining_faces_moves_vertex_mean_not_surface_centroid():
    mesh = box(offset=(0, 0, 0))
    refined = mesh.subdivide(face_index=[0, 1])  # more vertices on one side only
    np.testing.assert_allclose(baselines.surface_centroid(refined), 0.0, atol=1e-12)
    assert np.linalg.norm(baselines.vertex_mean(refined)) > 1e-2


@pytest.mark.parametrize("radius", [0.5, 2.0])
def test_mean_distance_of_sphere_is_radius(radius):
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=radius)
    assert baselines.mean_distance(sphere, np.zeros(3)) == pytest.approx(radius, rel=2e-3)
    assert baselines.mean_distance(sphere) == pytest.approx(radius, rel=2e-3)  # centroid default


def test_mean_distance_of_square_matches_integral():
    # square [-1, 1]^2: mean distance from its center is (sqrt(2) + asinh(1)) / 3
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    square = trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)
    exact = (np.sqrt(2) + np.arcsinh(1.0)) / 3
    assert baselines.mean_distance(square, np.zeros(3)) == pytest.approx(exact, rel=2e-3)
    # away from the surface the integrand is smooth and the quadrature near-exact
    far = np.array([0.0, 0.0, 10.0])
    reference = _mean_distance_monte_carlo(square, far)
    assert baselines.mean_distance(square, far) == pytest.approx(reference, rel=1e-4)


def _mean_distance_monte_carlo(mesh, center, count=400_000):
    points, _ = trimesh.sample.sample_surface(mesh, count, seed=0)
    return float(np.linalg.norm(points - center, axis=1).mean())


def test_point_clouds_fall_back_to_points():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(200, 3))
    np.testing.assert_allclose(baselines.surface_centroid(points), points.mean(0))
    np.testing.assert_allclose(baselines.surface_centroid(trimesh.PointCloud(points)), points.mean(0))
    c = np.array([0.1, 0.2, 0.3])
    assert baselines.mean_distance(points, c) == pytest.approx(np.linalg.norm(points - c, axis=1).mean())
    assert baselines.unit_cube(points) == pytest.approx(np.ptp(points, axis=0).max())


# --------------------------------------------------------------------------- min ball
@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("kind", ["normal", "cube", "sphere", "few"])
def test_min_ball_matches_miniball(seed, kind):
    rng = np.random.default_rng(seed)
    if kind == "normal":
        points = rng.normal(size=(500, 3)) * [1.0, 2.0, 0.5] + 3.0
    elif kind == "cube":
        points = rng.uniform(-1, 1, size=(300, 3))
    elif kind == "sphere":
        points = rng.normal(size=(300, 3))
        points /= np.linalg.norm(points, axis=1, keepdims=True)
    else:
        points = rng.normal(size=(int(rng.integers(2, 7)), 3))
    center, radius = baselines.min_ball(points)
    ref_center, ref_r2 = miniball.get_bounding_ball(points, rng=np.random.default_rng(0))
    np.testing.assert_allclose(center, ref_center, atol=1e-9)
    assert radius == pytest.approx(np.sqrt(ref_r2), rel=1e-9)
    assert np.all(np.linalg.norm(points - center, axis=1) <= radius * (1 + 1e-12))


def test_min_ball_of_mesh_matches_miniball():
    mesh = lumpy()
    center, radius = baselines.min_ball(mesh)
    ref_center, ref_r2 = miniball.get_bounding_ball(np.asarray(mesh.vertices), rng=np.random.default_rng(0))
    np.testing.assert_allclose(center, ref_center, atol=1e-9)
    assert radius == pytest.approx(np.sqrt(ref_r2), rel=1e-9)


@pytest.mark.parametrize(
    "points, center, radius",
    [
        (np.array([[0, 0, 0], [2, 0, 0]] * 3, float), [1, 0, 0], 1.0),  # duplicates
        (np.array([[0, 0, 0], [1, 0, 0], [4, 0, 0]], float), [2, 0, 0], 2.0),  # collinear
        (np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0.5, 0.5, 0]], float), [0, 0, 0], 1.0),
    ],
)
def test_min_ball_degenerate_sets(points, center, radius):
    c, r = baselines.min_ball(points)
    np.testing.assert_allclose(c, center, atol=1e-12)
    assert r == pytest.approx(radius)


def test_min_ball_is_deterministic():
    points = np.random.default_rng(3).normal(size=(1000, 3))
    a, b = baselines.min_ball(points), baselines.min_ball(points)
    np.testing.assert_array_equal(a[0], b[0])
    assert a[1] == b[1]


# --------------------------------------------------------------------------- equivariance
def _moved(mesh, seed):
    rotation = Rotation.random(random_state=seed).as_matrix()
    shift = np.random.default_rng(seed).normal(size=3)
    moved = mesh.copy()
    moved.apply_transform(np.block([[rotation, shift[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
    return moved, rotation, shift


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("method", ["surface_centroid", "vertex_mean", "min_ball"])
def test_rotation_equivariant_centers(method, seed):
    mesh = lumpy()
    moved, rotation, shift = _moved(mesh, seed)
    expected = rotation @ baselines.center(mesh, method) + shift
    np.testing.assert_allclose(baselines.center(moved, method), expected, atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("method", ["mean_distance", "unit_sphere"])
def test_rotation_invariant_scales(method, seed):
    mesh = lumpy()
    moved, _, _ = _moved(mesh, seed)
    assert baselines.scale(moved, method) == pytest.approx(baselines.scale(mesh, method), rel=1e-9)


@pytest.mark.parametrize("method", baselines.CENTERS)
def test_translation_equivariant_all_centers(method):
    mesh = lumpy()
    shift = np.array([1.5, -2.0, 0.25])
    moved = mesh.copy()
    moved.apply_translation(shift)
    np.testing.assert_allclose(baselines.center(moved, method), baselines.center(mesh, method) + shift, atol=1e-9)
    assert baselines.scale(moved, "unit_cube") == pytest.approx(baselines.scale(mesh, "unit_cube"))


@pytest.mark.parametrize("offset", [1e6, 1e12])
@pytest.mark.parametrize("method", baselines.CENTERS)
def test_centers_keep_their_digits_far_from_the_origin(method, offset):
    """Every center called directly on a closed mesh at 1e6 and 1e12: within 1e-9 of the extent
    (plus the float spacing at the offset) of the same mesh moved back exactly (fl(v + o) - o is
    exact). The voxel baseline lays its grid out about one of the mesh's vertices, so the same
    voxels come out."""
    o = offset * np.array([1.0, -0.7, 0.3])
    base = trimesh.creation.capsule(height=1.0, radius=0.5, count=[12, 12])
    far = trimesh.Trimesh(base.vertices + o, base.faces, process=False)
    near = trimesh.Trimesh(far.vertices - o, base.faces, process=False)
    error = np.abs(baselines.center(far, method) - o - baselines.center(near, method)).max()
    assert error <= 2e-9 + 2 * np.spacing(offset), (method, error)


def test_scales_are_homogeneous():
    mesh = lumpy()
    big = mesh.copy()
    big.apply_scale(2.5)
    for method in baselines.SCALES:
        assert baselines.scale(big, method) == pytest.approx(2.5 * baselines.scale(mesh, method), rel=1e-9)


# --------------------------------------------------------------------------- dispatch & errors
def test_dispatch_matches_functions():
    mesh = lumpy()
    np.testing.assert_array_equal(baselines.center(mesh, "bbox_center"), baselines.bbox_center(mesh))
    np.testing.assert_array_equal(baselines.center(mesh, "min_ball"), baselines.min_ball(mesh)[0])
    c = baselines.vertex_mean(mesh)
    assert baselines.scale(mesh, "unit_sphere", center=c) == baselines.unit_sphere(mesh, c)
    assert baselines.scale(mesh, "mean_distance") == baselines.mean_distance(mesh, baselines.surface_centroid(mesh))


def test_unknown_method_lists_valid_names():
    with pytest.raises(InvalidInputError, match="surface_centroid.*min_ball"):
        baselines.center(box(), "centroid")
    with pytest.raises(InvalidInputError, match="mean_distance"):
        baselines.scale(box(), "diameter")


@pytest.mark.parametrize(
    "bad",
    [np.array([[0.0, np.nan, 0.0], [1, 1, 1]]), np.zeros((5, 2)), np.array([["a", "b", "c"]])],
)
def test_bad_points_raise(bad):
    with pytest.raises(InvalidInputError):
        baselines.vertex_mean(bad)


def test_bad_center_raises():
    with pytest.raises(InvalidInputError, match="center"):
        baselines.mean_distance(box(), [0.0, 1.0])
    for bad in ("x", ["a", "b", "c"], [True, False, True], {"x": 0.0}):  # "x": float()'s raw ValueError; bools taken as 1/0
        with pytest.raises(InvalidInputError, match="^center must be 3 finite numbers"):
            baselines.scale(box(), "mean_distance", center=bad)


def test_solid_centroid_is_trimesh_center_mass_for_a_closed_mesh_only():
    """The docstring's contract: trimesh's center_mass for a closed mesh; for an open one (warned)
    the two differ (each sums tetrahedra to its own reference point: the vertex mean here, trimesh's
    the origin), and this one moves with the mesh. It said 'the same' without the condition."""
    import re
    import warnings

    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    box.apply_translation([5.0, 1.0, 0.0])
    center_mass = lambda m: trimesh.triangles.mass_properties(m.triangles)["center_mass"]
    np.testing.assert_allclose(baselines.solid_centroid(box), center_mass(box), rtol=0, atol=1e-12)
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-2], process=False)  # one side open
    moved = open_box.copy()
    moved.apply_translation([10.0, 0.0, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OpenMeshWarning)
        ours, theirs = baselines.solid_centroid(open_box), center_mass(open_box)
        assert np.abs(ours - theirs).max() > 1.0
        np.testing.assert_allclose(baselines.solid_centroid(moved) - ours, [10.0, 0.0, 0.0], atol=1e-12)
    doc = " ".join(baselines.solid_centroid.__doc__.split())
    claim = next(s for s in re.split(r"(?<=\.) ", doc) if "center_mass" in s)
    assert "closed" in claim, claim  # the equality is a closed mesh's
    assert "open" in doc and "differ" in doc, doc


def test_a_method_name_given_as_an_array_is_refused_by_name():
    """baselines.center / scale / frame (and rotation.frame_of, tuning.tune, evaluation's variants
    and rotations) compared an array of names element-wise: NumPy's "truth value of an array is
    ambiguous" ValueError, or a one-element array taken as its name and then "unhashable type".
    One rule (config.is_name): a name is a str among the valid ones."""
    from jaxpose.evaluation import variants
    from jaxpose.rotation.rotation import frame_of

    box = trimesh.creation.box()
    two, one = np.array(["bbox_center", "vertex_mean"]), np.array(["bbox_center"])
    for call, message in ((lambda m: baselines.center(box, m), "unknown center method"),
                          (lambda m: baselines.scale(box, m), "unknown scale method"),
                          (lambda m: baselines.frame(box, m), "unknown frame method"),
                          (lambda m: frame_of(box, m), "unknown rotation"),
                          (lambda m: variants.make_class([box, box], m, 0, 0), "unknown variant")):
        for name in (two, one):
            with pytest.raises(InvalidInputError, match=message):
                call(name)
    np.testing.assert_allclose(baselines.center(box, "bbox_center"), box.bounds.mean(axis=0))
