"""Command line: normalize end to end, error handling, evaluate wiring, python -m jaxpose."""
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from jaxpose import baselines, cli, mesh
from jaxpose.config import OCSVM_ONLY

ROOT = Path(__file__).resolve().parents[1]


def digest(path):
    with open(path, "rb") as handle:
        return hashlib.sha256(handle.read()).hexdigest()


def shape():
    body = trimesh.creation.capsule(height=1.0, radius=0.5)
    arm = trimesh.creation.box(extents=(1.5, 0.2, 0.2))
    arm.apply_translation([1.2, 0.0, 0.3])
    out = trimesh.util.concatenate([body, arm])
    out.apply_translation([2.0, -1.0, 0.5])
    return out


def assert_clean_failure(code, capsys, fragment, expected=1):
    err = capsys.readouterr().err
    assert code == expected
    assert "Traceback" not in err
    errors = [line for line in err.splitlines() if line.startswith("jaxpose: error:")]
    assert len(errors) == 1 and err.splitlines()[-1] == errors[0], err
    assert fragment in errors[0], err


# --------------------------------------------------------------------------- normalize
@pytest.mark.parametrize("ext", ["obj", "ply", "off"])
def test_normalize_writes_mesh_and_transform(tmp_path, capsys, ext):
    source = tmp_path / f"in.{ext}"
    shape().export(source)
    before = digest(source)
    output = tmp_path / f"out.{ext}"
    code = cli.main(["normalize", str(source), "-o", str(output), "--method", "surface_centroid"])
    assert code == 0
    assert digest(source) == before  # input untouched
    printed = capsys.readouterr().out
    assert "center" in printed and "matrix" in printed

    record = json.loads((tmp_path / "out.transform.json").read_text())
    assert set(record) >= {"center", "scale", "matrix", "method", "input"} and "gamma" not in record  # not the OCSVM
    assert record["method"] == "surface_centroid" and record["input"] == str(source.resolve())
    original = mesh.load(source)
    normalized = mesh.load(output)
    matrix = np.array(record["matrix"])
    center = np.array(record["center"])
    np.testing.assert_allclose(matrix[:3, :3] @ center + matrix[:3, 3], 0.0, atol=1e-9)
    np.testing.assert_allclose(center, baselines.surface_centroid(original), rtol=1e-6)  # float32 pose
    np.testing.assert_allclose(baselines.surface_centroid(normalized), 0.0, atol=1e-5)
    assert baselines.mean_distance(normalized, np.zeros(3)) == pytest.approx(1.0, rel=1e-5)
    assert record["scale"] == pytest.approx(baselines.mean_distance(original), rel=1e-6)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([source.name, output.name, "out.transform.json"])


@pytest.mark.parametrize("method", ["vertex_mean", "bbox", "min_ball"])
def test_normalize_other_methods_and_transform_path(tmp_path, method):
    source = tmp_path / "in.ply"
    shape().export(source)
    transform = tmp_path / "t.json"
    code = cli.main(
        ["normalize", str(source), "-o", str(tmp_path / "out.stl"), "--method", method, "--transform", str(transform)]
    )
    assert code == 0
    record = json.loads(transform.read_text())
    assert record["method"] == method
    assert not set(OCSVM_ONLY) & set(record), record  # the OCSVM's options are not this method's: not recorded
    assert not (tmp_path / "out.transform.json").exists()


def test_normalize_example(tmp_path, capsys):
    output = tmp_path / "example.ply"
    assert cli.main(["normalize", "--example", "-o", str(output), "--method", "surface_centroid"]) == 0
    assert output.exists() and (tmp_path / "example.transform.json").exists()
    assert json.loads((tmp_path / "example.transform.json").read_text())["input"] == "example"
    # without -o only the transform is printed
    assert cli.main(["normalize", "example", "--method", "min_ball"]) == 0
    assert "scale" in capsys.readouterr().out


