"""jaxpose.rotation.parts: the merge tree of a depth field and the head, neck and trunk, on voxel solids of
balls and rods whose depths are known in closed form (their radii, within the distance transform's
voxel)."""
import numpy as np
import pytest
from scipy import ndimage

from jaxpose.orientation import GAP_MIN
from jaxpose.rotation.parts import (BRANCH, DISK, NECK, SHARE, THICK, TRUNK, WIDER, ends, find_head, find_parts,
                                   merge_tree, part_across, waist)
from jaxpose.occupancy.solid import Solid


def voxel_solid(parts, pitch=0.05, lo=(-3.0, -1.2, -1.2), hi=(3.0, 1.2, 1.2)):
    """A Solid of the union of parts (functions of voxel centers (..., 3) -> bool), depth by the EDT."""
    axes = [np.arange(a + 0.5 * pitch, b, pitch) for a, b in zip(lo, hi)]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    inside = np.zeros(x.shape[:3], bool)
    for part in parts:
        inside |= part(x)
    depth = ndimage.distance_transform_edt(inside) * pitch
    return Solid(inside, depth, np.array(lo, float), pitch, None, np.eye(3), 1, 0)


def ball(c, r):
    return lambda x: np.linalg.norm(x - np.array(c), axis=-1) <= r


def rod(x0, x1, r):  # a cylinder along the first axis
    return lambda x: (x[..., 0] >= x0) & (x[..., 0] <= x1) & (np.hypot(x[..., 1], x[..., 2]) <= r)


def center(sol, flat):
    return sol.origin + sol.pitch * (np.array(np.unravel_index(int(flat), sol.inside.shape)) + 0.5)


def test_merge_tree_of_a_dumbbell():
    """Two balls (radii 1.0, 0.7) joined by a rod (radius 0.3): the deepest maximum is born at 1.0
    and never dies, the other is born at 0.7 at the small ball's center and dies at the rod's 0.3
    in the rod, joining the big ball's; nothing else persists beyond 2 voxels."""
    pitch = 0.05
    sol = voxel_solid([ball((-1.2, 0, 0), 1.0), ball((1.2, 0, 0), 0.7), rod(-1.2, 1.2, 0.3)], pitch)
    tree = merge_tree(sol.inside, sol.depth)
    assert tree.shape[1] == 5
    (b0, d0, p0, s0, j0), (b1, d1, p1, s1, j1) = tree[:2]
    assert abs(b0 - 1.0) < 1.5 * pitch and d0 == 0.0 and s0 == -1 and j0 == -1
    assert abs(b1 - 0.7) < 1.5 * pitch and abs(d1 - 0.3) < 1.5 * pitch and j1 == p0
    assert np.all(tree[2:, 0] - tree[2:, 1] < 2 * pitch)
    assert sol.depth.ravel()[int(p0)] == b0 and sol.depth.ravel()[int(s1)] == d1
    np.testing.assert_allclose(center(sol, p0), [-1.2, 0, 0], atol=2 * pitch)
    np.testing.assert_allclose(center(sol, p1), [1.2, 0, 0], atol=2 * pitch)
    saddle = center(sol, s1)
    assert -0.2 - pitch <= saddle[0] <= 0.5 + pitch and np.hypot(*saddle[1:]) < 2 * pitch  # in the rod

    found = find_parts(sol)
    assert found.head_depth == b1 and found.neck_depth == d1 and found.constriction == b1 / d1
    np.testing.assert_allclose(found.neck, saddle)
    head = sol.origin + pitch * (np.stack(np.nonzero(found.head), 1) + 0.5)
    assert np.all(head[:, 0] > 0.5 - pitch) and found.head.sum() < found.trunk.sum()
    assert not (found.head & found.trunk).any()


def _merge_tree_reference(inside, depth):
    """merge_tree's contract written out voxel by voxel: the voxels in decreasing depth (ties in
    flat-index order); each takes the components of its 26-neighbours already in, collected as a
    Python set of their peaks' flat indices in neighbour order (a, b, c in -1, 0, 1); the deepest
    peak lives on (ties: the set's order), the others die at the voxel; a last row for the
    component of the first voxel; rows by persistence, ties in the order they died."""
    shape = inside.shape
    cells = [tuple(i) for i in np.argwhere(inside)]
    cells.sort(key=lambda c: -depth[c])  # stable: flat-index order among equal depths
    steps = [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1) if (a, b, c) != (0, 0, 0)]
    padded = tuple(n + 2 for n in shape)  # the set holds the indices merge_tree uses: of the grid padded by 1
    key = {c: int(np.ravel_multi_index(tuple(np.add(c, 1)), padded)) for c in cells}
    comp, rows = {}, []  # voxel -> its component's peak (a voxel), updated on every merge

    def flat(c):
        return int(np.ravel_multi_index(c, shape))

    for c in cells:
        met = [comp[n] for n in (tuple(np.add(c, s)) for s in steps) if n in comp]
        peaks = {key[p]: p for p in met}
        order = sorted({key[p] for p in met}, key=lambda k: -depth[peaks[k]])
        if not order:
            comp[c] = c
            continue
        keep = peaks[order[0]]
        for k in order[1:]:
            rows.append((depth[peaks[k]], depth[c], flat(peaks[k]), flat(c), flat(keep)))
        dead = {peaks[k] for k in order[1:]}
        for v in comp:
            if comp[v] in dead:
                comp[v] = keep
        comp[c] = keep
    if not cells:
        return np.zeros((0, 5))
    top = comp[cells[0]]
    rows.append((depth[top], 0.0, flat(top), -1, -1))
    rows = np.array(rows, np.float64)
    return rows[np.argsort(-(rows[:, 0] - rows[:, 1]), kind="stable")]


