"""Surface samples: deterministic per seed, exact counts, on the surface, stratified or area-weighted;
lattice points."""
import numpy as np
import pytest
import trimesh

from jaxpose import sample
from jaxpose.config import MEMORY_BUDGET
from jaxpose._validate import InvalidInputError


def lumpy():
    body = trimesh.creation.capsule(height=1.0, radius=0.5)
    arm = trimesh.creation.box(extents=(1.5, 0.2, 0.2))
    arm.apply_translation([1.2, 0.0, 0.3])
    return trimesh.util.concatenate([body, arm])


@pytest.mark.parametrize("method", ["even", "random"])
def test_sample_surface_shape_and_determinism(method):
    shape = lumpy()
    a = sample.sample_surface(shape, 1001, seed=7, method=method)
    b = sample.sample_surface(shape, 1001, seed=7, method=method)
    c = sample.sample_surface(shape, 1001, seed=8, method=method)
    assert a.shape == (1001, 3) and a.dtype == np.float64
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


@pytest.mark.parametrize("count", [4, 5, 7, 97, 2000])
def test_even_sampling_returns_exact_count(count):
    assert sample.sample_surface(lumpy(), count, seed=1).shape == (count, 3)


@pytest.mark.parametrize("method", ["even", "random"])
def test_samples_lie_on_the_surface(method):
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    points = sample.sample_surface(box, 500, seed=0, method=method)
    on_a_side = np.isclose(np.abs(points), [0.5, 1.0, 1.5]).any(axis=1)
    assert on_a_side.all()
    assert np.all(np.abs(points) <= np.array([0.5, 1.0, 1.5]) + 1e-12)


def test_even_sampling_is_stratified_by_area():
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    for seed in range(5):
        points = sample.sample_surface(box, 600, seed=seed, method="even")
        side = np.argmax(np.abs(points), axis=1) * 2 + (points[np.arange(600), np.argmax(np.abs(points), axis=1)] > 0)
        counts = np.bincount(side, minlength=6)
        assert np.all(np.abs(counts - 100) <= 2), counts  # two faces per side, each floor/ceil of 50


def test_random_sampling_is_area_weighted():
    slab = trimesh.creation.box(extents=(10.0, 1.0, 1.0))
    points = sample.sample_surface(slab, 20000, seed=0, method="random")
    on_end_caps = np.isclose(np.abs(points[:, 0]), 5.0).mean()
    assert on_end_caps == pytest.approx(2.0 / 42.0, abs=0.006)