def test_existing_output_needs_force(tmp_path, capsys):
    source = tmp_path / "in.obj"
    shape().export(source)
    output = tmp_path / "out.obj"
    output.write_text("keep")
    args = ["normalize", str(source), "-o", str(output), "--method", "surface_centroid"]
    assert_clean_failure(cli.main(args), capsys, "exists", expected=2)  # usage: --force is the way out
    assert output.read_text() == "keep"
    assert not (tmp_path / "out.transform.json").exists()
    assert cli.main(args + ["--force"]) == 0
    assert isinstance(mesh.load(output), trimesh.Trimesh)


def test_existing_transform_needs_force(tmp_path, capsys):
    source = tmp_path / "in.obj"
    shape().export(source)
    (tmp_path / "out.transform.json").write_text("{}")
    code = cli.main(["normalize", str(source), "-o", str(tmp_path / "out.ply"), "--method", "bbox"])
    assert_clean_failure(code, capsys, "exists", expected=2)
    assert not (tmp_path / "out.ply").exists()


def test_normalize_names_a_truncated_or_malformed_file(tmp_path, capsys):
    """A binary PLY cut short and an OFF with a malformed counts line: the one error line names the
    file, says what is wrong and what was expected ("PLY is unexpected length!", "invalid literal
    for int() with base 10: 'x'" before); nothing is written."""
    data = trimesh.creation.icosphere(subdivisions=0).export(file_type="ply")
    body = trimesh.creation.icosphere(subdivisions=0).export(file_type="off").split("\n", 2)[2]
    cut = tmp_path / "cut.ply"
    cut.write_bytes(data[:-10])
    counts = tmp_path / "counts.off"
    counts.write_text("OFF\n3 x 0\n" + body)
    # (12 vertices of 12 bytes, 20 faces of 13: 404 bytes; 10 cut, the last face's)
    for source, fragment in ((cut, f"{cut}: cannot read PLY file: truncated, {len(data) - 10 - data.index(b'end_header') - 11} "
                                   "bytes after the header end inside its face 20 of 20 (its 12 vertex, 20 face elements"),
                             (counts, f"{counts}: cannot read OFF file: its counts line '3 x 0' is not 'vertices faces "
                                      "[edges]' as whole numbers")):
        code = cli.main(["normalize", str(source), "-o", str(tmp_path / "out.ply")])
        assert_clean_failure(code, capsys, fragment)
        assert not (tmp_path / "out.ply").exists()


@pytest.mark.parametrize("source, output, fragment, expected", [
    ("missing.ply", "out", "no such file: {tmp}/missing.ply", 1),       # was: "out: no extension ..." (exit 2)
    ("missing.ply", "out.ply", "no such file: {tmp}/missing.ply", 1),
    ("in.ply", "out", "out: no extension to choose an output format", 2),
])
def test_normalize_names_a_missing_input_before_the_output(tmp_path, capsys, source, output, fragment, expected):
    """A missing INPUT is named first, whatever -o says (as it is with a good -o); an existing INPUT
    with a bad -o is a usage error (exit 2) naming -o."""
    trimesh.creation.icosphere(subdivisions=0).export(tmp_path / "in.ply")
    code = cli.main(["normalize", str(tmp_path / source), "-o", str(tmp_path / output)])
    assert_clean_failure(code, capsys, fragment.format(tmp=tmp_path), expected=expected)
    assert not (tmp_path / output).exists()


@pytest.mark.parametrize(
    "name, content, extra, fragment",
    [
        ("missing.obj", None, [], "no such file"),
        ("corrupt.ply", b"ply\nformat nonsense\n\x00\x01", [], "cannot read"),
        ("corrupt.off", b"OFF\n3 1 0\n0 0\n", [], "cannot read"),
        ("empty.obj", b"", [], "empty geometry"),
        ("shape.abc", b"1 2 3", [], "unsupported format"),
    ],
)
def test_normalize_errors(tmp_path, capsys, name, content, extra, fragment):
    source = tmp_path / name
    if content == "mesh":
        shape().export(source)
    elif content is not None:
        source.write_bytes(content)
    before = digest(source) if source.exists() else None
    code = cli.main(["normalize", str(source), "-o", str(tmp_path / "out.ply")] + extra)
    assert_clean_failure(code, capsys, fragment)
    assert not (tmp_path / "out.ply").exists()
    if before is not None:
        assert digest(source) == before


