"""The robust voxel solid: analytic volumes, holes, stray parts, unions, point clouds, frames."""
import numpy as np
import pytest
import trimesh

from jaxpose import InvalidInputError
from jaxpose.occupancy.solid import cap_holes, exterior_fill, keep_main, robust_solid


def _solid(mesh, **kw):
    return robust_solid(np.asarray(mesh.vertices), np.asarray(mesh.faces), **kw)


def test_sphere_volume_and_depth():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    s = _solid(sphere)
    assert s.volume() == pytest.approx(sphere.volume, rel=0.01)
    assert float(s.depth.max()) == pytest.approx(1.0, abs=1.5 * s.pitch)  # the center is 1 deep
    np.testing.assert_allclose(s.centers().mean(axis=0), 0.0, atol=0.01)
    assert s.components == 1 and s.dropped == 0 and s.occupied is None


def test_holes_are_voted_over_and_capped():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    keep = np.abs(sphere.triangles_center[:, 0]) < 0.9  # two polar holes of radius ~0.44
    holed = trimesh.Trimesh(sphere.vertices, sphere.faces[keep], process=False)
    assert not holed.is_watertight
    s = _solid(holed)
    caps = np.pi * 0.1 ** 2 * (3 - 0.1) / 3  # the two domes beyond the cap planes are undetermined
    assert s.volume() == pytest.approx(sphere.volume - 2 * caps, rel=0.02)
    v, c = cap_holes(np.asarray(holed.vertices), np.asarray(holed.faces))
    assert len(v) == len(holed.vertices) + 2 and trimesh.Trimesh(v, np.vstack([holed.faces, c])).is_watertight


def test_union_kept_separate_small_part_dropped():
    a = trimesh.creation.box([2, 1, 1])
    b = trimesh.creation.box([1, 2, 1])
    b.apply_translation([0.5, 0.5, 0])  # overlaps a: the union counts once
    small = trimesh.creation.icosphere(radius=0.3)
    small.apply_translation([4, 0, 0])
    s = _solid(trimesh.util.concatenate([a, b, small]))
    assert s.volume() == pytest.approx(3.0, rel=0.03)  # the first pass left the far part out of the grid
    main = _solid(trimesh.util.concatenate([a, b]))
    np.testing.assert_allclose(s.centers().mean(0), main.centers().mean(0), atol=1e-9)  # the stray part is gone


@pytest.mark.parametrize("far", [5.0, 10.0, 30.0, 1e3, 1e6])
def test_a_speck_far_away_changes_nothing(far):
    """A speck of 1 % of the body's length, ``far`` body lengths away (a scan's stray bit): the solid
    is the body's alone, voxel for voxel, and so is normalize_mesh's pose. The first pass's grid was
    the box of everything: at 10 lengths the body's limbs fell between its voxel centers and the
    fine grid cut them off (center 0.59 of the scale off, scale +14 %, valid; at 30 lengths and more
    'the shape encloses no volume')."""
    import jaxpose
    from jaxpose.datasets import make_object

    body = make_object("human", 0, 0)  # thin arms and legs; 1 unit tall
    speck = trimesh.creation.icosphere(subdivisions=1, radius=0.01)
    speck.apply_translation([far, 0.0, 0.0])
    both = trimesh.util.concatenate([body, speck])
    alone, with_speck = _solid(body), _solid(both)
    assert with_speck.pitch == alone.pitch and with_speck.inside.shape == alone.inside.shape
    np.testing.assert_array_equal(with_speck.origin, alone.origin)
    np.testing.assert_array_equal(with_speck.inside, alone.inside)
    _, pose = jaxpose.normalize_mesh(both)
    _, reference = jaxpose.normalize_mesh(body)
    np.testing.assert_allclose(pose.center, reference.center, rtol=0, atol=1e-12)
    assert float(pose.scale) == pytest.approx(float(reference.scale), rel=1e-12) and bool(pose.valid)


