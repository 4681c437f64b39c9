"""Components labelled by runs of cells (jaxpose.occupancy.runs) against scipy.ndimage.label and
against the NumPy keep_main / linked_parts; the cell-by-cell fallback for grids with more runs than
the run arrays hold, one at a time and in a vmapped batch."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import ndimage

from jaxpose.occupancy import bits, runs
from jaxpose.occupancy import points as po
from jaxpose.occupancy import solid as host_solid

EIGHT26 = np.ones((3, 3, 3), bool)


def _random_solid(shape, seed, density):
    rng = np.random.default_rng(seed)
    return ndimage.binary_opening(rng.random(shape) < density) | (rng.random(shape) < 0.01)


def _numpy_runs(s):
    """(first, last) flat indices of the runs along the last axis, in flat order."""
    flat = np.pad(s, [(0, 0), (0, 0), (1, 1)]).astype(np.int8)
    d = np.diff(flat, axis=-1)
    a, b, c = s.shape
    idx = np.arange(a * b * c).reshape(a, b, c)
    return idx[d[..., :-1] == 1], idx[d[..., 1:] == -1]


def _find(s, cap):
    s = jnp.asarray(s)
    return jax.jit(runs.find_runs, static_argnums=(1, 2))(bits.pack(s), s.shape[-1], cap)


@pytest.mark.parametrize("shape", [(7, 6, 5), (12, 10, 33), (20, 18, 70), (9, 8, 130)])
def test_find_runs_equals_numpy(shape):
    s = np.random.default_rng(sum(shape)).random(shape) < 0.5
    first, last = _numpy_runs(s)
    found = _find(s, runs.default_cap(shape))
    n = len(first)
    assert int(found.count) == n and bool(found.fits) and n > 20
    assert np.array_equal(np.asarray(found.first)[:n], first) and np.array_equal(np.asarray(found.last)[:n], last)
    assert np.all(np.asarray(found.valid)[:n]) and not np.any(np.asarray(found.valid)[n:])


def test_find_runs_counts_beyond_cap():
    s = np.random.default_rng(3).random((10, 10, 40)) < 0.5
    first, _ = _numpy_runs(s)
    found = _find(s, 64)
    assert int(found.count) == len(first) > 64 and not bool(found.fits)
    assert np.array_equal(np.asarray(found.first), first[:64])


@pytest.mark.parametrize("shape,density,seed", [((40, 36, 30), 0.45, 0), ((30, 28, 70), 0.55, 1),
                                                ((25, 30, 40), 0.3, 2), ((16, 16, 96), 0.62, 3)])
def test_run_labels_partition_equals_scipy(shape, density, seed):
    """Each cell's run label names its 26-connected component (scipy), one label per component,
    the component's smallest flat index in its first run."""
    s = _random_solid(shape, seed, density)
    ref, n = ndimage.label(s, structure=EIGHT26)
    assert n > 20  # many components: the test means something
    found = _find(s, runs.default_cap(shape))
    assert bool(found.fits)
    labels = np.asarray(jax.jit(runs.run_labels, static_argnums=1)(found, shape))
    first = np.asarray(found.first)[: int(found.count)]
    per_cell = np.full(s.size, -1)
    last = np.asarray(found.last)[: int(found.count)]
    for k, (f, l) in enumerate(zip(first, last)):
        per_cell[f:l + 1] = labels[k]
    per_cell = per_cell.reshape(shape)
    pairs = set(zip(per_cell[s].tolist(), ref[s].tolist()))
    assert len(pairs) == n and len(set(per_cell[s].tolist())) == n
    for lab in set(per_cell[s].tolist()):  # the label is the run holding the smallest flat index
        assert first[lab] == np.flatnonzero(per_cell.reshape(-1) == lab)[0]


def _stripes(shape=(130, 130, 40)):
    """Planes of every other z: 20 components, more runs (338,000) than the run arrays hold; one
    plane 0.77 of the others (kept at ratio 0.5, dropped at 0.9)."""
    s = np.zeros(shape, bool)
    s[:, :, ::2] = True
    s[100:, :, 10] = False
    return s


@pytest.mark.parametrize("ratio", [0.5, 0.9])
def test_keep_main_beyond_cap_falls_back(ratio):
    s = _stripes()
    found = _find(s, runs.default_cap(s.shape))
    assert not bool(found.fits)
    # the ratio traced (as test_occupancy_points.py's keep_main tests): both ratios one program
    kept, count, dropped = jax.jit(po.keep_main)(jnp.asarray(s), ratio)
    ref, n, d = host_solid.keep_main(s, ratio)
    assert np.array_equal(np.asarray(kept), ref) and (int(count), int(dropped)) == (n, d)
    assert n == 20 and d == (1 if ratio == 0.9 else 0)