def test_merge_tree_matches_its_contract_voxel_by_voxel():
    """merge_tree against the reference above, bit for bit, on small grids with many ties (depths
    on a few levels, as a distance transform's: maxima of equal depth meeting at a saddle, where
    the survivor is the set order's) and on hand cases whose trees are known: empty, one voxel, one
    part, two peaks on a line, two parts that never meet (only the deepest voxel's has a row)."""
    assert merge_tree(np.zeros((3, 4, 5), bool), np.zeros((3, 4, 5))).shape == (0, 5)
    one = np.zeros((3, 3, 3), bool)
    one[1, 2, 0] = True
    np.testing.assert_array_equal(merge_tree(one, np.full((3, 3, 3), 0.5)), [[0.5, 0.0, 15, -1, -1]])
    box = np.ones((4, 3, 2), bool)
    np.testing.assert_array_equal(merge_tree(box, np.ones((4, 3, 2))), [[1.0, 0.0, 0, -1, -1]])  # one part
    line = np.ones((5, 1, 1), bool)
    depth = np.array([1.0, 3.0, 2.0, 2.5, 0.5]).reshape(5, 1, 1)  # peaks at 1 (3.0) and 3 (2.5), saddle at 2
    np.testing.assert_array_equal(merge_tree(line, depth), [[3.0, 0.0, 1, -1, -1], [2.5, 2.0, 3, 2, 1]])
    apart = line.copy()
    apart[2] = False
    np.testing.assert_array_equal(merge_tree(apart, depth), [[3.0, 0.0, 1, -1, -1]])
    rng = np.random.default_rng(7)
    ties = 0
    for _ in range(150):
        shape = tuple(rng.integers(1, 7, 3))
        inside = rng.random(shape) < rng.uniform(0.3, 1.0)
        depth = rng.integers(1, rng.integers(2, 5), shape) * 0.05 if rng.random() < 0.8 else rng.random(shape)
        tree, want = merge_tree(inside, depth), _merge_tree_reference(inside, depth)
        assert tree.dtype == np.float64 and tree.shape == want.shape and np.array_equal(tree, want)
        ties += int(np.any((tree[:, 3] >= 0) & (tree[:, 0] == depth.ravel()[tree[:, 4].astype(int)])))
    assert ties >= 20  # maxima of equal depth met often


def test_head_is_the_smaller_part_even_when_deepest():
    """A child's head is as thick as its trunk: a ball (radius 0.9) on a thinner but longer trunk
    (a rod of radius 0.8 and length 3.2) is the deepest part, and still the head (the smaller)."""
    sol = voxel_solid([rod(-2.8, 0.4, 0.8), ball((1.7, 0, 0), 0.9), rod(0.4, 1.7, 0.4)], 0.05,
                      lo=(-3.0, -1.0, -1.0), hi=(2.8, 1.0, 1.0))
    found = find_parts(sol)
    assert abs(found.head_depth - 0.9) < 0.075 and found.head.sum() < found.trunk.sum()
    head = sol.origin + sol.pitch * (np.stack(np.nonzero(found.head), 1) + 0.5)
    np.testing.assert_allclose(head.mean(axis=0), [1.7, 0, 0], atol=0.1)
    assert 0.4 <= found.neck[0] <= 1.0
    assert abs(found.constriction - 0.8 / 0.4) < 0.4  # the trunk's birth over the neck's depth


def test_neck_is_the_most_constricted_saddle():
    """A trunk of two balls (radius 1.0) joined at a waist (radius 0.6: persistence 0.4, birth /
    death 1.7) carrying a head (radius 0.6) on a neck (radius 0.3: persistence 0.3, birth / death
    2.0): the most persistent saddle is the waist, the most constricted the neck, where the head is
    found; the waist is the runner-up."""
    pitch = 0.05
    sol = voxel_solid([ball((-2.2, 0, 0), 1.0), ball((-0.2, 0, 0), 1.0), rod(-2.2, -0.2, 0.6),
                       ball((1.9, 0, 0), 0.6), rod(0.7, 1.9, 0.3)], pitch, lo=(-3.4, -1.2, -1.2), hi=(2.7, 1.2, 1.2))
    tree = merge_tree(sol.inside, sol.depth)
    assert abs(tree[1, 1] - 0.6) < 1.5 * pitch  # the most persistent saddle: the waist
    found = find_parts(sol)
    assert abs(found.head_depth - 0.6) < 1.5 * pitch and abs(found.neck_depth - 0.3) < 1.5 * pitch
    assert found.runner_up == pytest.approx(tree[1, 0] / tree[1, 1])
    head = sol.origin + pitch * (np.stack(np.nonzero(found.head), 1) + 0.5)
    np.testing.assert_allclose(head.mean(axis=0), [1.9, 0, 0], atol=0.1)
    assert 0.7 - pitch <= found.neck[0] <= 1.4