def test_surface_box_finds_the_main_surface_by_area():
    """surface_box: the box of everything where no part lies apart, or where the parts apart hold at
    least keep_ratio of the largest one's area; the main surface's box where a small part lies far."""
    from jaxpose.occupancy.solid import surface_box

    body = trimesh.creation.box(extents=(1.0, 2.0, 3.0))  # 12 faces, each longer than a voxel: their lattice joins them
    lo, hi = body.bounds
    assert all(np.array_equal(a, b) for a, b in zip(surface_box(body.vertices, body.faces, lo, hi), (lo, hi)))
    # a dense small sphere (1280 faces, 642 vertices) 100 lengths away: the body's 12 faces hold more area
    speck = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    speck.apply_translation([300.0, 0.0, 0.0])
    both = trimesh.util.concatenate([body, speck])
    got = surface_box(both.vertices, both.faces, *both.bounds)
    np.testing.assert_array_equal(got[0], lo)
    np.testing.assert_array_equal(got[1], hi)
    # a second body as large as the first, far away: both kept, no zoom (keep_main keeps both too)
    twin = body.copy()
    twin.apply_translation([300.0, 0.0, 0.0])
    pair = trimesh.util.concatenate([body, twin])
    got = surface_box(pair.vertices, pair.faces, *pair.bounds)
    np.testing.assert_array_equal(got[0], pair.bounds[0])
    np.testing.assert_array_equal(got[1], pair.bounds[1])


def test_surface_box_refuses_bad_arguments_by_name():
    """surface_box (in __all__) checked nothing: coarse=0 was a ZeroDivisionError, faces beyond the
    vertices an IndexError, keep_ratio=-1 taken; each refused as robust_solid refuses it."""
    from jaxpose.occupancy.solid import surface_box

    body = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    twin = body.copy()
    twin.apply_translation([300.0, 0.0, 0.0])
    pair = trimesh.util.concatenate([body, twin])  # parts apart: the faces are read
    v, f, (lo, hi) = pair.vertices, pair.faces, pair.bounds
    for kwargs, message in ((dict(coarse=0), "coarse must be"), (dict(keep_ratio=-1), "keep_ratio must be"),
                            (dict(keep_ratio=1.5), r"keep_ratio must be in \[0, 1\]"),
                            (dict(faces=f + len(v)), "faces index vertices that do not exist"),
                            (dict(faces=f[:, :2]), r"faces must be \(f, 3\)")):
        args = {"vertices": v, "faces": f, "lo": lo, "hi": hi, "coarse": 32, **kwargs}
        with pytest.raises(InvalidInputError, match=message):
            surface_box(**args)


def test_sharp_tips_stay_on_the_fine_grid():
    """A tetrahedron's corners and a cone's apex lie more than a coarse voxel from the coarse
    solid, so the first pass finds few of their vertices on the main body: the fine grid must
    still hold the whole body (it ended at the vertices found: the tetrahedron's grid had no
    extent, a ValueError; the cone kept 6 % of its volume). Analytic volumes are the oracle."""
    tet = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    cone = trimesh.creation.cone(radius=0.5, height=2.0, sections=64)
    assert tet.is_watertight and cone.is_watertight
    assert _solid(tet).volume() == pytest.approx(1 / 6, rel=0.01)
    assert _solid(cone).volume() == pytest.approx(cone.volume, rel=0.01)  # the 64-gon pyramid's exact volume


@pytest.mark.parametrize("subdivisions, far", [(2, 3.0), (3, 3.0), (2, 5.0)])
def test_a_thin_spike_is_not_cut_by_the_fine_grid(subdivisions, far):
    """A sphere with one vertex pulled out to ``far`` radii: a spike on the same surface, thinner
    than a coarse voxel before its tip. The first pass's box ends at the vertices within a coarse
    voxel of the coarse solid, so the fine solid, which resolves the spike farther out, reached the
    edge of its grid and was cut there (it ended at x = 2.71, 2.28, 3.92; now 2.77, 2.56, 4.34). Now the box takes in the
    surfaces lying mostly on the fine solid: the solid is, voxel for voxel, the one on its lattice
    with ten more voxels each side (ray_vote_solid, exterior_fill, keep_main on that grid)."""
    from jaxpose.occupancy.solid import MESH_REACH, ray_vote_solid

    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = m.vertices.copy()
    v[np.argmax(v[:, 0])] *= far
    s = _solid(trimesh.Trimesh(v, m.faces, process=False))
    wide = ray_vote_solid(v, m.faces, s.origin - 10 * s.pitch, s.pitch, np.array(s.inside.shape) + 20)[0]
    np.testing.assert_array_equal(np.argwhere(keep_main(exterior_fill(wide, MESH_REACH))[0]),
                                  np.argwhere(s.inside) + 10)


