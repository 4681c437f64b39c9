"""benchmarks/bodies.py (issue 34's research record): its measures against closed forms."""
import numpy as np
import pytest
import trimesh
from scipy import ndimage

from benchmarks import bodies
from jaxpose.occupancy.solid import Solid


def test_capped_volume_is_the_closed_form_and_caps_a_planar_hole():
    closed = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    assert bodies.capped_volume(closed.vertices, closed.faces) == pytest.approx(closed.volume, rel=1e-12)
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    top = np.flatnonzero(np.isclose(box.triangles_center[:, 2], 1.5))
    assert len(top) == 2  # the square face z = 1.5, two triangles
    opened = np.delete(box.faces, top, axis=0)
    assert bodies.capped_volume(box.vertices, opened) == pytest.approx(6.0, rel=1e-12)  # a flat cap is exact


def test_capped_area_is_the_closed_form_and_caps_a_planar_hole():
    closed = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    assert bodies.capped_area(closed.vertices, closed.faces) == pytest.approx(closed.area, rel=1e-12)
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    opened = np.delete(box.faces, np.flatnonzero(np.isclose(box.triangles_center[:, 2], 1.5)), axis=0)
    assert bodies.capped_area(box.vertices, opened) == pytest.approx(22.0, rel=1e-12)  # 2 (2 + 3 + 6), the cap flat


def test_local_thickness_of_two_balls():
    """Two separate balls of radius 9 and 4 voxels: every voxel's thickness is about its ball's
    radius (within the lattice's 1-2 voxels), whatever its depth; its depth is not."""
    grid = np.indices((60, 30, 30)).transpose(1, 2, 3, 0) + 0.5
    big = np.sum((grid - (15, 15, 15)) ** 2, axis=-1) < 9 ** 2
    small = np.sum((grid - (45, 15, 15)) ** 2, axis=-1) < 4 ** 2
    inside = big | small
    depth = ndimage.distance_transform_edt(inside)
    t = bodies.local_thickness(inside, depth)
    assert np.all(t[~inside] == 0)
    assert 6.5 <= t[big].min() and t[big].max() <= 9 and 2 <= t[small].min() and t[small].max() <= 4
    rim = big & (depth < 2)
    assert rim.sum() > 0.4 * big.sum() and t[rim].min() >= 6.5  # the rim of the big ball is thick, not shallow


def test_spreads_by_hand():
    sigma, cv = bodies.spreads([[0, 0, 0], [2, 0, 0]], [1.0, 3.0])
    assert sigma == pytest.approx(1.0) and cv == pytest.approx(0.5)


def _dumbbell(pitch=0.05):
    """Voxel solid of a trunk (ball, radius 1.0, at x = -1.2), a head (ball, radius 0.5, at x = 1.4)
    and a neck (rod of radius 0.25 along x between them); depth by the distance transform."""
    axes = [np.arange(a + 0.5 * pitch, b, pitch) for a, b in zip((-2.4, -1.2, -1.2), (2.0, 1.2, 1.2))]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    trunk = np.linalg.norm(x - (-1.2, 0, 0), axis=-1) <= 1.0
    head = np.linalg.norm(x - (1.4, 0, 0), axis=-1) <= 0.5
    neck = (x[..., 0] >= -1.2) & (x[..., 0] <= 1.4) & (np.hypot(x[..., 1], x[..., 2]) <= 0.25)
    inside = trunk | head | neck
    depth = ndimage.distance_transform_edt(inside) * pitch
    return Solid(inside, depth, np.array((-2.4, -1.2, -1.2)), pitch, None, np.eye(3), 1, 0), x, trunk, head, neck


def test_head_candidates_of_a_dumbbell():
    """One candidate: the head ball, born at its radius (0.5 of the trunk's 1.0), dying at the neck's
    0.25 (constriction 2), its part beyond the saddle the head and at most the whole neck, never the
    trunk; parts_at gives the head's and the trunk's voxels deeper than the neck."""
    sol, x, trunk, head, neck = _dumbbell()
    rows = bodies.head_candidates(sol)
    assert len(rows) == 1
    (row,) = rows
    tol = 2 * sol.pitch  # the distance transform's voxel
    assert row["thickness"] == pytest.approx(0.5, abs=tol)
    assert row["constriction"] == pytest.approx(2.0, rel=0.25)
    assert np.linalg.norm(row["center"] - (1.4, 0, 0)) < tol
    total = sol.inside.sum()
    assert head.sum() / total - 0.01 <= row["part"] <= (head | (neck & (x[..., 0] > -0.2))).sum() / total
    found = bodies.parts_at(sol, row["row"])  # the head's voxels deeper than the neck: a ball of radius 0.25
    core = np.linalg.norm(x - (1.4, 0, 0), axis=-1) <= 0.25 - tol
    assert found.head[core].all() and not found.head[~head].any() and found.trunk[trunk & (sol.depth > 0.3)].all()