def test_no_head_without_a_thick_saddle():
    """One ball, a box, a ball with a thin arm (a maximum shallower than THICK times the deepest),
    two balls barely apart (a saddle less than NECK times thinner), an empty grid: no head."""
    assert find_parts(voxel_solid([ball((0, 0, 0), 1.0)], 0.1)) is None
    box = voxel_solid([lambda x: np.all(np.abs(x) <= [1.0, 0.5, 0.3], axis=-1)], 0.05)
    assert find_parts(box) is None
    arm = voxel_solid([ball((-1.0, 0, 0), 1.0), ball((1.5, 0, 0), 0.2), rod(-1.0, 1.5, 0.1)], 0.05)
    assert 0.2 < THICK * 1.0 and find_parts(arm) is None
    pair = voxel_solid([ball((-0.3, 0, 0), 1.0), ball((0.3, 0, 0), 1.0)], 0.05)
    tree = merge_tree(pair.inside, pair.depth)
    assert 1.0 < tree[1, 0] / tree[1, 1] < NECK and find_parts(pair) is None
    empty = voxel_solid([lambda x: np.zeros(x.shape[:-1], bool)], 0.5)
    assert merge_tree(empty.inside, empty.depth).shape == (0, 5) and find_parts(empty) is None


def capsule(p, q, r):
    """A capsule: the points within r of the segment p-q."""
    p, q = np.asarray(p, float), np.asarray(q, float)

    def inside(x):
        t = np.clip(((x - p) @ (q - p)) / ((q - p) @ (q - p)), 0.0, 1.0)
        return np.linalg.norm(x - (p + t[..., None] * (q - p)), axis=-1) <= r
    return inside


def four_legged(pitch=0.05):
    """A four-legged body of known parts: a trunk (radius 0.45) along x, four legs and a tail
    (radii 0.12 and 0.06), and a head (a ball of radius 0.2, less than half the trunk's depth)
    on a neck (radius 0.12) at the front, centered at (1.6, 0, 0.65)."""
    legs = [capsule((x, y, -0.1), (x, y, -1.2), 0.12) for x in (-0.8, 0.6) for y in (-0.25, 0.25)]
    return voxel_solid([capsule((-1.2, 0, 0), (0.8, 0, 0), 0.45), *legs, capsule((-1.2, 0, 0), (-2.0, 0, 0.3), 0.06),
                        capsule((0.8, 0, 0.1), (1.5, 0, 0.6), 0.12), ball((1.6, 0, 0.65), 0.2)], pitch,
                       lo=(-2.2, -0.6, -1.4), hi=(2.0, 0.6, 1.0))


def test_find_head_finds_a_head_thinner_than_half_the_trunk():
    """The four-legged body's head is 0.2 deep, its trunk 0.45: find_parts asks a head at least
    THICK times as deep as the trunk and finds none; find_head finds the part that ends the body
    (cut off at its neck, one far end), the thickest such: the head (not a leg, not the tail),
    centered at the ball's center, its depth the ball's radius, its neck on the neck's axis."""
    sol = four_legged()
    assert 0.2 < THICK * 0.45 and find_parts(sol) is None
    found = find_head(sol)
    assert found is not None and found.terminal
    head = sol.origin + sol.pitch * (np.stack(np.nonzero(found.head), 1) + 0.5)
    np.testing.assert_allclose(head.mean(axis=0), [1.6, 0, 0.65], atol=0.1)
    assert abs(found.head_depth - 0.2) < 1.5 * sol.pitch
    # the part beyond the neck: the head and the neck's end, none of the trunk (about 0.2^3 4 pi / 3
    # for the ball plus at most the neck's length, 0.86, of pi 0.12^2)
    beyond = sol.origin + sol.pitch * (np.stack(np.nonzero(found.beyond), 1) + 0.5)
    assert found.beyond[found.head].all() and np.all(beyond[:, 0] > 0.8)
    assert 4.19 * 0.2 ** 3 < found.beyond.sum() * sol.pitch ** 3 < 4.19 * 0.2 ** 3 + 3.15 * 0.12 ** 2 * 0.86
    # the neck lies on the neck's axis, between the trunk and the head
    axis = np.array([0.7, 0.0, 0.5]) / np.linalg.norm([0.7, 0.0, 0.5])
    rel = found.neck - np.array([0.8, 0, 0.1])
    assert np.linalg.norm(rel - (rel @ axis) * axis) < 0.12 + sol.pitch and 0.0 < rel @ axis < np.linalg.norm([0.7, 0, 0.5]) + 0.2


