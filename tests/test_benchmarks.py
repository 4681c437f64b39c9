"""benchmarks/ (``jaxpose bench``): runs in quick mode on tiny sizes and writes the JSON schema. No timing assertions."""
import json

import numpy as np
import pytest

import benchmarks as bench
from jaxpose import cli

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def _tiny(monkeypatch):
    monkeypatch.setitem(bench.QUICK, "m", 120)
    monkeypatch.setitem(bench.QUICK, "repeats", 1)
    monkeypatch.setitem(bench.QUICK, "batch_objects", 2)
    monkeypatch.setitem(bench.QUICK, "batch_m", 80)
    monkeypatch.setitem(bench.QUICK, "scaling_m", (80,))
    monkeypatch.setitem(bench.QUICK, "resolutions", (8,))
    monkeypatch.setitem(bench.QUICK, "resolution", 8)
    monkeypatch.setitem(bench.QUICK, "sk_resolution", 8)
    monkeypatch.setitem(bench.QUICK, "ref_resolution", 8)
    monkeypatch.setitem(bench.QUICK, "ref_refine", 2)
    monkeypatch.setitem(bench.QUICK, "accuracy_objects", 2)
    monkeypatch.setitem(bench.QUICK, "accuracy_sk_resolutions", (8, 12))


def _timing(d, compiled=True):
    assert d["median_s"] >= 0 and isinstance(d["runs_s"], list)
    if compiled:
        assert d["compile_s"] >= 0 and d["first_s"] >= 0


def _check_schema(r, sk):
    assert r["schema_version"] == bench.SCHEMA_VERSION
    assert r["quick"] is True
    assert {"source", "gamma", "nu", "repeats", "environment", "sklearn", "sections"} <= set(r)
    assert r["environment"]["backend"]
    assert set(r["sections"]) == set(bench.SECTIONS)
    s = r["sections"]

    solver = s["solver"]
    _timing(solver["jaxpose"])
    assert {"iterations", "objective", "kkt_violation", "n_support", "feasibility"} <= set(solver["jaxpose"])
    end = s["end2end"]
    _timing(end["jaxpose"])
    assert {"center", "scale", "center_err", "center_err_rel_scale"} <= set(end["jaxpose"])
    assert {"center", "scale", "boundary_resolution"} <= set(end["reference"])
    batch = s["batch"]
    for k in ("jaxpose_batch", "jaxpose_loop"):
        _timing(batch[k])
        assert batch[k]["objects_per_s"] > 0
    scaling = s["scaling"]
    assert [row["m"] for row in scaling["in_m"]] == [80]
    assert "peak_rss_mb" in scaling["in_m"][0]["jaxpose"], scaling["in_m"][0]["jaxpose"]
    assert [row["resolution"] for row in scaling["in_resolution"]["rows"]] == [8]
    acc = s["accuracy"]
    assert acc["n_objects"] == 2 and len(acc["objects"]) == 2 and len(set(acc["objects"])) == 2
    _check_errors(acc["jaxpose"], 2)

    if sk:
        assert r["sklearn"] == "available"
        _timing(solver["sklearn"], compiled=False)
        assert solver["ratio"] > 0
        # same problem, same mapping: the objectives agree to solver tolerance (not a timing)
        assert abs(solver["objective_rel_diff"]) < 1e-2
        assert end["ratio"] > 0 and "center_err" in end["sklearn"]
        assert batch["sklearn_loop"]["objects_per_s"] > 0
        assert "peak_rss_mb" in scaling["in_m"][0]["sklearn"]
        assert scaling["in_resolution"]["rows"][0]["ratio"] > 0
        assert sorted(acc["sklearn"]) == ["12", "8"]
        for v in acc["sklearn"].values():
            _check_errors(v, 2)
    else:
        assert r["sklearn"] == bench.UNAVAILABLE
        assert solver["sklearn"] == bench.UNAVAILABLE and solver["ratio"] is None
        assert end["sklearn"] == bench.UNAVAILABLE
        assert batch["sklearn_loop"] == bench.UNAVAILABLE
        assert acc["sklearn"] == bench.UNAVAILABLE