@pytest.mark.parametrize(
    "args",
    [
        [],
        ["normalize", "in.obj", "--gamma", "abc"],
        ["normalize", "in.obj", "--method", "ocsvm", "--gamma", "-1"],  # values out of range: usage (README)
        ["normalize", "in.obj", "--method", "ocsvm", "--nu", "2"],
        ["normalize", "in.obj", "--method", "ocsvm", "--count", "2"],
        ["normalize", "in.obj", "--gamma", "30"],  # an option the default (robust) method ignores
        ["normalize", "in.obj", "--method", "centroid"],
        ["normalize"],
        ["frobnicate"],
    ],
)
def test_usage_errors_exit_2(args, capsys):
    with pytest.raises(SystemExit) as info:
        code = cli.main(args)
        raise SystemExit(code)
    assert info.value.code == 2
    assert "Traceback" not in capsys.readouterr().err


@pytest.mark.parametrize("method", [None, "ocsvm"])
def test_normalize_default_and_ocsvm(tmp_path, method):
    source = tmp_path / "in.off"
    shape().export(source)
    output = tmp_path / "out.off"
    extra = ["--method", method] if method else []
    # the robust default takes no OCSVM options; 400 samples (incidental): the OCSVM pose at 448
    # rows on the default grid, test_pinned.py's float32 program (500 compiled one of its own)
    extra += ["--count", "400"] if method == "ocsvm" else []
    assert cli.main(["normalize", str(source), "-o", str(output), *extra]) == 0
    record = json.loads((tmp_path / "out.transform.json").read_text())
    assert record["method"] == (method or "robust")
    ocsvm = {"gamma": 47.0, "nu": 0.5, "count": 400, "seed": 0, "sampling": "even"}  # only where it runs
    assert {k: record[k] for k in OCSVM_ONLY if k in record} == (ocsvm if method else {})
    names = ("ocsvm", "ocsvm") if method else ("robust_depth", "robust_volume")
    assert (record["center_method"], record["scale_method"]) == names
    matrix = np.array(record["matrix"])
    np.testing.assert_allclose(matrix[:3, :3] @ np.array(record["center"]) + matrix[:3, 3], 0.0, atol=1e-6)
    expected = mesh.load(source).vertices @ matrix[:3, :3].T + matrix[:3, 3]
    np.testing.assert_allclose(mesh.load(output).vertices, expected, atol=1e-5)


# --------------------------------------------------------------------------- evaluate
@pytest.fixture
def fake_evaluation(monkeypatch):
    from jaxpose import datasets, evaluation

    calls = {}

    def evaluate(classes, **kwargs):
        calls["classes"], calls["kwargs"] = classes, kwargs
        kwargs["progress"](0, 1, "working")
        kwargs["progress"](1, 1, "done")
        return {"summary": [{"method": "ocsvm", "sigma_tr": 0.1}], "params": {"gamma": kwargs.get("gamma")}}

    monkeypatch.setattr(evaluation, "evaluate", evaluate)
    monkeypatch.setattr(evaluation, "format_table", lambda result: "TABLE")
    monkeypatch.setattr(evaluation, "format_per_class", lambda result: "PER CLASS")
    monkeypatch.setattr(datasets, "make_dataset", lambda seed=0, **kw: {"made": seed, **kw})
    monkeypatch.setattr(datasets, "load_folder", lambda path, classes=None: {"folder": str(path), "classes": classes})
    return calls