def test_part_beyond_keeps_what_hangs_on_the_far_side():
    """The part beyond the neck holds the head and not the trunk, whichever side the plane is cut from."""
    sol, x, trunk, head, neck = _dumbbell()
    blob = np.linalg.norm(x - (1.4, 0, 0), axis=-1) <= 0.2
    saddle = np.array(np.unravel_index(np.argmin(np.where(neck, np.abs(x[..., 0] - 0.5), np.inf)), sol.inside.shape))
    part = bodies.part_beyond(sol, blob, saddle)
    assert part[head].all() and not part[trunk].any()


def _quadruped(pitch=0.08):
    """Voxel solid of a trunk (ball, radius 1.0, at x = -1.5), a rump (ball, radius 0.8, at x = 0.8)
    joined to it by a waist (rod, radius 0.6), two hind legs (rods, radius 0.2, 2.5 long, down
    from the rump at y = +-0.4) and a head (ball, radius 0.45, at x = -3.2) on a neck (rod, radius
    0.25): the rump is thicker than the head and, like it, beyond a saddle, but it branches."""
    axes = [np.arange(a + 0.5 * pitch, b, pitch) for a, b in zip((-3.8, -1.2, -3.0), (1.8, 1.2, 1.2))]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)

    def ball(c, r):
        return np.linalg.norm(x - np.array(c), axis=-1) <= r

    def along_x(x0, x1, r):
        return (x[..., 0] >= x0) & (x[..., 0] <= x1) & (np.hypot(x[..., 1], x[..., 2]) <= r)

    def leg(y):
        return (x[..., 2] >= -2.5) & (x[..., 2] <= 0.0) & (np.hypot(x[..., 0] - 0.8, x[..., 1] - y) <= 0.2)

    head = ball((-3.2, 0, 0), 0.45)
    inside = ball((-1.5, 0, 0), 1.0) | ball((0.8, 0, 0), 0.8) | along_x(-1.5, 0.8, 0.6) | leg(0.4) | leg(-0.4) \
        | head | along_x(-3.2, -1.5, 0.25)
    depth = ndimage.distance_transform_edt(inside) * pitch
    return Solid(inside, depth, np.array((-3.8, -1.2, -3.0)), pitch, None, np.eye(3), 1, 0), x, head


def test_terminal_head_takes_the_part_that_ends_the_body_not_the_thicker_rump():
    """The rump (0.8 deep) is beyond a saddle and thicker than the head (0.45), but its two legs
    are two ends 2.5 long, more than BRANCH rump depths apart; the head's part has one end: the
    prototype takes the head."""
    sol, x, head = _quadruped()
    row, peak, part = bodies.terminal_head(sol)
    tol = 2 * sol.pitch
    center = sol.origin + sol.pitch * (np.array(np.unravel_index(int(peak), sol.inside.shape)) + 0.5)
    assert np.linalg.norm(center - (-3.2, 0, 0)) < tol
    assert part[head & (sol.depth > tol)].all() and part.sum() < 1.5 * head.sum()
    rows = bodies.head_candidates(sol)
    rump = [r for r in rows if np.linalg.norm(r["center"] - (0.8, 0, 0)) < tol]
    assert len(rump) == 1 and rump[0]["thickness"] > 0.7  # a thicker candidate, passed over
    labels, _ = ndimage.label(sol.depth > rump[0]["row"][1], np.ones((3, 3, 3), bool))
    blob = labels == labels[tuple(np.array(np.unravel_index(int(rump[0]["row"][2]), sol.inside.shape)))]
    saddle = np.array(np.unravel_index(int(rump[0]["row"][3]), sol.inside.shape))
    rump_part = bodies.part_across(sol, blob, saddle, rump[0]["row"][1])
    assert bodies.ends(sol, rump_part, saddle, sol.depth.ravel()[int(rump[0]["row"][2])]) >= 2