def _check_errors(v, n):
    """The accuracy section's summary is that of its per-object errors."""
    import numpy as np

    err = np.array(v["center_err"])
    assert err.shape == (n,) and np.all(np.isfinite(err)) and np.all(err >= 0)
    assert v["median"] == np.median(err) and v["max"] == err.max()
    assert v["within_bar"] == int(np.sum(err <= bench.sections.ACCURACY_BAR))
    sc = np.array(v["scale_err_rel"])
    assert sc.shape == (n,) and np.all(np.isfinite(sc)) and np.all(sc >= 0)
    assert v["scale_median"] == np.median(sc) and v["scale_max"] == sc.max()


def test_bench_quick_json(tmp_path, monkeypatch, capsys):
    _tiny(monkeypatch)
    out = tmp_path / "bench.json"
    code = cli.main(["bench", "--quick", "--json", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "[solver]" in text and "[end2end]" in text and "[accuracy]" in text and "ratio" in text
    r = json.loads(out.read_text())
    _check_schema(r, sk=bench.sklearn_available())
    # refuses to overwrite
    assert bench.cli(["--quick", "--sections", "solver", "--json", str(out)]) == 1


def test_bench_without_sklearn(monkeypatch):
    _tiny(monkeypatch)
    # every section asks jaxpose.bench.common.sklearn_available (the package re-exports it)
    monkeypatch.setattr(bench.common, "sklearn_available", lambda: False)
    r = bench.run(("solver", "end2end", "batch", "accuracy"), quick=True)
    assert r["sklearn"] == bench.UNAVAILABLE
    assert r["sections"]["solver"]["sklearn"] == bench.UNAVAILABLE
    assert r["sections"]["end2end"]["ratio"] is None
    assert r["sections"]["batch"]["ratio_batch_vs_sklearn"] is None
    assert r["sections"]["accuracy"]["sklearn"] == bench.UNAVAILABLE
    assert "unavailable" in bench.format_table(r)


def test_bench_usage_errors(capsys):
    assert bench.cli(["--sections", "nope"]) == 2
    assert bench.cli(["--m", "2"]) == 2
    assert bench.cli(["--refine", "3"]) == 2
    assert bench.cli(["--resolution", "4"]) == 2
    assert bench.cli(["--sk-resolution", "1"]) == 2
    assert bench.cli(["--objects", "0"]) == 2
    assert bench.cli(["--help"]) == 0
    assert "--quick" in capsys.readouterr().out


def test_sklearn_mapping_objective():
    """The libsvm solution mapped into our scaling is feasible: sum a = 1, 0 <= a <= 1/(nu m)."""
    if not bench.sklearn_available():
        pytest.skip("scikit-learn is not installed")
    import numpy as np

    points, _ = bench.load_points(150)
    y = bench.prescale(points)[0]
    oc = bench.sk_fit(y, 47.0, 0.5)
    a = bench.sk_alpha(oc, len(y), 0.5)
    assert abs(a.sum() - 1.0) < 1e-9
    assert a.min() >= 0 and a.max() <= 1.0 / (0.5 * len(y)) * (1 + 1e-9)
    assert bench.dual_objective(y, a, 47.0) > 0
    np.testing.assert_allclose(bench.prescale(points)[0].mean(axis=0), 0, atol=1e-12)


def test_sk_resolution_reaches_the_sklearn_pipeline(monkeypatch):
    """--sk-resolution sets the scikit-learn pipeline's grid (the issue's text compares 64^3)."""
    if not bench.sklearn_available():
        pytest.skip("scikit-learn is not installed")
    _tiny(monkeypatch)
    r = bench.run(("end2end",), quick=True, sk_resolution=12)
    assert r["sections"]["end2end"]["sklearn"]["resolution"] == 12


def test_accuracy_section_objects(monkeypatch):
    """--objects reaches the accuracy section, which measures distinct objects (FAUST meshes, or
    samplings of the example shape with distinct seeds), and the table shows it."""
    _tiny(monkeypatch)
    monkeypatch.setattr(bench.common, "sklearn_available", lambda: False)
    r = bench.run(("accuracy",), quick=True, objects=3)
    acc = r["sections"]["accuracy"]
    assert acc["n_objects"] == 3 and len(set(acc["objects"])) == 3
    _check_errors(acc["jaxpose"], 3)
    assert "[accuracy]  3 objects" in bench.format_table(r)


def test_resolution_reaches_normalize(monkeypatch):
    """--resolution sets normalize's coarse grid in end2end and accuracy (default: normalize's, 64)."""
    _tiny(monkeypatch)
    monkeypatch.setattr(bench.common, "sklearn_available", lambda: False)
    r = bench.run(("end2end", "accuracy"), quick=True, resolution=12, objects=1)
    assert r["sections"]["end2end"]["jaxpose"]["resolution"] == 12
    assert r["sections"]["accuracy"]["resolution"] == 12
    monkeypatch.setitem(bench.QUICK, "resolution", None)
    from jaxpose.config import GridConfig

    r = bench.run(("end2end",), quick=True)
    assert r["sections"]["end2end"]["jaxpose"]["resolution"] == GridConfig().resolution == 64


def test_gradients_benchmark_verdict_and_table():
    """benchmarks/gradients.py: the 20 % / 1e-6 criterion and its markdown (no computation)."""
    from benchmarks import gradients as g

    fd = [1.0, 0.0, 0.0, 2.0]
    assert g.agrees([1.1, 0.0, 0.0, 2.2], fd)[0]
    assert not g.agrees([1.3, 0.0, 0.0, 2.0], fd)[0]
    assert g.agrees([1e-7, 0.0, 0.0, 2.0], [5e-7, 0.0, 0.0, 2.0])[0]  # within 1e-6 absolute
    cell = dict(ok=True, center=0.01, scale=0.02)
    row = dict(shape="s", gamma=20.0, nu=0.3, **{f"{m}_{p}_{e:g}": cell for m in ("trend", "exact")
                                                 for p in ("gamma", "nu") for e in g.STEPS})
    text = g.markdown({"accuracy": [row], "timing": [dict(shape="s", m=10, dtype="float32", seconds={"forward": 1.0},
                                                          ratio={"forward": 1.0})]})
    assert "| s (20, 0.3) |" in text and "trend, steps of 1%: 1 of 1 cases" in text and "1.00x forward" in text


def test_stop_rule_benchmark_table():
    """benchmarks/stop_rule.py: the acceptance line takes the worst cell (no computation)."""
    from benchmarks import stop_rule as s

    rows = [dict(shape="a", gamma=g, nu=n, iterations=10, iterations_tight=20, converged_tight=True,
                 center=2e-3 if (g, n) == (1.0, 0.0) else 1e-4, scale=1e-5) for n in s.NUS for g in s.GAMMAS]
    text = s.markdown({"minimum_ball": [dict(seed=0, solver="pg", iterations=5, converged=True, distance=1e-4)],
                       "tolerance": rows})
    assert "worst |difference| / scale: 2.00e-03" in text and "| a | 0 |" in text


def _voxel_solid(parts, pitch=0.05, lo=(-3.0, -1.2, -1.2), hi=(3.0, 1.2, 1.2)):
    """A Solid of the union of parts (functions of voxel centers (..., 3) -> bool), depth by the EDT."""
    from scipy import ndimage

    from jaxpose.solid import Solid

    axes = [np.arange(a + 0.5 * pitch, b, pitch) for a, b in zip(lo, hi)]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    inside = np.zeros(x.shape[:3], bool)
    for part in parts:
        inside |= part(x)
    depth = ndimage.distance_transform_edt(inside) * pitch
    return Solid(inside, depth, np.array(lo, float), pitch, None, np.eye(3), 1, 0)


def _ball(c, r):
    return lambda x: np.linalg.norm(x - np.array(c), axis=-1) <= r


def _rod(x0, x1, r):  # a cylinder along the first axis
    return lambda x: (x[..., 0] >= x0) & (x[..., 0] <= x1) & (np.hypot(x[..., 1], x[..., 2]) <= r)


def test_head_frame_merge_tree_of_a_dumbbell():
    """benchmarks/head_frame.py: two balls (radii 1.0, 0.7) joined by a rod (radius 0.3): the deepest
    maximum is born at 1.0 and never dies, the other is born at 0.7 and dies at the rod's 0.3
    (distance transform: within 1.5 voxels); nothing else persists beyond 2 voxels."""
    from benchmarks.head_frame import head_and_trunk, merge_tree

    pitch = 0.05
    sol = _voxel_solid([_ball((-1.2, 0, 0), 1.0), _ball((1.2, 0, 0), 0.7), _rod(-1.2, 1.2, 0.3)], pitch)
    tree = merge_tree(sol.inside, sol.depth)
    (b0, d0, p0, s0, j0), (b1, d1, p1, s1, j1) = tree[:2]
    assert abs(b0 - 1.0) < 1.5 * pitch and d0 == 0.0 and s0 == -1
    assert abs(b1 - 0.7) < 1.5 * pitch and abs(d1 - 0.3) < 1.5 * pitch and j0 == -1 and j1 == p0
    assert all(b - d < 2 * pitch for b, d, *_ in tree[2:])
    centers = sol.origin + pitch * (np.array(np.unravel_index([p0, p1, s1], sol.inside.shape)).T + 0.5)
    np.testing.assert_allclose(centers[0], [-1.2, 0, 0], atol=2 * pitch)
    np.testing.assert_allclose(centers[1], [1.2, 0, 0], atol=2 * pitch)
    assert -0.2 - pitch <= centers[2][0] <= 0.5 + pitch and np.hypot(*centers[2][1:]) < 2 * pitch  # in the rod
    trunk, head, neck, head_depth, constriction = head_and_trunk(sol)
    assert head_depth == b1 and constriction == b1 / d1
    np.testing.assert_allclose(neck, centers[2])
    hc = sol.origin + pitch * (np.stack(np.nonzero(head), 1) + 0.5)
    assert np.all(hc[:, 0] > 0.5 - pitch)  # the small ball's side of the rod


def test_head_frame_head_is_the_smaller_blob_even_when_deepest():
    """A child's head is as thick as its trunk: a ball (radius 0.9) on a thinner but longer trunk
    (a rod of radius 0.8 and length 3.2) is the deepest part, and still the head (the smaller blob)."""
    from benchmarks.head_frame import head_and_trunk

    sol = _voxel_solid([_rod(-2.8, 0.4, 0.8), _ball((1.7, 0, 0), 0.9), _rod(0.4, 1.7, 0.4)], 0.05,
                       lo=(-3.0, -1.0, -1.0), hi=(2.8, 1.0, 1.0))
    trunk, head, neck, head_depth, _ = head_and_trunk(sol)
    assert abs(head_depth - 0.9) < 0.075 and head.sum() < trunk.sum()
    hc = sol.origin + sol.pitch * (np.stack(np.nonzero(head), 1) + 0.5)
    np.testing.assert_allclose(hc.mean(axis=0), [1.7, 0, 0], atol=0.1)
    assert 0.4 <= neck[0] <= 1.0


def test_head_frame_neck_is_the_most_constricted_saddle():
    """A trunk of two balls (radius 1.0) joined at a waist (radius 0.6: persistence 0.4, birth / death
    1.7) carrying a head (radius 0.6) on a neck (radius 0.3: persistence 0.3, birth / death 2.0): the
    most persistent saddle is the waist, the most constricted the neck, and the head is found there."""
    from benchmarks.head_frame import head_and_trunk, merge_tree, neck

    pitch = 0.05
    sol = _voxel_solid([_ball((-2.2, 0, 0), 1.0), _ball((-0.2, 0, 0), 1.0), _rod(-2.2, -0.2, 0.6),
                        _ball((1.9, 0, 0), 0.6), _rod(0.7, 1.9, 0.3)], pitch, lo=(-3.4, -1.2, -1.2), hi=(2.7, 1.2, 1.2))
    tree = merge_tree(sol.inside, sol.depth)
    waist, chosen = tree[1], neck(tree)
    assert abs(waist[1] - 0.6) < 1.5 * pitch and abs(chosen[0] - 0.6) < 1.5 * pitch and abs(chosen[1] - 0.3) < 1.5 * pitch
    trunk, head, at, head_depth, _ = head_and_trunk(sol)
    hc = sol.origin + pitch * (np.stack(np.nonzero(head), 1) + 0.5)
    np.testing.assert_allclose(hc.mean(axis=0), [1.9, 0, 0], atol=0.1)
    assert 0.7 - pitch <= at[0] <= 1.4 and head.sum() < trunk.sum()
    with pytest.raises(ValueError, match="no saddle"):  # one ball: no neck
        neck(merge_tree(*_voxel_solid([_ball((0, 0, 0), 1.0)], 0.1)[:2]))
