"""Pinned results: centers, scales and solver outputs of fixed inputs, recorded from the code
before a restructuring and checked after it (float64 and float32).

``python tests/test_pinned.py --write`` records them again into ``tests/data/pinned.json``;
do that only for a change that is meant to alter results, and say which in the commit.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from conftest import box_surface, clusters, sphere_with_arm  # noqa: E402

import jaxpose  # noqa: E402

PINNED = Path(__file__).resolve().parent / "data" / "pinned.json"
RTOL64, RTOL32 = 1e-9, 2e-5
M = 400


def _inputs():
    from jaxpose.mesh import example_shape, sample_surface

    return {  # one point count: one compilation per option set
        "sphere_arm": sphere_with_arm(M, seed=1),
        "clusters": clusters(M, seed=2) * 3.0 + 5.0,
        "box": box_surface(M, seed=3),
        "example": sample_surface(example_shape(), M, seed=4),
    }


def _vec(pose):
    return [float(v) for v in np.asarray(pose.center, np.float64).reshape(-1)] + \
        [float(v) for v in np.asarray(pose.scale, np.float64).reshape(-1)]


def compute(x64: bool) -> dict:
    """Every pinned value, computed by the code as it is."""
    old = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", x64)
    try:
        out = {}
        inputs = _inputs()
        for name, pts in inputs.items():
            out[f"{name}/normalize"] = _vec(jaxpose.normalize(pts))
        for name in ("sphere_arm", "box"):
            out[f"{name}/normalize_g20_n0.3_r32"] = _vec(jaxpose.normalize(inputs[name], 20.0, 0.3, resolution=32))
        pts = inputs["sphere_arm"]
        out["sphere_arm/smo"] = _vec(jaxpose.normalize(pts, solver="smo"))
        out["sphere_arm/auto"] = _vec(jaxpose.normalize(pts, solver="auto"))
        out["sphere_arm/refine4"] = _vec(jaxpose.normalize(pts, resolution=32, refine=4))
        batch = jaxpose.normalize_batch([inputs["sphere_arm"], inputs["box"][:350]], resolution=32)
        out["batch"] = _vec(batch)
        svdd = jaxpose.fit_svdd(inputs["clusters"], 0.5, 0.3)
        out["fit_svdd/clusters"] = [float(svdd.objective), float(svdd.offset), float(jnp.sum(svdd.alpha)),
                                    int(svdd.iterations)]
        mom = jaxpose.volume_moments(svdd, resolution=32)
        out["volume_moments/clusters"] = [*map(float, np.asarray(mom.center)), float(mom.mean_distance),
                                          float(mom.volume)]
        f = jaxpose.decision_function(svdd, inputs["clusters"][:5])
        out["decision_function/clusters"] = [float(v) for v in np.asarray(f)]
        if x64:
            from jaxpose.mesh import normalize_mesh, example_shape

            mesh = example_shape()
            for method in ("surface_centroid", "vertex_mean", "bbox", "min_ball"):
                out[f"mesh/{method}"] = _vec(normalize_mesh(mesh, method=method)[1])
            out["mesh/ocsvm"] = _vec(normalize_mesh(mesh, count=M, method="ocsvm")[1])
            p = inputs["sphere_arm"]
            jac = jax.jacfwd(lambda g, n: jnp.concatenate(
                [(q := jaxpose.normalize(p, g, n, resolution=16, tol=1e-6)).center, q.scale[None]]),
                argnums=(0, 1))(20.0, 0.3)
            out["jacfwd_exact/sphere_arm"] = [float(v) for v in np.concatenate([np.asarray(j) for j in jac])]
        return out
    finally:
        jax.config.update("jax_enable_x64", old)


@pytest.fixture(scope="module")
def pinned():
    return json.loads(PINNED.read_text())


@pytest.mark.parametrize("x64", [True, False], ids=["float64", "float32"])
def test_results_are_pinned(pinned, x64):
    expected = pinned["float64" if x64 else "float32"]
    got = compute(x64)
    assert sorted(got) == sorted(expected)
    rtol = RTOL64 if x64 else RTOL32
    for key in expected:
        np.testing.assert_allclose(got[key], expected[key], rtol=rtol, atol=rtol * 1e-3, err_msg=key)


if __name__ == "__main__":
    if "--write" in sys.argv:
        PINNED.write_text(json.dumps({"float64": compute(True), "float32": compute(False)}, indent=1) + "\n")
        print(f"wrote {PINNED}")
    else:
        a, b = json.loads(PINNED.read_text()), {"float64": compute(True), "float32": compute(False)}
        same = {k: all(a[k][n] == b[k][n] for n in a[k]) for k in a}
        print("bit-identical:", same)