def test_two_equal_parts_are_both_kept():
    a, b = trimesh.creation.box([1, 1, 1]), trimesh.creation.box([1, 1, 1])
    b.apply_translation([3, 0, 0])
    s = _solid(trimesh.util.concatenate([a, b]))
    assert s.dropped == 0 and s.components == 2
    assert s.centers().mean(0)[0] == pytest.approx(1.5, abs=0.02)


def test_inverted_mesh_is_the_same_solid():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    inverted = sphere.copy()
    inverted.invert()
    assert _solid(inverted).volume() == pytest.approx(_solid(sphere).volume(), rel=1e-12)


def test_point_cloud_solid():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    points, _ = trimesh.sample.sample_surface(sphere, 20000, seed=0)
    s = robust_solid(points)
    assert s.occupied is not None
    assert s.volume() == pytest.approx(sphere.volume, rel=0.05)
    np.testing.assert_allclose(s.centers().mean(0), 0.0, atol=0.02)


def test_frame_rotates_the_grid():
    capsule = trimesh.creation.capsule(height=2.0, radius=0.5)
    q, _ = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    turned = capsule.copy()
    turned.apply_transform(np.block([[q, np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]]))
    a, b = _solid(capsule), _solid(turned, frame=q.T)  # the grid turned with the shape
    assert b.volume() == pytest.approx(a.volume(), rel=1e-9)
    np.testing.assert_allclose(np.sort(b.centers() @ q, axis=0), np.sort(a.centers(), axis=0), atol=1e-9)


def test_fill_and_components_helpers():
    shell = np.zeros((7, 7, 7), bool)
    shell[1:6, 1:6, 1:6] = True
    shell[2:5, 2:5, 2:5] = False  # a closed cavity
    assert exterior_fill(shell)[3, 3, 3] and exterior_fill(shell).sum() == 125
    two = np.zeros((9, 3, 3), bool)
    two[0:4], two[6:7] = True, True
    kept, n, dropped = keep_main(two)
    assert n == 2 and dropped == 1 and kept[:4].all() and not kept[6:].any()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exterior_fill_against_scipy(seed):
    """reach 0 is scipy's binary_fill_holes; reach 1 is the outside a ball of one voxel's radius
    reaches, built from scipy's exact distance transform: the free voxels farther than 1 from the
    solid (beyond the grid free), those connected to the border, and every free voxel within 1 of them."""
    from scipy import ndimage

    rng = np.random.default_rng(seed)
    solid = ndimage.binary_dilation(rng.random((18, 15, 16)) < 0.08)  # pockets, slits, cavities
    assert np.array_equal(exterior_fill(solid), ndimage.binary_fill_holes(solid))
    free = np.pad(~solid, 1, constant_values=True)
    lab, _ = ndimage.label(ndimage.distance_transform_edt(free) > 1)
    faces = np.concatenate([f.ravel() for f in (lab[0], lab[-1], lab[:, 0], lab[:, -1], lab[:, :, 0], lab[:, :, -1])])
    reached = np.isin(lab, faces[faces > 0])
    outside = (ndimage.distance_transform_edt(~reached) <= 1) & free
    expected = ~outside[1:-1, 1:-1, 1:-1]
    got = exterior_fill(solid, reach=1)
    assert np.array_equal(got, expected) and (got & ~exterior_fill(solid)).any()
    with pytest.raises(InvalidInputError, match="reach"):
        exterior_fill(solid, reach=2)


