"""The filled voxel solid: volumes, depths and centroids against closed forms."""
import numpy as np
import pytest
import trimesh

from jaxpose import baselines
from jaxpose.occupancy import voxels
from jaxpose.errors import InvalidInputError, OpenMeshWarning


def test_filled_voxels_of_a_box_have_its_volume_and_depths():
    box = trimesh.creation.box((2.0, 1.0, 0.5))
    x, depth = voxels.filled_voxels(box, voxels=64)
    pitch = 2.0 / 64
    assert np.allclose(np.diff(np.unique(np.round(x[:, 0] / pitch, 6))), 1.0)  # a lattice of pitch 2 / 64
    # The surface voxels are kept whole: the solid is the box grown by at most one voxel per side.
    volume = len(x) * pitch ** 3
    grown = (2.0 + 2 * pitch) * (1.0 + 2 * pitch) * (0.5 + 2 * pitch)
    assert 1.0 <= volume <= grown, volume
    assert np.all(x.min(axis=0) > -np.array([1.0, 0.5, 0.25]) - pitch)
    assert np.all(x.max(axis=0) < np.array([1.0, 0.5, 0.25]) + pitch)
    # Depth: the Euclidean distance in voxels to the nearest outside voxel; the thinnest side
    # (0.5 = 16 voxels, 17 or 18 occupied) bounds it.
    assert depth.min() == 1.0 and 8.0 <= depth.max() <= 9.5


def test_depth_weighted_solid_of_a_cone_moves_from_its_centroid_to_its_deepest_point():
    """A cone (radius 1, height 2, base at z = 0): its solid centroid is at z = h / 4 = 0.5 (closed
    form) and its deepest point, the center of the inscribed sphere, at z = r h / (r + sqrt(r^2 +
    h^2)) = 0.618. Power 0 gives the centroid (within a voxel); higher powers move the center up the
    axis toward the deepest point, never past it."""
    cone = trimesh.creation.cone(radius=1.0, height=2.0, sections=64)
    pitch, deepest = 2.0 / 96, 2.0 / (1.0 + 5.0 ** 0.5)
    centers = np.array([voxels.depth_weighted_solid(cone, power=p, voxels=96) for p in (0.0, 2.0, 4.0, 16.0)])
    assert np.abs(centers[:, :2]).max() <= pitch, centers
    assert cone.center_mass[2] == pytest.approx(0.5, abs=1e-12)
    assert centers[0, 2] == pytest.approx(0.5, abs=pitch)
    assert np.all(np.diff(centers[:, 2]) > 0) and centers[-1, 2] < deepest + pitch, centers[:, 2]


def test_weighted_centroid_is_the_weighted_mean_and_keeps_its_digits():
    rng = np.random.default_rng(0)
    x, w = rng.normal(size=(1000, 3)), rng.uniform(0, 1, 1000)
    np.testing.assert_allclose(voxels.weighted_centroid(x, w), np.average(x, axis=0, weights=w), rtol=0, atol=1e-15)
    far = 1e9 + x  # 1e9 + x is exact to the float spacing at 1e9 (1.2e-7)
    error = np.abs(voxels.weighted_centroid(far, w) - 1e9 - np.average(far - 1e9, axis=0, weights=w)).max()
    assert error <= 2 * np.spacing(1e9), error


def test_baselines_name_the_same_functions():
    for name in ("depth_weighted_solid", "filled_voxels", "weighted_centroid"):
        assert getattr(baselines, name) is getattr(voxels, name)
    box = trimesh.creation.box((2.0, 1.0, 1.0))
    np.testing.assert_array_equal(baselines.center(box, "depth_weighted_solid"), voxels.depth_weighted_solid(box))


def test_bad_input_is_refused_clearly():
    box = trimesh.creation.box()
    with pytest.raises(InvalidInputError, match="depth_weighted_solid needs a mesh with faces"):
        voxels.depth_weighted_solid(box.vertices)
    # the one int rule (jaxpose._validate.check_int): 16.0 was taken as 16, None was int()'s TypeError
    for bad, message in ((7, ">= 8, got 7"), (8.5, "an int, got 8.5"), (True, "an int, got True"),
                         (16.0, "an int, got 16.0"), (np.float64(16.0), r"an int, got np.float64\(16.0\)"),
                         (None, "an int, got None"), ("16", "an int, got '16'")):
        with pytest.raises(InvalidInputError, match=f"^voxels must be {message}$"):
            voxels.filled_voxels(box, voxels=bad)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(InvalidInputError, match="power must be a finite number >= 0"):
            voxels.depth_weighted_solid(box, power=bad)
    holed = trimesh.Trimesh(box.vertices, box.faces[:-1], process=False)
    with pytest.warns(OpenMeshWarning, match="depth_weighted_solid: the mesh is not closed"):
        voxels.depth_weighted_solid(holed)
    with pytest.raises(InvalidInputError, match="strict=True"):
        voxels.depth_weighted_solid(holed, strict=True)