def test_geodesic_along_a_rod_and_around_a_wall():
    """Inside a straight rod the geodesic distance is the straight one (within the 26-neighbour
    metric's 8 %); a wall with a gap makes the far side's distance the way round it."""
    mask = np.zeros((40, 5, 5), bool)
    mask[:, 1:4, 1:4] = True
    g = bodies.geodesic(mask, (0, 2, 2), 0.5)
    assert g[39, 2, 2] == pytest.approx(39 * 0.5)
    room = np.ones((21, 21, 1), bool)
    room[10, :18, 0] = False  # a wall along y with a gap at y >= 18
    g = bodies.geodesic(room, (0, 0, 0), 1.0)
    straight = 20.0
    assert g[20, 0, 0] > 1.8 * straight
    closed = room & (np.arange(21)[None, :, None] < 18)  # no gap: the far side cannot be reached
    assert np.isinf(bodies.geodesic(closed, (0, 0, 0), 1.0)[20, 0, 0])


def test_head_mirror_normal_of_a_snouted_head():
    """A sphere's surface points with a snout (a cone along x) and an ear on each side: symmetric
    about the plane y = 0 only. Searched across up = z, the best mirror plane's normal is y,
    within the search's last step (a twelfth of 5 degrees); the error about it is 0 (every point
    has its mirror image in the set) and that about x is not."""
    rng = np.random.default_rng(0)
    u = rng.normal(size=(1500, 3))
    sphere = u / np.linalg.norm(u, axis=1, keepdims=True)
    t = rng.uniform(0.0, 1.0, 400)
    phi = rng.uniform(0.0, 2 * np.pi, 400)
    snout = np.stack([0.9 + 0.8 * t, 0.35 * (1 - t) * np.cos(phi), 0.35 * (1 - t) * np.sin(phi)], axis=1)
    ear = np.stack([rng.uniform(-0.2, 0.0, 200), rng.uniform(0.5, 0.7, 200), rng.uniform(0.8, 1.2, 200)], axis=1)
    half = np.vstack([sphere, snout, ear])
    head = np.vstack([half, half * (1, -1, 1)])  # mirror pairs about y = 0
    a = np.array([np.cos(0.3), np.sin(0.3), 0.0])
    b = np.array([-np.sin(0.3), np.cos(0.3), 0.0])
    n = bodies.head_mirror_normal(head, a, b)
    assert np.degrees(np.arccos(min(1.0, abs(n[1])))) < 0.5
    assert bodies.mirror_error(head, head.mean(axis=0), np.array([0.0, 1.0, 0.0])) == pytest.approx(0.0, abs=1e-12)
    assert bodies.mirror_error(head, head.mean(axis=0), np.array([1.0, 0.0, 0.0])) > 0.05


def test_pitch_study_of_a_class_of_one_moved_shape():
    """A class of one box moved about: its voxels are the same on each grid (the grid follows the
    box), so every cv is 0 whatever sets the pitch."""
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    moved = [box.copy().apply_translation(t) for t in ((0, 0, 0), (5, -2, 1), (-3, 7, 2))]
    lines = []
    record = bodies.pitch_study({"box": moved}, resolution=24, out=lines.append)
    assert record["box"] == {"extent": pytest.approx(0.0, abs=1e-12), "area": pytest.approx(0.0, abs=1e-12),
                             "sqrt_area": pytest.approx(0.0, abs=1e-12)}
    assert len(lines) == 1 and lines[0].startswith("box: cv of V^(1/3)")


def test_volume_parts_finds_the_part_that_grows():
    """A 4 x 2 x 2 box whose right half is stretched by 0-15 % along x from pose to pose (turned off
    the grid's axes, so that no face lies along a voxel layer): of two clusters, the right one holds
    most of the change of the volume."""
    from trimesh.remesh import subdivide

    v, f = trimesh.creation.box(extents=(4.0, 2.0, 2.0)).vertices, trimesh.creation.box().faces
    for _ in range(3):
        v, f = subdivide(v, f)
    stretch = np.array([1.0, 1.05, 1.1, 1.15])
    turn = trimesh.transformations.rotation_matrix(0.7, (1.0, 2.0, 3.0))[:3, :3]
    meshes = []
    for s in stretch:
        w = v.copy()
        w[w[:, 0] > 0, 0] *= s
        meshes.append(trimesh.Trimesh(w @ turn.T, f, process=False))
    record = bodies.volume_parts(meshes, resolution=64, parts=2, out=lambda line: None)
    right = max(record["clusters"], key=lambda c: (turn.T @ c["middle"])[0])
    left = min(record["clusters"], key=lambda c: (turn.T @ c["middle"])[0])
    # k-means cuts the median shape a little right of the joint (x = 0.2): about 0.9 / 0.1 expected
    assert right["variance_share"] > 0.8 and abs(left["variance_share"]) < 0.2
    assert right["volume_cv"] > 5 * left["volume_cv"]
    volumes = 8.0 * (1.0 + stretch)  # the left half 8, the right 8 s
    assert record["total_cv"] == pytest.approx(volumes.std() / volumes.mean(), rel=0.05)