def test_ends_counts_the_far_ends_of_a_part():
    """A ball on a rod has one far end from its saddle; a rump with two legs and a tail three;
    a bump shorter than BRANCH part depths does not count."""
    pitch = 0.05
    sol = four_legged(pitch)
    inside = sol.inside
    rump = inside & (np.stack(np.meshgrid(*[sol.origin[i] + pitch * (np.arange(n) + 0.5) for i, n in
                                            enumerate(inside.shape)], indexing="ij"), -1)[..., 0] < -0.3)
    saddle = np.rint((np.array([-0.3, 0.0, 0.0]) - sol.origin) / pitch - 0.5).astype(int)
    assert ends(sol, rump, saddle, 0.12) == 3  # two hind legs and the tail, at the scale of a leg
    head = inside & (np.linalg.norm(sol.origin + pitch * (np.argwhere(np.ones(inside.shape, bool)) + 0.5)
                                    - [1.6, 0, 0.65], axis=1).reshape(inside.shape) < 0.35)
    near = np.rint((np.array([1.35, 0.0, 0.5]) - sol.origin) / pitch - 0.5).astype(int)
    assert ends(sol, head, near, 0.2) <= 1
    assert BRANCH * 0.2 > 0.35


def test_find_head_keeps_the_neck_of_a_person_and_rejects_a_branching_part():
    """Where find_parts' head ends the body (the dumbbell's small ball), find_head returns it,
    checked (terminal); where find_parts' part branches into limbs (two legs and a tail, each
    longer than BRANCH rump depths, beyond the narrowest thick saddle; the head thinner than half
    the trunk), find_head takes the part that ends the body."""
    pitch = 0.05
    sol = voxel_solid([ball((-1.2, 0, 0), 1.0), ball((1.2, 0, 0), 0.7), rod(-1.2, 1.2, 0.3)], pitch)
    a, b = find_parts(sol), find_head(sol)
    assert b.terminal and np.array_equal(a.head, b.head) and b.constriction == a.constriction
    # a rump (ball, 0.4) beyond a waist (0.3) on a trunk (0.45): find_parts takes the rump
    legs = [capsule((-1.5, y, -0.2), (-1.5, y, -1.2), 0.1) for y in (-0.2, 0.2)]
    body = voxel_solid([capsule((-0.6, 0, 0), (0.8, 0, 0), 0.45), capsule((-1.3, 0, 0), (-0.6, 0, 0), 0.3),
                        ball((-1.5, 0, 0), 0.4), *legs, capsule((-1.5, 0, 0), (-2.6, 0, 0.4), 0.06),
                        capsule((0.8, 0, 0.1), (1.5, 0, 0.6), 0.1), ball((1.6, 0, 0.65), 0.18)], pitch,
                       lo=(-2.8, -0.6, -1.4), hi=(2.0, 0.6, 1.0))
    rump = find_parts(body)
    assert rump is not None and rump.neck[0] < -0.5 and rump.head_depth > 0.3  # the waist; the rump beyond it
    found = find_head(body)
    head = body.origin + pitch * (np.stack(np.nonzero(found.head), 1) + 0.5)
    assert found.terminal and np.allclose(head.mean(axis=0), [1.6, 0, 0.65], atol=0.1)


