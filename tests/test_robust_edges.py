"""Shapes at the edge of the robust estimator (issue 36.5): each is a clear JaxposeError with its
reason at the public boundary (jaxpose.normalize_mesh, the command line), never a confident number;
shapes just inside the edges still get their pose."""
import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose import JaxposeError, cli

SPHERE = trimesh.creation.icosphere(subdivisions=3)


def _sheet(amplitude=0.2, n=30):
    u, v = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    z = amplitude * np.sin(3 * u) * np.cos(2 * v)
    faces = [[i * n + j, i * n + j + 1, (i + 1) * n + j + 1] for i in range(n - 1) for j in range(n - 1)]
    faces += [[i * n + j, (i + 1) * n + j + 1, (i + 1) * n + j] for i in range(n - 1) for j in range(n - 1)]
    return trimesh.Trimesh(np.c_[u.ravel(), v.ravel(), z.ravel()], faces, process=False)


def _spheres(*placed):
    parts = []
    for scale, shift in placed:
        s = SPHERE.copy()
        s.apply_scale(scale)
        s.apply_translation(shift)
        parts.append(s)
    return trimesh.util.concatenate(parts)


def _cloud(n, seed=0):
    x = np.random.default_rng(seed).normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


@pytest.mark.parametrize("shape, reason", [
    (lambda: _sheet(), "mostly open"),  # an open sheet: the fan caps would make its solid
    (lambda: trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]]), "encloses no volume"),
    (lambda: _cloud(30), "too sparse for a closing"),
    (lambda: _spheres((1, (0, 0, 0)), (1, (5, 0, 0))), "2 separate bodies of equal size"),
    (lambda: _spheres((1, (0, 0, 0)), (1, (5, 0, 0)), (1, (0, 5, 0))), "3 separate bodies of equal size"),
])
def test_edge_shapes_are_refused_with_their_reason(shape, reason):
    with pytest.raises(JaxposeError, match=reason):
        jaxpose.normalize_mesh(shape())


def test_shapes_inside_the_edges_keep_their_pose():
    _, pose = jaxpose.normalize_mesh(_spheres((1, (0, 0, 0)), (0.3, (5, 0, 0))))  # a small stray part: dropped
    np.testing.assert_allclose(pose.center, 0.0, atol=2e-3)
    _, pose = jaxpose.normalize_mesh(_spheres((1, (0, 0, 0)), (0.78, (5, 0, 0))))  # unequal bodies: kept together
    assert 0.1 < pose.center[0] < 2.5
    _, pose = jaxpose.normalize_mesh(_cloud(60))  # sparse, still closed: 12 voxels across
    assert np.all(np.isfinite(pose.center))
    _, pose = jaxpose.normalize_mesh(_cloud(2000))  # dense enough for a closing
    np.testing.assert_allclose(pose.center, 0.0, atol=0.02)
    assert abs(float(pose.scale) / (4 / 3 * np.pi) ** (1 / 3) - 1) < 0.03
    holed = SPHERE.copy()
    holed.update_faces(np.arange(len(holed.faces)) % 10 != 0)  # a tenth of the faces gone: holes, not a sheet
    _, pose = jaxpose.normalize_mesh(holed)
    np.testing.assert_allclose(pose.center, 0.0, atol=0.02)


def test_command_line_says_why_and_what_to_use(tmp_path, capsys):
    path = tmp_path / "two.ply"
    _spheres((1, (0, 0, 0)), (1, (5, 0, 0))).export(path)
    assert cli.main(["normalize", str(path), "-o", str(tmp_path / "out.ply")]) == 1
    err = capsys.readouterr().err
    assert "separate bodies" in err and "--method surface_centroid" in err and "Traceback" not in err
    assert not (tmp_path / "out.ply").exists()