def test_evaluate_wiring(tmp_path, capsys, fake_evaluation):
    out = tmp_path / "result.json"
    code = cli.main(["evaluate", "--gamma", "30", "--nu", "0.2", "--seed", "3", "--align-core", "--json", str(out)])
    assert code == 0
    captured = capsys.readouterr()
    assert "TABLE" in captured.out and "PER CLASS" not in captured.out
    assert fake_evaluation["classes"] == {"made": 3, "instances": 10, "classes": None}
    kwargs = fake_evaluation["kwargs"]
    assert (kwargs["gamma"], kwargs["nu"], kwargs["seed"], kwargs["align_core"], kwargs["sweep"]) == (
        30.0, 0.2, 3, True, False)
    assert kwargs["variants"] == ["plain", "outliers", "big_outliers", "points", "holes"]  # all, as the README shows
    assert kwargs["methods"] is None
    assert kwargs["core_weight"] == "vertices"  # the stable core as a share of the vertices unless told
    assert json.loads(out.read_text())["params"] == {"gamma": 30.0}
    assert_clean_failure(cli.main(["evaluate", "--json", str(out)]), capsys, "exists", expected=2)
    assert cli.main(["evaluate", "--data", str(tmp_path), "--sweep", "--json", str(out), "--force",
                     "--variants", "plain,holes", "--methods", "robust,depth_weighted_solid:4"]) == 0
    assert fake_evaluation["classes"] == {"folder": str(tmp_path), "classes": None}
    assert fake_evaluation["kwargs"]["variants"] == ["plain", "holes"]
    assert fake_evaluation["kwargs"]["methods"] == ["robust", "depth_weighted_solid:4"]
    assert fake_evaluation["kwargs"]["sweep"] is True
    assert cli.main(["evaluate", "--per-class"]) == 0
    assert "TABLE" in (printed := capsys.readouterr().out) and "PER CLASS" in printed
    assert cli.main(["evaluate", "--align-core", "--core-weight", "area"]) == 0
    assert fake_evaluation["kwargs"]["core_weight"] == "area"
    capsys.readouterr()
    assert cli.main(["evaluate", "--core-weight", "area"]) == 2  # it says how --align-core chooses; alone it is refused
    err = capsys.readouterr().err
    assert "add --align-core" in err and "Traceback" not in err, err
    for bad, unknown in (("bogus", "['bogus']"), ("core,Head", "['Head']"), (",", None), ("", None)):
        # a usage error before the dataset is made (exit 1 from the evaluation, after making it; '' ran the
        # center/scale evaluation instead)
        fake_evaluation.clear()
        assert cli.main(["evaluate", "--rotation", bad]) == 2
        err = capsys.readouterr().err
        assert (f"--rotation: unknown rotation methods {unknown}; valid: all, core, head" if unknown else
                f"--rotation names no rotation method ({bad!r}); give some, comma-separated, or all") in err, err
        assert "classes" not in fake_evaluation


def test_evaluate_plots(tmp_path, capsys, fake_evaluation, monkeypatch):
    try:
        from jaxpose import plot
    except ImportError:
        monkeypatch.setitem(sys.modules, "jaxpose.plot", None)  # import fails
        assert_clean_failure(cli.main(["evaluate", "--plots", str(tmp_path)]), capsys, "plots not available")
        return
    seen = {}
    monkeypatch.setattr(plot, "evaluation_figures", lambda result, folder: seen.setdefault("folder", folder))
    assert cli.main(["evaluate", "--plots", str(tmp_path)]) == 0
    assert seen["folder"] == str(tmp_path)


def test_plots_are_written(tmp_path, capsys, fake_evaluation, monkeypatch):
    import jaxpose.plot

    seen = []
    monkeypatch.setattr(jaxpose.plot, "evaluation_figures", lambda result, out: seen.append(out) or [])
    assert cli.main(["evaluate", "--plots", str(tmp_path)]) == 0
    assert seen == [str(tmp_path)]