def test_part_across_without_thin_bridges():
    """A trunk ball (radius 1.0) and a head ball (0.6) on a neck rod (0.3), and a bridge (radius 0.1,
    2 voxels) from the top of the head around the disk to the top of the trunk. Cut as it is, the
    bridge joins the head to the trunk beyond the disk: not cut off. Cut without the voxels at
    most 0.15 deep (a point solid's closing bridges, terminal_part), the head is cut off: the head ball beyond the disk, none of the trunk ball, and the bridge's voxels split between
    the two sides by their nearest deep voxel (the neck rod, 0.3 deep, is no bridge)."""
    pitch = 0.05
    bridge = [capsule((1.2, 0.4, 0.0), (1.0, 1.0, 0.0), 0.1), capsule((1.0, 1.0, 0.0), (-0.8, 1.0, 0.0), 0.1),
              capsule((-0.8, 1.0, 0.0), (-0.8, 0.6, 0.0), 0.1)]
    mesh = voxel_solid([ball((-1.2, 0, 0), 1.0), ball((1.2, 0, 0), 0.6), rod(-1.2, 1.2, 0.3)] + bridge, pitch)
    found = find_parts(mesh)
    x = mesh.origin + pitch * (np.stack(np.nonzero(mesh.inside), 1) + 0.5)
    head_center, trunk_center = np.argmin(np.linalg.norm(x - [1.2, 0, 0], axis=1)), np.argmin(np.linalg.norm(x - [-1.2, 0, 0], axis=1))
    idx = np.stack(np.nonzero(mesh.inside), 1)
    assert found is not None and found.head[tuple(idx[head_center])]  # the head is the small ball
    assert abs(found.neck_depth - 0.3) < 1.5 * pitch
    saddle = np.rint((found.neck - mesh.origin) / pitch - 0.5).astype(int)
    other = idx[trunk_center]
    assert part_across(mesh, found.head, saddle, found.neck_depth, other) is None  # the bridge joins them
    assert part_across(mesh, found.head, saddle, found.neck_depth, other, thin=pitch) is None  # deeper than that

    part = part_across(mesh, found.head, saddle, found.neck_depth, other, thin=3 * pitch)
    assert part is not None
    in_head = np.linalg.norm(x - [1.2, 0, 0], axis=1) <= 0.6
    beyond_disk = x[:, 0] > found.neck[0] + 2 * pitch  # the neck meets the head ball: the disk cuts its edge
    in_trunk = np.linalg.norm(x - [-1.2, 0, 0], axis=1) <= 1.0
    assert part[tuple(idx[in_head & beyond_disk].T)].all() and not part[tuple(idx[in_trunk].T)].any()
    on_bridge = np.zeros(len(x), bool)
    for c in bridge:
        on_bridge |= c(x)
    on_bridge &= ~in_head & ~in_trunk
    assert 0 < part[tuple(idx[on_bridge].T)].sum() < on_bridge.sum()  # split between the two sides
    assert not (part & ~mesh.inside).any()


def _waisted_animal():
    """A body whose trunk has a waist: a chest (capsule, radius 0.45) along x, a waist (0.36) and a
    rump (ball, 0.42) that ends in one blob (a point solid's closing fills the flanks between hind
    legs), two front legs (0.1) and a head (ball, 0.18: less than half the trunk's depth) on a neck
    (0.1) ahead. As (center or segment, radius) primitives: ("ball", c, r) or ("capsule", p, q, r)."""
    return [("capsule", (-0.6, 0, 0), (0.8, 0, 0), 0.45), ("capsule", (-1.3, 0, 0), (-0.6, 0, 0), 0.36),
            ("ball", (-1.5, 0, 0), 0.42), ("capsule", (0.5, -0.2, -0.2), (0.5, -0.2, -1.2), 0.1),
            ("capsule", (0.5, 0.2, -0.2), (0.5, 0.2, -1.2), 0.1), ("capsule", (0.8, 0, 0.1), (1.5, 0, 0.6), 0.1),
            ("ball", (1.6, 0, 0.65), 0.18)]


def _inside(prim):
    return ball(prim[1], prim[2]) if prim[0] == "ball" else capsule(prim[1], prim[2], prim[3])


def _surface_points(prims, n, seed):
    """About ``n`` points on the surface of the union of the primitives: points on each primitive's
    surface (a ball's sphere; a capsule's cylinder and end spheres), uniform in area, kept where no
    other primitive holds them."""
    rng = np.random.default_rng(seed)
    pieces, areas = [], []
    for p in prims:
        if p[0] == "ball":
            pieces.append(("sphere", np.array(p[1], float), None, p[2]))
            areas.append(4 * np.pi * p[2] ** 2)
        else:
            a, b, r = np.array(p[1], float), np.array(p[2], float), p[3]
            pieces += [("cylinder", a, b, r), ("sphere", a, None, r), ("sphere", b, None, r)]
            areas += [2 * np.pi * r * np.linalg.norm(b - a), 4 * np.pi * r ** 2, 4 * np.pi * r ** 2]
    counts = rng.multinomial(n, np.array(areas) / np.sum(areas))
    out = []
    for (kind, a, b, r), k in zip(pieces, counts):
        d = rng.normal(size=(k, 3))
        if kind == "sphere":
            out.append(a + r * d / np.linalg.norm(d, axis=1, keepdims=True))
            continue
        axis = (b - a) / np.linalg.norm(b - a)
        d -= (d @ axis)[:, None] * axis
        out.append(a + rng.uniform(0, 1, (k, 1)) * (b - a) + r * d / np.linalg.norm(d, axis=1, keepdims=True))
    x = np.concatenate(out)
    covered = np.zeros(len(x), bool)
    for p in prims:  # strictly inside another primitive: not on the union's surface
        q = (p[0], p[1], p[2] - 1e-6) if p[0] == "ball" else (p[0], p[1], p[2], p[3] - 1e-6)
        covered |= _inside(q)(x)
    return x[~covered]


