"""Pinned results: centers, scales and solver outputs of fixed inputs, recorded from the code
before a restructuring and checked after it (float64 and float32).

``python tests/test_pinned.py --write`` records them again into ``tests/data/pinned.json``;
do that only for a change that is meant to alter results, and say which in the commit;
``python tests/test_pinned.py`` prints, per key, whether this machine reproduces them bit for bit.

On the recording machine the values are reproduced bit for bit. Another CPU vectorizes reductions
differently, so the test compares in units of each value's own magnitude floor (the shape's scale
for centers): float64 agrees to ~1e-12 there and float32 to ~1e-4; SMO's discrete working-set
choices can diverge and stop elsewhere within its tolerance (5e-4 of the scale seen).
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
TOL = {"float64": 1e-9, "float32": 3e-4}  # of each value's own magnitude floor (_floors)
TOL_SMO = 2e-3  # the SMO solver's paths (solver="smo" and "auto" at this size), both precisions
ITERATIONS_RTOL = {"float64": 0.0, "float32": 0.2}  # solver iteration counts
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
            out[f"{name}/normalize"] = _vec(jaxpose.normalize(pts, method="ocsvm"))
        for name in ("sphere_arm", "box"):
            out[f"{name}/normalize_g20_n0.3_r32"] = _vec(jaxpose.normalize(inputs[name], method="ocsvm", gamma=20.0, nu=0.3, resolution=32))
        pts = inputs["sphere_arm"]
        out["sphere_arm/smo"] = _vec(jaxpose.normalize(pts, method="ocsvm", solver="smo"))
        out["sphere_arm/auto"] = _vec(jaxpose.normalize(pts, method="ocsvm", solver="auto"))
        out["sphere_arm/refine4"] = _vec(jaxpose.normalize(pts, method="ocsvm", resolution=32, refine=4))
        batch = jaxpose.normalize_batch([inputs["sphere_arm"], inputs["box"][:350]], method="ocsvm", resolution=32)
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
                [(q := jaxpose.normalize(p, method="ocsvm", gamma=g, nu=n, resolution=16, tol=1e-6, derivative="exact")).center,
                 q.scale[None]]),
                argnums=(0, 1))(20.0, 0.3)
            out["jacfwd_exact/sphere_arm"] = [float(v) for v in np.concatenate([np.asarray(j) for j in jac])]
        return out
    finally:
        jax.config.update("jax_enable_x64", old)


@pytest.fixture(scope="module")
def pinned():
    return json.loads(PINNED.read_text())


def _floors(key, want):
    """The magnitude each entry of a record is compared in: a pose's scale for its center and
    scale; a volume's mean distance for its center; the largest value of a decision function or
    a Jacobian; the value itself for the solver's objective, offset and sum."""
    if key.startswith("fit_svdd"):
        return np.abs(want[:3])
    if key.startswith("volume_moments"):
        return np.concatenate([np.full(3, abs(want[3])), np.abs(want[3:])])
    if key.startswith(("decision_function", "jacfwd")):
        return np.full(want.shape, np.max(np.abs(want)))
    scale = np.min(np.abs(want[-2:])) if key == "batch" else abs(want[-1])
    return np.full(want.shape, scale)


@pytest.mark.parametrize("x64", [True, False], ids=["float64", "float32"])
def test_results_are_pinned(pinned, x64):
    expected = pinned["float64" if x64 else "float32"]
    got = compute(x64)
    assert sorted(got) == sorted(expected)
    precision = "float64" if x64 else "float32"
    failures = []
    for key in expected:
        want, have = np.asarray(expected[key], np.float64), np.asarray(got[key], np.float64)
        tol = TOL_SMO if key.endswith(("/smo", "/auto")) else TOL[precision]
        if key.startswith("fit_svdd"):  # the iteration count separately
            if abs(have[3] - want[3]) > ITERATIONS_RTOL[precision] * want[3]:
                failures.append((key, "iterations", have[3], want[3]))
            want, have = want[:3], have[:3]
        err = np.abs(have - want) / _floors(key, want)
        if not np.all(err <= tol):
            failures.append((key, float(err.max()), have.tolist(), want.tolist()))
    assert not failures, failures


if __name__ == "__main__":
    if "--write" in sys.argv:
        PINNED.write_text(json.dumps({"float64": compute(True), "float32": compute(False)}, indent=1) + "\n")
        print(f"wrote {PINNED}")
    else:
        a, b = json.loads(PINNED.read_text()), {"float64": compute(True), "float32": compute(False)}
        same = {k: all(a[k][n] == b[k][n] for n in a[k]) for k in a}
        print("bit-identical:", same)