def test_subvoxel_study_of_spheres_of_known_radii():
    """Spheres of radius 1.0-1.3: the cv of V^(1/3) is the radii's cv for the closed form
    (exactly: the polyhedron's volume is r^3 times a constant), and within a few percent of it for
    the voxel count and the sub-voxel count."""
    radii = np.array([1.0, 1.1, 1.2, 1.3])
    meshes = [trimesh.creation.icosphere(subdivisions=3, radius=r) for r in radii]
    truth = radii.std() / radii.mean()
    cv = bodies.subvoxel_study(meshes, resolution=32, out=lambda line: None)
    assert cv["capped"] == pytest.approx(truth, rel=1e-9)
    assert cv["subvoxel"] == pytest.approx(truth, rel=0.02)
    assert cv["voxels"] == pytest.approx(truth, rel=0.05)


def test_grid_offsets_of_spheres_and_the_offset_restored():
    """Spheres of radius 1.0-1.3 centered at the origin: on every shifted grid the center is the
    origin within a voxel and the cv of V^(1/3) the radii's within a few percent; the library's
    grid offset is the same after the study."""
    from jaxpose.occupancy import solid

    before = solid.GRID_OFFSET
    radii = np.array([1.0, 1.1, 1.2, 1.3])
    meshes = [trimesh.creation.icosphere(subdivisions=3, radius=r) for r in radii]
    record = bodies.grid_offsets(meshes, resolution=32, out=lambda line: None)
    assert solid.GRID_OFFSET == before
    assert len(record["cv"]) == len(bodies.GRID_SHIFTS)
    for cv in record["cv"] + [record["mean_cv"]]:
        assert cv == pytest.approx(radii.std() / radii.mean(), rel=0.05)
    assert max(record["sigma_tr"]) < 2.6 / 32  # a voxel of the largest sphere's grid


def _toy_person():
    """A trunk box, a neck rod and a head ball (radius 0.13, centered at (0.06, 0, 0.98)), two legs."""
    head = trimesh.creation.icosphere(subdivisions=3, radius=0.13)
    head.apply_translation([0.06, 0.0, 0.98])
    trunk = trimesh.creation.box(extents=(0.3, 0.5, 0.8))
    trunk.apply_translation([0.0, 0.0, 0.4])
    neck = trimesh.creation.cylinder(radius=0.05, height=0.12)
    neck.apply_translation([0.0, 0.0, 0.84])
    legs = []
    for y in (-0.13, 0.14):
        leg = trimesh.creation.box(extents=(0.12, 0.12, 0.9))
        leg.apply_translation([0.0, y, -0.45])
        legs.append(leg)
    return trimesh.util.concatenate([trunk, head, neck] + legs)


def test_head_center_is_the_head_ball_and_moves_with_the_body():
    """The depth^4 centroid of the found head is the head ball's center (a ball's depth is symmetric
    about it; the neck's voxels are shallow), within a voxel; moved, it moves alike."""
    from benchmarks import head_center

    m = _toy_person()
    c = head_center.head_center(m.vertices, m.faces)
    pitch = np.ptp(m.vertices, axis=0).max() / 96  # frame_solid's default grid: 96 voxels along the largest extent
    assert c is not None and np.linalg.norm(c - [0.06, 0.0, 0.98]) < pitch
    shift = np.array([3.0, -1.0, 2.0])
    moved = head_center.head_center(m.vertices + shift, m.faces)
    np.testing.assert_allclose(moved, c + shift, atol=1e-9)
    ball = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    assert head_center.head_center(ball.vertices, ball.faces) is None  # no part ends a ball beyond a saddle


def test_head_sizes_of_a_body_and_its_double():
    """A class of a body and the body scaled by 2: the grid is set by the extent, so every head size
    doubles and each cv is std / mean of (s, 2s) = 1/3."""
    from benchmarks import head_center

    m = _toy_person()
    big = trimesh.Trimesh(2.0 * m.vertices, m.faces, process=False)
    cvs = head_center.head_sizes({"toy": [m, big]})["toy"]
    assert set(cvs) == {"volume", "beyond_volume", "depth", "depth_volume^2"}
    for name, cv in cvs.items():
        assert cv == pytest.approx(1 / 3, abs=1e-9), name