@pytest.mark.parametrize("as_points", [False, True])
def test_a_part_beyond_a_waist_is_no_head(as_points):
    """A waist is no neck: the trunk's depth (0.45) over the waist's (0.36) is less than TRUNK. The
    body's most constricted thick saddle is that waist, and the rump beyond it passes every other
    test of a head (cut off there it holds at most SHARE of the solid and has one far end: its
    legs are filled in), so find_parts takes the rump and find_head took it; find_head now takes
    the head ball, the thickest part beyond a neck that ends the body. On the voxel solid of the
    body and on the robust solid of a sample of its surface (a point cloud: closing and all)."""
    prims = _waisted_animal()
    if as_points:
        from jaxpose.occupancy.solid import robust_solid
        sol = robust_solid(_surface_points(prims, 40000, seed=1), None, resolution=64)
    else:
        sol = voxel_solid([_inside(p) for p in prims], 0.04, lo=(-2.1, -0.6, -1.4), hi=(2.0, 0.6, 1.0))
    assert 0.36 * TRUNK > 0.45 and 0.42 > NECK * 0.36 and 0.42 > THICK * 0.45
    rump = find_parts(sol)
    assert rump is not None and rump.neck[0] < -0.6 and waist(rump.neck_depth, sol.depth.max())
    # the rump would pass as a head but for the waist: cut off at its saddle, small, one end
    saddle = np.rint((rump.neck - sol.origin) / sol.pitch - 0.5).astype(int)
    beyond = part_across(sol, rump.head, saddle, rump.neck_depth)
    assert beyond is not None and beyond.sum() <= SHARE * sol.inside.sum()
    assert ends(sol, beyond, saddle, rump.head_depth) <= 1
    found = find_head(sol)
    head = sol.origin + sol.pitch * (np.stack(np.nonzero(found.head), 1) + 0.5)
    assert found.terminal and not waist(found.neck_depth, sol.depth.max())
    np.testing.assert_allclose(head.mean(axis=0), [1.6, 0, 0.65], atol=0.1)
    assert abs(found.head_depth - 0.18) < 2 * sol.pitch


def _cone(p, q, r0, r1):
    """The points within r0 + t (r1 - r0) of the segment p-q at its parameter t."""
    p, q = np.asarray(p, float), np.asarray(q, float)

    def inside(x):
        t = np.clip(((x - p) @ (q - p)) / ((q - p) @ (q - p)), 0.0, 1.0)
        return np.linalg.norm(x - (p + t[..., None] * (q - p)), axis=-1) <= r0 + t * (r1 - r0)
    return inside


def _web(p, q, down, reach, half):
    """A plate 2 half thick along the segment p-q, reaching ``reach`` from it along ``down``."""
    p, q, down = np.asarray(p, float), np.asarray(q, float), np.asarray(down, float)
    a = (q - p) / np.linalg.norm(q - p)
    across = np.cross(a, down)

    def inside(x):
        r = x - p
        t, s, w = r @ a, r @ down, r @ across
        return (t >= 0) & (t <= np.linalg.norm(q - p)) & (s >= 0) & (s <= reach) & (np.abs(w) <= half)
    return inside


def test_a_neck_is_cut_where_it_is_narrowest():
    """A hole's cap across a throat and a jaw fills the notch between them: a web under the neck
    (a plate 0.07 thick, too thin to be a part, reaching 0.55 from the neck's axis) from the trunk
    to 0.1 beyond the neck's narrowest section (a cone tapering from 0.14 to 0.10 at the head).
    The neck's saddle lies at that section; no disk there (DISK or WIDER saddle depths: 0.40 at
    most) cuts the head off, the web joins it to the trunk around the disk, so the head would be
    no part that ends the body (without the slide find_head finds no head). A disk slid
    beyond the web toward the head's peak cuts it off: find_head takes the head ball (centered at
    its center, as without the web), cut off with the web's end and none of the trunk."""
    pitch = 0.04
    legs = [capsule((x, y, -0.1), (x, y, -1.2), 0.12) for x in (-0.8, 0.6) for y in (-0.25, 0.25)]
    axis = np.array([0.7, 0.0, 0.5]) / np.linalg.norm([0.7, 0.0, 0.5])
    root, end = np.array([0.8, 0.0, 0.1]), np.array([1.6, 0.0, 0.65]) - 0.17 * axis
    body = [capsule((-1.2, 0, 0), (0.8, 0, 0), 0.45), *legs, capsule((-1.2, 0, 0), (-2.0, 0, 0.3), 0.06),
            _cone(root, end, 0.14, 0.10), ball((1.6, 0, 0.65), 0.2)]
    web = _web(root, end + 0.1 * axis, [axis[2], 0.0, -axis[0]], 0.55, 0.035)
    box = dict(lo=(-2.2, -0.6, -1.4), hi=(2.0, 0.6, 1.0))
    plain, webbed = voxel_solid(body, pitch, **box), voxel_solid(body + [web], pitch, **box)
    assert 0.2 < THICK * 0.45 and find_parts(webbed) is None  # the head is found as an end of the body
    centers = []
    for sol in (plain, webbed):
        found = find_head(sol)
        assert found is not None and found.terminal
        head = sol.origin + pitch * (np.stack(np.nonzero(found.head), 1) + 0.5)
        centers.append(head.mean(axis=0))
        assert abs(found.neck_depth - 0.10) < 1.5 * pitch and np.linalg.norm(found.neck - end) < 0.15
        beyond = sol.origin + pitch * (np.stack(np.nonzero(found.beyond), 1) + 0.5)
        assert np.all(np.linalg.norm(beyond - [1.6, 0, 0.65], axis=1) < 0.2 + 0.55)  # none of the trunk
        assert found.beyond.sum() * pitch ** 3 < 4.19 * 0.2 ** 3 + 0.55 * 0.2 * 0.07 + 3.15 * 0.14 ** 2 * 0.3
    np.testing.assert_allclose(centers, [[1.6, 0, 0.65]] * 2, atol=0.1)
    # on the webbed body no disk at the saddle cuts the head off: the web joins it to the trunk
    found = find_head(webbed)
    saddle = np.rint((found.neck - webbed.origin) / pitch - 0.5).astype(int)
    trunk = np.argwhere(webbed.depth == webbed.depth.max())[0]
    for disk in (DISK, WIDER):
        assert part_across(plain, find_head(plain).head, saddle, found.neck_depth, trunk, disk) is not None
        assert part_across(webbed, found.head, saddle, found.neck_depth, trunk, disk) is None
    assert 0.55 > WIDER * 0.10 + 2 * pitch