# --------------------------------------------------------------------------- tune / bench
@pytest.mark.parametrize("command", ["tune", "bench"])
def test_tune_and_bench_delegate(command, monkeypatch):
    """Every argument after the command name reaches the command's entry point (argv -> exit status):
    :func:`jaxpose.cli.tune.run`, and ``benchmarks.cli`` of the source checkout."""
    import types

    from jaxpose.cli import tune

    seen = []
    fake = lambda argv: seen.append(argv) or 0  # noqa: E731
    if command == "tune":
        monkeypatch.setattr(tune, "run", fake)
    else:
        module = types.ModuleType("benchmarks")
        module.cli = fake
        monkeypatch.setitem(sys.modules, "benchmarks", module)
    assert cli.main([command, "--quick", "--json", "x.json"]) == 0
    assert seen == [["--quick", "--json", "x.json"]]


def test_version(capsys):
    """`jaxpose --version` prints the package's version (jaxpose.__version__, the installed
    metadata's and pyproject.toml's) on stdout and exits 0, as --help does."""
    import importlib.metadata
    import tomllib

    import jaxpose

    with pytest.raises(SystemExit) as exit_:
        cli.main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out == f"jaxpose {jaxpose.__version__}\n"
    assert jaxpose.__version__ == tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert jaxpose.__version__ == importlib.metadata.version("jaxpose")


# --------------------------------------------------------------------------- python -m jaxpose
def test_python_m_jaxpose(tmp_path):
    missing = tmp_path / "nope.obj"
    run = subprocess.run(
        [sys.executable, "-m", "jaxpose", "normalize", str(missing), "-o", str(tmp_path / "out.ply")],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert run.returncode == 1
    assert "Traceback" not in run.stderr and "no such file" in run.stderr
    help_run = subprocess.run([sys.executable, "-m", "jaxpose", "--help"], capture_output=True, text=True, cwd=ROOT)
    assert help_run.returncode == 0 and "normalize" in help_run.stdout and "evaluate" in help_run.stdout


def test_python_m_jaxpose_normalize(tmp_path):
    source = tmp_path / "in.ply"
    shape().export(source)
    before = digest(source)
    run = subprocess.run(
        [sys.executable, "-m", "jaxpose", "normalize", str(source), "-o", str(tmp_path / "o.ply"),
         "--method", "surface_centroid"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "o.ply").exists() and (tmp_path / "o.transform.json").exists()
    assert digest(source) == before


def test_ocsvm_runs_under_python_w_error(tmp_path):
    """``python -W error -m jaxpose normalize ... --method ocsvm``: jaxopt's notice that it is no
    longer maintained (a DeprecationWarning on its import) was raised there, a traceback and exit
    1. The one module that imports jaxopt leaves that notice out, and only it: another warning
    jaxopt's import gives still reaches the caller's filters (a stand-in jaxopt giving both)."""
    source = tmp_path / "in.ply"
    shape().export(source)
    run = subprocess.run(
        [sys.executable, "-W", "error", "-m", "jaxpose", "normalize", str(source), "-o", str(tmp_path / "o.ply"),
         "--method", "ocsvm"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    assert (tmp_path / "o.ply").exists()
    fake = tmp_path / "fake" / "jaxopt"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text(
        "import warnings\n"
        "warnings.warn('JAXopt is no longer maintained. See elsewhere.', DeprecationWarning)\n"
        "warnings.warn('another notice', DeprecationWarning)\n")
    code = ("import warnings\n"
            "from jaxpose.occupancy.svdd import pg\n"
            "with warnings.catch_warnings(record=True) as seen:\n"
            "    warnings.simplefilter('always')\n"
            "    pg._jaxopt()\n"
            "print(sorted(str(w.message) for w in seen))\n")
    import os

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "fake"), str(ROOT)])}
    seen = subprocess.run([sys.executable, "-W", "error", "-c", code], capture_output=True, text=True, cwd=ROOT,
                          env=env, timeout=120)
    assert seen.returncode == 0 and seen.stdout.strip() == "['another notice']", seen.stdout + seen.stderr