@pytest.mark.parametrize("gap", [0.5, 4.0])
def test_a_slit_the_grid_cannot_resolve_is_filled(gap):
    """Two slabs ``gap`` voxels apart, joined along one edge (a slit open on three sides): a slit
    half a voxel wide, which voxel centers may or may not straddle, is part of the mesh's solid;
    one four voxels wide stays open."""
    res, extent = 48, 2.0
    h = extent / res
    a = trimesh.creation.box(extents=(extent, 1.0, 0.5))
    b = a.copy()
    a.apply_translation((0, 0, -(0.25 + gap * h / 2)))
    b.apply_translation((0, 0, 0.25 + gap * h / 2))
    bar = trimesh.creation.box(extents=(0.3, 1.0, gap * h + 0.2))
    bar.apply_translation((extent / 2 - 0.15, 0, 0))
    mesh = trimesh.util.concatenate([a, b, bar])  # overlapping closed parts: a union
    s = _solid(mesh, resolution=res)
    mid = s.centers()
    in_slit = np.abs(mid[:, 2]) < gap * h / 2
    assert (in_slit & (np.abs(mid[:, 0]) < 0.5)).any() == (gap < 1)


def test_degenerate_input():
    with pytest.raises(InvalidInputError, match="no extent"):
        robust_solid(np.ones((10, 3)))


@pytest.mark.parametrize("kw, message", [
    # each was taken: an empty solid (keep_ratio 2, min_votes 7, a skewed frame), the whole grid inside
    # (min_votes 0), 'no' as True; a face beyond the vertices was an IndexError in the ray votes; a NaN
    # vertex read 'the shape has no extent'
    (dict(keep_ratio=2.0), r"keep_ratio must be in \[0, 1\], got 2.0"),
    (dict(min_votes=0), "min_votes must be >= 1, got 0"),
    (dict(min_votes=7), r"min_votes must be in 1 \.\.\. 6"),
    (dict(with_depth="no"), "with_depth must be True or False"),
    (dict(frame=np.ones((3, 3))), r"frame must be a \(3, 3\) rotation"),
    (dict(faces=np.array([[0, 1, 100]])), "faces index vertices that do not exist"),
    # (whole-number floats are indices, as jaxpose.mesh.load takes them; a fraction was truncated)
    (dict(faces=np.array([[0.0, 1.0, 2.5]])), r"faces must be \(f, 3\) integer indices .* with fractions"),
    (dict(vertices=np.array([[0.0, 0.0, 0.0], [np.nan, 1.0, 0.0], [1.0, 0.0, 0.0]])), "vertices has 1 row with NaN"),
])
def test_bad_arguments_are_refused_by_name(kw, message):
    box = trimesh.creation.box()
    args = {"vertices": np.asarray(box.vertices), "faces": np.asarray(box.faces), **kw}
    with pytest.raises(InvalidInputError, match=message):
        robust_solid(args.pop("vertices"), args.pop("faces"), **args)


def test_voxel_memory_is_bounded():
    import jax.numpy as jnp

    from jaxpose.occupancy.solid import check_resolution

    assert check_resolution(96) == 96 and check_resolution(291) == 291
    with pytest.raises(InvalidInputError, match=r"resolution=1000 needs up to 65\.\d+ GiB .* use a resolution in \[8, 291\]"):
        robust_solid(np.random.default_rng(0).normal(size=(50, 3)), resolution=1000)
    # the library's int rule and its messages (config's resolution and normalize's read so; these read
    # "resolution must be >= 8 (an int), got 96.0")
    for bad in (7.5, True, 96.0, np.float32(96), jnp.array([96]), float("inf")):
        with pytest.raises(InvalidInputError, match=r"^resolution must be an int, got "):
            check_resolution(bad)
    for bad in (7, np.int64(7), -1):
        with pytest.raises(InvalidInputError, match=r"^resolution must be >= 8, got (7|-1)$"):
            check_resolution(bad)
    for good in (np.int64(96), jnp.int32(96), np.array(96, dtype=np.uint16)):  # integer scalars: config's rule
        assert check_resolution(good) == 96 and type(check_resolution(good)) is int
    # robust_solid's coarse is named so (it read "resolution must be an int, got 7.5")
    cloud = np.random.default_rng(0).normal(size=(50, 3))
    for coarse, message in ((7.5, r"^coarse must be an int, got 7\.5$"), (7, r"^coarse must be >= 8, got 7$"),
                            (1000, r"^coarse=1000 needs up to 65\.\d+ GiB .* use a coarse in \[8, 291\]")):
        with pytest.raises(InvalidInputError, match=message):
            robust_solid(cloud, coarse=coarse)