def test_a_second_end_only_beyond_a_distinct_neck():
    """find_parts' head may have two far ends (a hand resting on a head) where its neck is the
    body's clearly most constricted saddle. A rump that a hole took the tail from (a ball of
    0.36 with two legs, no tail) on a saddle of 0.29 is hardly more constricted than the head's
    neck (a ball of 0.3 on a neck of 0.245): (c - runner-up) / c below GAP_MIN, so find_parts'
    rump vouches for nothing and must end the body as any part must (one far end): find_head
    takes the head. With a thin waist (0.2: constriction 1.8 against the head's 1.2) find_parts'
    rump is the distinct neck's part and keeps its allowance of two ends."""
    pitch = 0.04
    legs = [capsule((-1.5, y, -0.2), (-1.5, y, -1.3), 0.1) for y in (-0.2, 0.2)]
    heads = []
    for waist_radius in (0.29, 0.2):
        sol = voxel_solid([capsule((-0.6, 0, 0), (0.8, 0, 0), 0.45), capsule((-1.5, 0, 0), (-0.6, 0, 0), waist_radius),
                           ball((-1.5, 0, 0), 0.36), *legs, capsule((0.8, 0, 0), (1.6, 0, 0), 0.245),
                           ball((1.75, 0, 0), 0.3)], pitch, lo=(-2.0, -0.6, -1.45), hi=(2.2, 0.6, 0.6))
        rump = find_parts(sol)
        at = sol.origin + pitch * (np.stack(np.nonzero(rump.head), 1) + 0.5)
        assert np.allclose(at.mean(axis=0), [-1.5, 0, 0], atol=0.1)  # find_parts takes the rump
        assert not waist(rump.neck_depth, sol.depth.max()) and rump.runner_up > 1.1
        saddle = np.rint((rump.neck - sol.origin) / pitch - 0.5).astype(int)
        beyond = part_across(sol, rump.head, saddle, rump.neck_depth)
        assert beyond.sum() <= SHARE * sol.inside.sum() and ends(sol, beyond, saddle, rump.head_depth) == 2
        gap = (rump.constriction - rump.runner_up) / rump.constriction
        assert (gap < GAP_MIN) == (waist_radius == 0.29)
        found = find_head(sol)
        heads.append((sol.origin + pitch * (np.stack(np.nonzero(found.head), 1) + 0.5)).mean(axis=0))
    np.testing.assert_allclose(heads, [[1.75, 0, 0], [-1.5, 0, 0]], atol=0.1)


