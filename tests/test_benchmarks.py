"""benchmarks/ (``jaxpose bench``): runs in quick mode on tiny sizes and writes the JSON schema. No timing assertions."""
import json

import pytest

import benchmarks as bench
from jaxpose import cli

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def _tiny(monkeypatch):
    # m = batch_m = scaling_m = 80 (incidental): end2end's and accuracy's normalize, the solver
    # section's and the reference's fits run at the 80 rows of the batch section's loop and the
    # scaling section's (at 120 they compiled programs of their own)
    monkeypatch.setitem(bench.QUICK, "m", 80)
    monkeypatch.setitem(bench.QUICK, "repeats", 1)
    # one object (incidental: the section's schema and its three timed cases are checked, not a
    # batch size): normalize_batch's "map" cuts a batch into one lax.map chain per core, each one more
    # copy of the pipeline to compile (two objects on two cores: two copies)
    monkeypatch.setitem(bench.QUICK, "batch_objects", 1)
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
        for v in acc["sklearn"].values():  # an 8^3 grid may hold no point of a region (the example shape's)
            _check_errors(v, 2, empty_allowed=True)
    else:
        assert r["sklearn"] == bench.UNAVAILABLE
        assert solver["sklearn"] == bench.UNAVAILABLE and solver["ratio"] is None
        assert end["sklearn"] == bench.UNAVAILABLE
        assert batch["sklearn_loop"] == bench.UNAVAILABLE
        assert acc["sklearn"] == bench.UNAVAILABLE


def _check_errors(v, n, empty_allowed=False):
    """The accuracy section's summary is that of its per-object errors; an object whose region held
    no grid point (the scikit-learn indicator on a coarse grid) is null in both lists and counted."""
    import numpy as np

    assert len(v["center_err"]) == len(v["scale_err_rel"]) == n
    nulls = [e is None for e in v["center_err"]]
    assert nulls == [e is None for e in v["scale_err_rel"]] and v["empty"] == sum(nulls)
    assert empty_allowed or v["empty"] == 0
    err = np.array([e for e in v["center_err"] if e is not None], np.float64)
    sc = np.array([e for e in v["scale_err_rel"] if e is not None], np.float64)
    assert np.all(np.isfinite(err)) and np.all(err >= 0) and np.all(np.isfinite(sc)) and np.all(sc >= 0)
    if len(err):
        assert v["median"] == np.median(err) and v["max"] == err.max()
        assert v["scale_median"] == np.median(sc) and v["scale_max"] == sc.max()
    else:
        assert v["median"] is v["max"] is v["scale_median"] is v["scale_max"] is None
    assert v["within_bar"] == int(np.sum(err <= bench.sections.ACCURACY_BAR))


def test_bench_quick_json(tmp_path, monkeypatch, capsys):
    _tiny(monkeypatch)
    out = tmp_path / "bench.json"
    code = cli.main(["bench", "--quick", "--json", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "[solver]" in text and "[end2end]" in text and "[accuracy]" in text and "ratio" in text
    r = json.loads(out.read_text(), parse_constant=lambda token: pytest.fail(f"not JSON: {token}"))  # strict
    _check_schema(r, sk=bench.sklearn_available())
    # refuses to overwrite
    assert bench.cli(["--quick", "--sections", "solver", "--json", str(out)]) == 2  # usage, before the work


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
    capsys.readouterr()
    for argv, message in ((["--repeats", "-1"], "--repeats must be >= 0 (0: one cold run each), got -1"),
                          (["--resolutions", "x"], "--resolutions must be a comma list of ints, got 'x'"),  # ValueError
                          (["--scaling-m", "500,x"], "--scaling-m must be a comma list of ints"),
                          (["--resolutions", "32,4"], "--resolutions must list ints >= 8"),
                          (["--tol", "-1"], "--tol must be finite and > 0, got -1.0"),  # after the start, exit 1
                          (["--solver-tol", "nan"], "--solver-tol must be finite and > 0"),
                          (["--scaling-max-iter", "0"], "--scaling-max-iter must be >= 1")):
        assert bench.cli(argv) == 2, argv
        err = capsys.readouterr().err
        assert message in err and "jaxpose bench: solver" not in err, err
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
    # the argument (8) over the quick preset's (12): the argument is _tiny's own grid, so the
    # programs are those test_bench_quick_json compiles (a grid of its own compiled two more)
    monkeypatch.setitem(bench.QUICK, "resolution", 12)
    monkeypatch.setattr(bench.common, "sklearn_available", lambda: False)
    r = bench.run(("end2end", "accuracy"), quick=True, resolution=8, objects=1)
    assert r["sections"]["end2end"]["jaxpose"]["resolution"] == 8
    assert r["sections"]["accuracy"]["resolution"] == 8
    monkeypatch.setitem(bench.QUICK, "resolution", None)
    from jaxpose.config import GridConfig

    # 400 points (incidental): normalize's default grid is then test_pinned.py's float32
    # program (448 rows), and the reference's fit its solver program
    r = bench.run(("end2end",), quick=True, m=400)
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



def test_robust_speed_benchmark_runs_on_the_example_shape():
    """benchmarks/robust_speed.py: one warm run on the built-in shape; the JAX and frozen NumPy
    paths agree and the power derivative is finite (no timing assertion)."""
    import numpy as np

    from benchmarks import robust_speed as r

    result = r.run([("example_shape", None)], repeats=1)
    speed, grad = result["speed"][0], result["gradients"][0]
    assert speed["center_diff_rel"] < 1e-6 and speed["scale_diff_rel"] < 1e-12
    assert speed["stats"]["jax"]["runs_s"] and speed["ratio"] > 0
    assert grad["finite"] and grad["center_rel_err"] < 0.1 and grad["grad_scale"] == 0.0
    assert np.linalg.norm(grad["fd_center"]) > 0
    text = r.markdown(result)
    assert "| example_shape |" in text and "d center / dp" in text


def test_help_names_the_quick_presets_defaults():
    """Each option whose preset --quick changes names both defaults in its help (--m said
    "default 2000" and --quick ran 300; --resolution "normalize's, 64" and ran 16; --resolutions,
    --scaling-m and --objects likewise), from the presets themselves."""
    from benchmarks import report

    actions = {a.option_strings[0]: a.help for a in report._parser()._actions if a.option_strings}
    listed = lambda v: ",".join(map(str, v)) if isinstance(v, tuple) else str(v)
    preset = {"--m": "m", "--repeats": "repeats", "--scaling-m": "scaling_m", "--resolutions": "resolutions",
              "--resolution": "resolution", "--sk-resolution": "sk_resolution", "--objects": "accuracy_objects"}
    for option, key in preset.items():
        full, quick = report.FULL[key], report.QUICK[key]
        assert f"quick {listed(quick)}" in actions[option], (option, actions[option])
        assert full is None or f"default {listed(full)}" in actions[option], (option, actions[option])
    assert set(report.FULL) == set(report.QUICK)