def test_point_cloud_sampling():
    points = np.random.default_rng(0).normal(size=(100, 3))
    fewer = sample.sample_surface(points, 60, seed=0)
    assert len(np.unique(fewer, axis=0)) == 60  # without replacement
    assert all(any(np.array_equal(p, q) for q in points) for p in fewer)
    more = sample.sample_surface(trimesh.PointCloud(points), 300, seed=0)
    assert more.shape == (300, 3)
    np.testing.assert_array_equal(more, sample.sample_surface(points, 300, seed=0))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"count": 3}, "count"),
        ({"count": 10.0}, "count"),
        ({"count": True}, "count"),
        ({"count": 10, "seed": -1}, "seed"),
        ({"count": 10, "seed": 1.5}, "seed"),
        ({"count": 10, "method": "poisson"}, "sampling"),
        ({"count": 10**12}, r"count=1000000000000 samples need about .* GiB; the limit is 2 GiB"),  # was a MemoryError
    ],
)
def test_sample_surface_validation(kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        sample.sample_surface(lumpy(), **kwargs)


def test_normalize_mesh_refuses_a_count_beyond_memory():
    """The count of normalize_mesh (and --count) is checked against the memory budget before any
    work (it was a raw MemoryError from the sampler); the largest count allowed still passes."""
    from jaxpose.mesh import check_arguments

    check_arguments(count=sample.check_count(MEMORY_BUDGET // sample.SAMPLE_BYTES), method="ocsvm")
    with pytest.raises(InvalidInputError, match="count=.* the limit is"):
        check_arguments(count=MEMORY_BUDGET // sample.SAMPLE_BYTES + 1, method="ocsvm")


def test_lattice_points_cover_the_faces_and_move_with_the_mesh():
    """Every point of a box's surface lies within the spacing of a lattice point (the lattice's
    cells are triangles of edge <= spacing); a moved box gives the same points, moved; small faces
    add nothing."""
    from scipy.spatial import cKDTree

    box = trimesh.creation.box(extents=(1.0, 2.0, 0.5))
    points = sample.lattice_points(box.vertices, box.faces, 0.3)
    np.testing.assert_array_equal(points[:8], box.vertices)
    probe = sample.sample_surface(box, 5000, seed=0, method="random")
    assert cKDTree(points).query(probe)[0].max() <= 0.3
    q, _ = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))
    moved = sample.lattice_points(box.vertices @ q.T + 1.0, box.faces, 0.3)
    np.testing.assert_allclose(moved, points @ q.T + 1.0, atol=1e-12)
    np.testing.assert_array_equal(sample.lattice_points(box.vertices, box.faces, 10.0), box.vertices)
    np.testing.assert_array_equal(sample.lattice_points(box.vertices, None, 0.3), box.vertices)


@pytest.mark.parametrize("spacing", [1e-4, 1e-9, 1e-300])
def test_lattice_points_refuse_a_spacing_whose_points_exceed_the_memory_budget(spacing):
    """A spacing tiny for the faces was a lattice of (L / spacing)^2 points per face: at 1e-9 on a
    unit box the process was killed filling the memory; now refused before anything is allocated,
    naming a spacing that fits (whose points do, within 1 %)."""
    import re

    box = trimesh.creation.box(extents=(1.0, 2.0, 0.5))
    with pytest.raises(InvalidInputError, match="spacing=.* points on the faces; .* at least about") as raised:
        sample.lattice_points(box.vertices, box.faces, spacing)
    least = float(re.search(r"at least about (\S+)$", str(raised.value)).group(1))
    t = box.vertices[box.faces]
    n = np.ceil(np.max(np.linalg.norm(t - np.roll(t, 1, axis=1), axis=2), axis=1) / least)
    assert np.sum((n + 1) * (n + 2) / 2 - 3) * sample.LATTICE_BYTES <= 1.01 * MEMORY_BUDGET


@pytest.mark.parametrize("spacing", [0.0, -1.0, float("nan"), "a"])
def test_lattice_points_refuse_a_spacing_that_is_not_positive(spacing):
    box = trimesh.creation.box()
    with pytest.raises(InvalidInputError, match="spacing"):
        sample.lattice_points(box.vertices, box.faces, spacing)


@pytest.mark.parametrize("vertices, faces, message", [
    # NaN vertices gave NaN points; float faces were truncated (0.5 read as 0), an index past the vertices
    # NumPy's IndexError, (n, 2) vertices NumPy's reshape ValueError
    (lambda box: np.where(np.arange(8)[:, None] == 0, np.nan, box.vertices), lambda box: box.faces,
     r"^vertices has 1 row with NaN or inf coordinates"),
    (lambda box: box.vertices, lambda box: box.faces + 0.5, r"^faces must be \(f, 3\) integer indices of the vertices"),
    (lambda box: box.vertices, lambda box: box.faces + 100, r"^faces index vertices that do not exist"),
    (lambda box: box.vertices, lambda box: box.faces - 1, r"^faces index vertices that do not exist \(indices -1"),
    (lambda box: box.vertices[:, :2], lambda box: box.faces, r"^vertices must have shape \(m, 3\), got \(8, 2\)"),
])
def test_lattice_points_refuse_vertices_and_faces_that_are_no_mesh(vertices, faces, message):
    box = trimesh.creation.box()
    with pytest.raises(InvalidInputError, match=message):
        sample.lattice_points(vertices(box), faces(box), 0.5)