@pytest.mark.parametrize("ratio", [0.5, 0.05])
def test_keep_main_by_runs_equals_numpy(ratio):
    # a random solid in the first 40 planes of the stripes' grid: its find_runs and keep_main programs
    s = _random_solid((130, 130, 40), 4, 0.5) & (np.arange(130) < 40)[:, None, None]
    assert bool(_find(s, runs.default_cap(s.shape)).fits)
    kept, count, dropped = jax.jit(po.keep_main)(jnp.asarray(s), ratio)  # traced ratio: one program
    ref, n, d = host_solid.keep_main(s, ratio)
    assert n > 20 and d > 0
    assert np.array_equal(np.asarray(kept), ref) and (int(count), int(dropped)) == (n, d)


def test_keep_main_vmapped_mixed_batch():
    """A batch whose members fit the run arrays and one that does not: every member as NumPy
    (the whole batch takes the cell-by-cell branch), and a batch that fits (the run branch)."""
    small = [_random_solid((130, 130, 40), k, 0.5) & (np.arange(130) < 40)[:, None, None] for k in (5, 6, 7)]
    mixed = np.stack(small[:2] + [_stripes()])
    keep = jax.jit(jax.vmap(lambda g: po.keep_main(g, 0.5)))
    for grids in (mixed, np.stack(small)):  # batches of three: one compiled program
        kept, found, dropped = keep(jnp.asarray(grids))
        for k in range(len(grids)):
            ref, n, d = host_solid.keep_main(grids[k], 0.5)
            assert np.array_equal(np.asarray(kept[k]), ref) and (int(found[k]), int(dropped[k])) == (n, d)


def test_either_vmap_takes_one_branch_for_the_batch():
    calls = []

    def dense(x):
        calls.append("dense")
        return x * 2

    def sparse(x):
        calls.append("sparse")
        return x * 3

    f = jax.jit(jax.vmap(lambda x: runs.either(x > 0, dense, sparse, x)))
    assert np.array_equal(np.asarray(f(jnp.array([1, -1, 2]))), [2, -2, 4])  # one needs dense: all dense
    assert np.array_equal(np.asarray(f(jnp.array([-1, -2]))), [-3, -6])
    single = jax.jit(lambda x: runs.either(x > 0, dense, sparse, x))
    assert int(single(jnp.int32(-4))) == -12 and int(single(jnp.int32(4))) == 8
    assert set(calls) == {"dense", "sparse"}


def _parts_reference(occupied, near):
    """linked_parts in NumPy on 2 x 2 x 2 blocks (scipy labels)."""
    pad = occupied.shape[0] % 2
    occ = np.pad(occupied, [(0, pad)] * 3)
    nr = np.pad(near, [(0, pad)] * 3)
    h = occ.shape[0] // 2
    cells = nr.reshape(h, 2, h, 2, h, 2).any(axis=(1, 3, 5))
    count = occ.reshape(h, 2, h, 2, h, 2).sum(axis=(1, 3, 5))
    lab, n = ndimage.label(cells, structure=EIGHT26)
    if n == 0:
        return 0.0
    size = np.sort(np.bincount(lab[cells], weights=count[cells], minlength=n + 1)[1:])[::-1]
    return float(size[1] / max(size[0], 1)) if n > 1 else 0.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_linked_parts_equals_scipy(seed):
    """Three clusters of occupied voxels of different sizes and scattered single voxels."""
    rng = np.random.default_rng(seed)
    occupied = rng.random((61, 61, 61)) < 0.0005
    for center, count in (((15, 15, 15), 400), ((45, 20, 40), 150 + 50 * seed), ((20, 45, 45), 60)):
        idx = np.clip(np.round(rng.normal(size=(count, 3)) * 3 + center).astype(int), 0, 60)
        occupied[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    near = ndimage.binary_dilation(occupied, iterations=2)
    out = float(jax.jit(po.linked_parts)(jnp.asarray(occupied), jnp.asarray(near)))
    ref = _parts_reference(occupied, near)
    assert 0.2 < ref < 0.9  # the second cluster over the first: the test means something
    assert out == pytest.approx(ref, rel=1e-6)