def test_frame_pieces_of_a_solid_refuse_other_shapes_by_name():
    """Low-level frame pieces of rotation.core, .head and .parts (docs/api.md) given other shapes were
    NumPy's errors naming nothing: symmetry_scores' (2, 2) axes or (2,) center a matmul or broadcast
    ValueError, feet_offset's (3,) axes or up=5 an IndexError, merge_tree's two shapes a broadcast
    error (a 2-D grid: an empty tree), waist's array float()'s TypeError, mirror_error's (2,) normal a
    matmul error and no points a NaN. Each is refused by name; what they take is unchanged (a ball is
    its own mirror image about any plane through its center: scores 1, error 0)."""
    import jaxpose
    from jaxpose.rotation.core import feet_offset, symmetry_scores
    from jaxpose.rotation.head import mirror_error

    sol = voxel_solid([ball((0.0, 0.0, 0.0), 0.8)], pitch=0.2, lo=(-1.2, -1.2, -1.2), hi=(1.2, 1.2, 1.2))
    center = np.zeros(3)
    points = np.random.default_rng(0).normal(size=(40, 3))
    for call, message in (
            (lambda: symmetry_scores(sol, np.eye(2), center), r"^axes must be real numbers of shape \(3, 3\)"),
            (lambda: symmetry_scores(sol, np.eye(3), np.zeros(2)), r"^center must be real numbers of shape \(3,\)"),
            (lambda: symmetry_scores(sol.inside, np.eye(3), center), "^sol must be a Solid"),
            (lambda: feet_offset(sol, np.ones(3)), r"^axes must be real numbers of shape \(3, 3\)"),
            (lambda: feet_offset(sol, np.eye(3), up=5), "^up and forward must be two different axes, 0, 1 or 2"),
            (lambda: feet_offset(sol, np.eye(3), up=2, forward=2), "^up and forward must be two different axes"),
            (lambda: merge_tree(sol.inside, sol.depth[:, :, :-1]), "^inside and depth must be one 3-D grid"),
            (lambda: merge_tree(sol.inside[0], sol.depth[0]), r"^inside and depth must be one 3-D grid .*got shapes \(12, 12\)"),
            (lambda: waist(np.zeros(2), 0.45), "^death must be a finite number >= 0"),
            (lambda: mirror_error(points, center, np.array([1.0, 0.0])), r"^normal must be real numbers of shape \(3,\)"),
            (lambda: mirror_error(np.zeros((0, 3)), center, np.array([1.0, 0.0, 0.0])), "^points needs at least 1 point, got 0")):
        with pytest.raises(jaxpose.InvalidInputError, match=message):
            call()
    np.testing.assert_allclose(symmetry_scores(sol, np.eye(3), center), 1.0)
    assert mirror_error(np.r_[points, points * [-1, 1, 1]], center, np.array([1.0, 0.0, 0.0])) == 0.0
    assert waist(0.36, 0.45) and not waist(0.25, 0.45)  # 0.45 < 1.5 x 0.36; 0.45 > 1.5 x 0.25


def test_mirror_scores_and_feet_of_an_empty_solid_are_refused_by_name():
    """symmetry_scores and feet_offset (rotation.core, docs/api.md) of a solid with no voxel inside
    were NumPy's 'zero-size array to reduction operation maximum'. Refused by name; their callers
    never pass one (core_frame and head_frame flag such a solid: ambiguity 1, as before)."""
    import jaxpose
    from jaxpose.rotation.core import core_frame, feet_offset, symmetry_scores
    from jaxpose.rotation.head import head_frame

    sol = voxel_solid([ball((0.0, 0.0, 0.0), 0.8)], pitch=0.2, lo=(-1.2, -1.2, -1.2), hi=(1.2, 1.2, 1.2))
    empty = sol._replace(inside=np.zeros_like(sol.inside), depth=np.zeros_like(sol.depth))
    for call, what in ((lambda: symmetry_scores(empty, np.eye(3), np.zeros(3)), "no mirror score"),
                       (lambda: feet_offset(empty, np.eye(3)), "no feet")):
        with pytest.raises(jaxpose.InvalidInputError, match=rf"^sol has no voxel inside .*0 voxels set\): an empty solid has {what}"):
            call()
    vertices = np.random.default_rng(0).normal(size=(10, 3))
    for frame in (core_frame(empty), head_frame(empty, vertices)):
        assert frame.ambiguity == 1.0 and frame.flag
        np.testing.assert_array_equal(frame.rotation, np.eye(3))
    np.testing.assert_allclose(symmetry_scores(sol, np.eye(3), np.zeros(3)), 1.0)  # a ball: its own mirror image


def test_mirror_error_reads_the_normal_as_a_direction():
    """head.mirror_error (docs/api.md) took its normal as a unit vector without a word: a zero
    normal read 0.0 (a perfect mirror) for any points, a normal of length 2 reflected them off the
    plane (a line's mirror error about its own perpendicular plane read 0.5). The plane is the one
    normal to the direction; a zero normal is refused by name."""
    import jaxpose
    from jaxpose.rotation.head import mirror_error

    line = np.c_[np.linspace(-1.0, 1.0, 21), np.zeros(21), np.zeros(21)]  # symmetric about x = 0
    skew = line[line[:, 0] >= -0.5]  # x in [-0.5, 1]: reflected in x = 0, 10 of 16 land on points
    e = np.array([1.0, 0.0, 0.0])
    # independent oracle: the reflection x -> -x, nearest neighbours by brute force
    want = np.mean([np.min(np.abs(skew[:, 0] + x)) for x in skew[:, 0]])
    for normal in (e, 2.0 * e, 1e-3 * e, 1e200 * e, 1e-170 * e):  # (1e200, 1e-170: the norm over- and underflowed; review)
        assert mirror_error(line, np.zeros(3), normal) == pytest.approx(0.0, abs=1e-12)
        assert mirror_error(skew, np.zeros(3), normal) == pytest.approx(want, rel=1e-12)
    with pytest.raises(jaxpose.InvalidInputError, match="^normal is zero: no plane to mirror in"):
        mirror_error(line, np.zeros(3), np.zeros(3))
