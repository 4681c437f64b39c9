"""The evaluation's input variants, exactly as documented: stray parts, points, holes; seeded."""
import numpy as np
import pytest
import trimesh

from jaxpose import InvalidInputError
from jaxpose.evaluation.variants import VARIANTS, make_class, make_variant, stray_mask, up_axis


def _body():
    return trimesh.creation.capsule(height=1.6, radius=0.3, count=[32, 32])


@pytest.mark.parametrize("variant,low,high", [("outliers", 0.02, 0.05), ("big_outliers", 0.08, 0.15)])
def test_stray_part_area_and_separation(variant, low, high):
    body = _body()
    for seed in range(5):
        out = make_variant(body, variant, np.random.default_rng([seed, 0, 0]), up=up_axis(body))
        extra = out.area - body.area
        assert low * body.area <= extra <= high * body.area
        part = np.asarray(out.vertices)[len(body.vertices):]
        lo, hi = body.bounds
        horiz = [k for k in range(3) if k != up_axis(body)]
        gap = np.maximum(np.maximum(lo[horiz] - part[:, horiz], part[:, horiz] - hi[horiz]), 0).max(axis=1)
        assert gap.min() > 0  # outside the bounding box, never touching the body
        assert out.metadata["stray"]["fraction"] == pytest.approx(extra / body.area, rel=1e-9)


def test_half_of_a_class_gets_the_stray_part_reproducibly():
    meshes = [_body() for _ in range(6)]
    a = make_class(meshes, "outliers", seed=3, class_index=1)
    b = make_class(meshes, "outliers", seed=3, class_index=1)
    grown = [len(m.faces) > len(meshes[0].faces) for m in a]
    assert sum(grown) == 3 and grown == list(stray_mask(6, 3, 1))
    assert all(np.array_equal(x.vertices, y.vertices) for x, y in zip(a, b))  # seeded
    c = make_class(meshes, "outliers", seed=4, class_index=1)
    assert any(not np.array_equal(x.vertices, y.vertices) for x, y in zip(a, c))


@pytest.mark.parametrize("seed", (1.5, True, -1, "a", np.float64(2.0)))
def test_a_seed_that_is_not_an_int_is_refused(seed):
    """make_class and stray_mask refuse a bad seed by name, as every entry point does (1.5 was
    NumPy's TypeError, "a" and -1 its ValueError; True was taken as 1)."""
    meshes = [_body() for _ in range(2)]
    with pytest.raises(InvalidInputError, match="^seed must be"):
        make_class(meshes, "outliers", seed=seed, class_index=0)
    with pytest.raises(InvalidInputError, match="^seed must be"):
        stray_mask(6, seed, 0)
    assert list(stray_mask(6, np.int64(3), 1)) == list(stray_mask(6, 3, 1))


@pytest.mark.parametrize("class_index", (True, 1.0, 1.5, -1, "a", None, np.float64(1.0)))
def test_a_class_index_that_is_not_an_int_is_refused(class_index):
    """make_class and stray_mask refuse a bad class_index by name (an int >= 0, the library's int
    rule): True was taken as 1, 1.0 and 1.5 were NumPy's TypeError "seed must be integer", -1 and
    "a" its ValueError, None a TypeError from len()."""
    meshes = [_body() for _ in range(2)]
    with pytest.raises(InvalidInputError, match="^class_index must be"):
        make_class(meshes, "outliers", seed=3, class_index=class_index)
    with pytest.raises(InvalidInputError, match="^class_index must be"):
        stray_mask(6, 3, class_index)


def test_a_class_index_may_be_a_numpy_or_jax_integer():
    """A () JAX integer array was a TypeError from len(); it is the same class as the int."""
    import jax.numpy as jnp

    meshes = [_body() for _ in range(4)]
    one = make_class(meshes, "outliers", seed=3, class_index=1)
    for same in (np.int64(1), jnp.int32(1)):
        assert list(stray_mask(4, 3, same)) == list(stray_mask(4, 3, 1))
        assert all(np.array_equal(x.vertices, y.vertices)
                   for x, y in zip(make_class(meshes, "outliers", seed=3, class_index=same), one))



@pytest.mark.parametrize("up,message", [(3, "^up must be 0, 1 or 2"), (-1, "^up must be 0, 1 or 2"),
                                        (1.5, "^up must be an int"), (True, "^up must be an int"),
                                        ("z", "^up must be an int")])
def test_an_up_that_is_not_an_axis_is_refused(up, message):
    """make_class and make_variant take up as an axis 0, 1 or 2 (None: make_class's default): 3
    and -1 were NumPy's broadcast ValueError, "z" int()'s ValueError, 1.5 and True were taken as 1."""
    meshes = [_body() for _ in range(2)]
    with pytest.raises(InvalidInputError, match=message):
        make_class(meshes, "outliers", seed=3, class_index=0, up=up)
    with pytest.raises(InvalidInputError, match=message):
        make_variant(meshes[0], "outliers", np.random.default_rng(0), up=up)


def test_an_empty_class_is_refused():
    """make_class([]) was an IndexError on meshes[0] with up=None (the class's up axis) and [] with
    an up given; refused by name either way."""
    for up in (None, 2):
        with pytest.raises(InvalidInputError, match="^meshes is empty: a class needs at least one mesh"):
            make_class([], "plain", seed=3, class_index=0, up=up)
    with pytest.raises(InvalidInputError, match="^meshes must be a list of meshes, got None"):  # len()'s TypeError
        make_class(None, "plain", seed=3, class_index=0)
    for up in (None, 2):  # load_folder's {class: meshes}: a KeyError 0 (up=None), its keys as meshes (up=2)
        with pytest.raises(InvalidInputError, match=r"^meshes must be one class's list of meshes, got a mapping"):
            make_class({"chair": [_body()]}, "plain", seed=3, class_index=0, up=up)
    with pytest.raises(InvalidInputError, match=r"^rng must be a numpy\.random\.Generator"):  # 'int' object has no attribute 'uniform'
        make_variant(_body(), "outliers", 0)


def test_holes_remove_ten_percent_in_five_patches():
    body = _body()
    out = make_variant(body, "holes", np.random.default_rng([0, 0, 0]))
    removed = len(body.faces) - len(out.faces)
    assert removed == pytest.approx(0.10 * len(body.faces), abs=5)
    assert out.metadata["holes"]["removed_faces"] == removed
    boundary = out.edges_sorted[trimesh.grouping.group_rows(out.edges_sorted, require_count=1)]
    loops = trimesh.graph.connected_components(boundary)
    assert 1 <= len(loops) <= 5  # five patches (two may merge)


def test_points_and_plain():
    body = _body()
    pts = make_variant(body, "points", np.random.default_rng(0))
    assert isinstance(pts, trimesh.PointCloud) and np.array_equal(pts.vertices, body.vertices)
    plain = make_variant(body, "plain", np.random.default_rng(0))
    assert plain is not body and np.array_equal(plain.vertices, body.vertices)
    with pytest.raises(InvalidInputError, match="unknown variant"):
        make_variant(body, "noise", np.random.default_rng(0))
    assert VARIANTS == ("plain", "outliers", "big_outliers", "points", "holes")