def test_the_test_runs_filters_hide_jaxopts_archive_notice_and_no_other_deprecation():
    """pyproject's pytest filterwarnings ignores jaxopt's notice that it is no longer maintained,
    and only it (``error`` for the rest): they ignored every DeprecationWarning raised in a jaxopt
    module or naming jaxopt, so a deprecation of a jaxopt API jaxpose calls would never show. A
    real one here: jaxopt.LBFGS's ``condition`` argument."""
    import warnings

    from jaxpose.occupancy.svdd import pg

    jaxopt = pg._jaxopt()
    with pytest.raises(DeprecationWarning, match="Argument condition is deprecated"):
        jaxopt.LBFGS(fun=lambda x: x @ x, condition="armijo")
    with pytest.raises(DeprecationWarning, match="jaxopt"):
        warnings.warn("jaxopt.ProjectedGradient's old argument is deprecated", DeprecationWarning)
    warnings.warn("JAXopt is no longer maintained. See https://docs.jax.dev/en/latest/ for alternatives.",
                  DeprecationWarning)  # the notice: ignored (the test fails if it raises)


# --------------------------------------------------------------------------- far from the origin, files, limits
def test_cli_translation_is_exact_at_1e9(tmp_path):
    """``jaxpose normalize`` (a real subprocess, the robust default) on a closed mesh written at 1e9
    (an OBJ: trimesh writes PLY vertices in float32): the transform's center is the un-offset file's plus the offset, to 1e-6 of the
    scale plus the float spacing at 1e9; the same scale to 1e-6; the output mesh at the origin."""
    o = 1e9 * np.array([1.0, -0.7, 0.3])
    body = trimesh.creation.capsule(height=1.0, radius=0.5, count=[12, 12])
    far = trimesh.Trimesh(body.vertices + o, body.faces, process=False)
    source = tmp_path / "far.obj"
    far.export(source)
    vertices = mesh.load(source).vertices  # what the file holds (merged, as the CLI reads it)
    assert len(vertices) == len(body.vertices) and np.max(np.abs(vertices - o - body.vertices)) < 1e-6
    run = subprocess.run([sys.executable, "-m", "jaxpose", "normalize", str(source), "-o", str(tmp_path / "out.ply")],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert run.returncode == 0, run.stderr
    record = json.loads((tmp_path / "out.transform.json").read_text())
    near = trimesh.Trimesh(vertices - o, mesh.load(source).faces, process=False)  # exact: fl(v + o) - o
    _, p0 = mesh.normalize_mesh(near)
    c0, s0 = np.asarray(p0.center), float(p0.scale)
    assert np.max(np.abs(np.array(record["center"]) - o - c0)) <= 1e-6 * s0 + np.spacing(1e9)
    assert record["scale"] == pytest.approx(s0, rel=1e-6)
    normalized = mesh.load(tmp_path / "out.ply").vertices
    np.testing.assert_allclose(normalized, (vertices - o - c0) / s0, atol=1e-5)  # float32 output file


def test_cli_reads_latin1_text_and_names_mismatched_content(tmp_path, capsys):
    tetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    (tmp_path / "latin1.obj").write_bytes(("# modèle créé\n" + tetra).encode("latin-1"))
    assert cli.main(["normalize", str(tmp_path / "latin1.obj"), "--method", "surface_centroid"]) == 0
    capsys.readouterr()
    (tmp_path / "body.obj").write_bytes(trimesh.creation.icosphere(subdivisions=1).export(file_type="ply"))
    assert_clean_failure(cli.main(["normalize", str(tmp_path / "body.obj")]), capsys,
                         "the content is PLY, not OBJ: rename it to .ply")


@pytest.mark.parametrize("method, limit", [("robust", 291), ("ocsvm", 281)])
def test_cli_refuses_a_grid_beyond_the_memory_budget(tmp_path, capsys, method, limit):
    source = tmp_path / "in.ply"
    shape().export(source)
    code = cli.main(["normalize", str(source), "-o", str(tmp_path / "o.ply"), "--method", method,
                     "--resolution", "1000"])
    err = capsys.readouterr().err  # a value out of range: a usage error (exit 2), before any work
    assert code == 2 and f"use a resolution in [8, {limit}]" in err and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.ply"]