def test_point_spacing_from_a_subset(monkeypatch):
    """Above SPACING_SAMPLES points the spacing is measured from a seeded subset of them (to all
    the others): the same closing radius and nearly the same solid as from every point."""
    import jaxpose.occupancy.solid as solid

    sphere = trimesh.creation.icosphere(subdivisions=3)
    points = trimesh.sample.sample_surface(sphere, 2000, seed=0)[0]
    full = robust_solid(points)
    monkeypatch.setattr(solid, "SPACING_SAMPLES", 400)
    sub = robust_solid(points)
    assert sub.pitch == pytest.approx(full.pitch, rel=0.05)
    assert sub.volume() == pytest.approx(full.volume(), rel=0.02)
    r_all = solid.neighbour_distances(points, 4)[:, 3]
    r_sub = solid.neighbour_distances(points, 4, samples=400, seed=3)[:, 3]
    assert len(r_sub) == 400 and set(np.round(r_sub, 12)) <= set(np.round(r_all, 12))


@pytest.mark.parametrize("seed", (1.5, True, -1, "a", np.float64(2.0)))
def test_neighbour_distances_refuses_a_seed_that_is_not_an_int(seed):
    """A bad seed is refused by name, as at every entry point (1.5 and "a" were NumPy's TypeError,
    -1 its ValueError; True was taken as 1)."""
    from jaxpose.occupancy.solid import neighbour_distances

    points = np.random.default_rng(0).normal(size=(100, 3))
    with pytest.raises(InvalidInputError, match="^seed must be"):
        neighbour_distances(points, 4, samples=10, seed=seed)
    np.testing.assert_array_equal(neighbour_distances(points, 4, samples=10, seed=np.int64(3)),
                                  neighbour_distances(points, 4, samples=10, seed=3))


def test_near_solid_checks_its_arguments():
    """solid.near_solid (public): one point (3,) was an IndexError, a NaN point or a pitch 0 read as
    off the solid (False, no error), grow=-1 scipy's dilation repeated until nothing changed (every
    voxel near); refused by name. In range: the voxel lookup, checked against the grid by hand."""
    from jaxpose.occupancy.solid import near_solid

    kept = np.zeros((4, 4, 4), bool)
    kept[1, 1, 1] = True
    x = np.array([[1.5, 1.5, 1.5], [2.5, 2.5, 2.5], [3.5, 3.5, 3.5], [-9.0, 0.0, 0.0]])
    np.testing.assert_array_equal(near_solid(x, kept, np.zeros(3), 1.0, grow=0), [True, False, False, False])
    np.testing.assert_array_equal(near_solid(x, kept, np.zeros(3), 1.0, grow=1), [True, True, False, False])
    for call, message in [
        (lambda: near_solid(x[0], kept, np.zeros(3), 1.0), r"^x must have shape \(m, 3\), got \(3,\)"),
        (lambda: near_solid(np.full((1, 3), np.nan), kept, np.zeros(3), 1.0), r"^x has 1 row with NaN or inf"),
        (lambda: near_solid(x, kept, np.zeros(3), 0.0), r"^pitch must be a finite number > 0, got 0\.0"),
        (lambda: near_solid(x, kept, np.zeros(3), 1.0, grow=-1), r"^grow must be >= 0, got -1"),
        (lambda: near_solid(x, kept, np.zeros(2), 1.0), r"^origin must be 3 finite numbers"),
        (lambda: near_solid(x, kept[0], np.zeros(3), 1.0), r"^kept must be a 3-D grid"),
    ]:
        with pytest.raises(InvalidInputError, match=message):
            call()


def test_solid_moments_names_a_sol_that_is_no_solid():
    """moments.solid_moments(points, 4.0) was AttributeError "'numpy.ndarray' object has no attribute 'inside'"."""
    from jaxpose import moments

    for sol in (np.zeros((5, 3)), None, (1, 2)):
        with pytest.raises(InvalidInputError, match=r"^sol must be a Solid \(jaxpose.occupancy.solid.robust_solid"):
            moments.solid_moments(sol, 4.0)
