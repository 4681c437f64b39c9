"""Command-line habits a new user meets (issue 37.4, 36.2, 36.3): options a method ignores are
refused naming the method they belong to, outputs are checked before any work, folders are made
for single outputs as for datasets, exit codes follow the README (2 usage), a closed pipe ends
quietly, the help describes every option."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from jaxpose import cli

ROOT = Path(__file__).resolve().parents[1]


def _err(capsys):
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    return err


@pytest.fixture
def box(tmp_path):
    path = tmp_path / "box.ply"
    trimesh.creation.box(extents=(1.0, 0.6, 0.3)).export(path)
    return path


@pytest.mark.parametrize("extra,named", [(["--count", "5"], "--count"), (["--gamma", "3", "--nu", "0.2"], "--gamma, --nu"),
                                         (["--sampling", "random"], "--sampling"), (["--strict"], "--strict")])
def test_options_the_method_ignores_are_refused(tmp_path, box, capsys, extra, named):
    out = tmp_path / "out.ply"
    assert cli.main(["normalize", str(box), "-o", str(out), *extra]) == 2
    err = _err(capsys)
    assert named in err and "robust" in err and ("ocsvm" in err or "closed-surface" in err), err
    assert not out.exists()


def test_ocsvm_options_with_the_ocsvm_method_and_ocsvm_frame_are_taken(tmp_path, box, capsys):
    out = tmp_path / "out.ply"
    code = cli.main(["normalize", str(box), "-o", str(out), "--method", "ocsvm", "--count", "300", "--gamma", "20"])
    assert code == 0, _err(capsys)
    assert cli.main(["normalize", str(box), "-o", str(tmp_path / "s.ply"), "--method", "surface_centroid",
                     "--count", "300"]) == 2
    assert "surface_centroid" in _err(capsys)


def test_a_mesh_file_name_for_many_inputs_is_refused(tmp_path, box, capsys):
    folder = tmp_path / "scans"
    folder.mkdir()
    box.rename(folder / "box.ply")
    assert cli.main(["normalize", str(folder), "-o", str(tmp_path / "x.ply")]) == 2
    assert "OUTDIR" in _err(capsys)
    assert not (tmp_path / "x.ply").exists()


def test_single_output_folders_are_made_as_for_datasets(tmp_path, box, capsys):
    out = tmp_path / "new" / "deeper" / "out.ply"
    assert cli.main(["normalize", str(box), "-o", str(out), "--method", "surface_centroid"]) == 0, _err(capsys)
    assert out.exists() and (out.parent / "out.transform.json").exists()
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert cli.main(["normalize", str(box), "-o", str(blocker / "out.ply"), "--method", "surface_centroid"]) == 2
    assert "is a file" in _err(capsys)  # an output path that cannot be used: a usage error, as README says
    # a folder on the way that is a link to nothing, or to a file: refused before the work (the first was
    # read and normalized, then failed writing: exit 1, 'FileExistsError')
    (tmp_path / "dangling").symlink_to(tmp_path / "missing")
    (tmp_path / "to_file").symlink_to(blocker)
    for link, says in (("dangling", "is a symbolic link to a missing folder"), ("to_file", "is a symbolic link to a file")):
        assert cli.main(["normalize", str(box), "-o", str(tmp_path / link / "sub" / "out.ply"), "--method",
                         "surface_centroid"]) == 2
        assert f"-o {tmp_path / link / 'sub' / 'out.ply'}: {tmp_path / link} {says}" in _err(capsys)


@pytest.mark.parametrize("args, fragment", [
    (["--workers", "0"], "workers must be >= 1"),
    (["--dask-local", "0"], "dask_local must be >= 1"),
    (["--timeout", "-1"], "timeout (seconds) must be a finite number > 0"),
    (["--timeout", "nan"], "timeout (seconds) must be a finite number > 0"),
    (["--shard", "3/2"], "shard must have 0 <= index < count"),
])
def test_many_files_bad_values_are_usage_errors(tmp_path, capsys, args, fragment):
    """A dataset run's values out of range exit 2 (usage: a bad value), as malformed ones do; they
    were failures (exit 1) found by the run. Nothing is made."""
    folder = tmp_path / "scans"
    folder.mkdir()
    out = tmp_path / "normalized"
    with pytest.raises(SystemExit) as info:  # argparse's usage error, as for a malformed value
        cli.main(["normalize", str(folder), "-o", str(out), *args])
    assert info.value.code == 2, args
    assert fragment in _err(capsys)
    assert not out.exists()


def test_dask_without_dask_is_refused_before_any_work(tmp_path, box, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    folder = tmp_path / "scans"
    folder.mkdir()
    box.rename(folder / "box.ply")
    out = tmp_path / "normalized"
    assert cli.main(["normalize", str(folder), "-o", str(out), "--dask-local", "2"]) == 1
    assert "jaxpose[dask]" in _err(capsys)
    assert not out.exists()  # no table, no .jaxpose/


def test_flat_mesh_error_names_the_command_line_flag(tmp_path, capsys):
    flat = tmp_path / "flat.ply"
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]]).export(flat)
    assert cli.main(["normalize", str(flat), "-o", str(tmp_path / "out.ply")]) == 1
    assert "--method surface_centroid" in _err(capsys)


# --------------------------------------------------------------------------- evaluate
@pytest.fixture
def no_work(monkeypatch):
    """evaluation.evaluate that fails the test if reached: a refusal must come before the work."""
    from jaxpose import evaluation

    monkeypatch.setattr(evaluation, "evaluate", lambda *a, **k: pytest.fail("the work started"))
    monkeypatch.setattr(evaluation, "evaluate_rotation", lambda *a, **k: pytest.fail("the work started"))


@pytest.mark.parametrize("args, fragment", [
    (["--methods", "robust,surface_centroid", "--gamma", "30"], "--gamma applies to the ocsvm method"),
    (["--methods", "robust", "--count", "100", "--nu", "0.2"], "--nu, --count apply to the ocsvm method"),
    (["--gamma", "-1"], "gamma must be a finite number > 0"),
    (["--variants", "plain,wobbly"], "unknown variants"),
    (["--methods", "median"], "unknown method"),
    (["--classes", "unicorn"], "unknown class"),
    (["--methods", "robust:-1"], "the power after ':' must be a finite number >= 0"),  # were rows of n/a
    (["--methods", "robust:nan"], "the power after ':' must be a finite number >= 0"),
    (["--methods", "vertex_mean:2"], "vertex_mean takes no power"),  # was the vertex mean, labelled :2
    (["--instances", "1"], "--instances must be >= 2"),  # was exit 1 after making the dataset
    # was a dataset built in memory without a word (3.9 GB in 15 s, one class), never reaching the work
    (["--instances", "1000000000"], "--instances must be <= 200 (the built-in dataset is built in memory"),
    (["--classes", ","], "--classes names no class"),  # was exit 1 naming the library's dict argument
    (["--methods", ""], "--methods names no method (''); give some, comma-separated, or all"),  # ran every method
    # the frames' run reads neither: it measured the frames and dropped them without a word
    (["--rotation", "pca_vertices", "--methods", "bbox"], "--methods chooses what the center and scale run measures"),
    (["--rotation", "--sweep"], "--sweep chooses what the center and scale run measures"),
    (["--rotation", "head", "--methods", "robust", "--sweep"], "--methods and --sweep choose"),
    # the sweep sets gamma and nu itself: they were taken and never read
    # ... and so the hint for them is not --sweep (it sent the user to a second refusal)
    (["--methods", "vertex_mean", "--gamma", "47"], "which this evaluation does not run (add ocsvm to --methods, or "
                                                    "leave it out)"),
    (["--methods", "vertex_mean", "--count", "300"], "(add ocsvm to --methods or --sweep, or leave it out)"),
    (["--methods", "robust", "--sweep", "--gamma", "30", "--nu", "0.2"],
     "--gamma, --nu apply to the ocsvm method (the paper's), which this evaluation does not run, and --sweep sets "
     "gamma and nu itself (add ocsvm to --methods, or leave them out)"),
    # a name given twice: it ran twice, two rows and a 0.0 ms/object, or a class's frames counted twice
    (["--methods", "robust,bbox,robust"], "methods names 'robust' twice"),
    (["--methods", "depth_weighted_solid:2,depth_weighted_solid:2.0"], "names 'depth_weighted_solid:2.0' twice "
                                                                        "(as 'depth_weighted_solid:2'"),
    # the default power spelled out: one estimator run twice under two names
    (["--methods", "robust,robust:4"], "methods names 'robust:4' twice (as 'robust'; both are robust at power 4)"),
    (["--variants", "plain,holes,plain"], "variants names 'plain' twice"),
    (["--rotation", "head,pca_vertices,head"], "--rotation names 'head' twice"),
    (["--classes", "human, chair,human"], "--classes names 'human' twice"),  # (was one class, silently)
])
def test_evaluate_usage_errors_exit_2_before_the_work(capsys, no_work, args, fragment):
    assert cli.main(["evaluate", *args]) == 2
    assert fragment in _err(capsys)


def test_evaluate_method_lists_may_carry_spaces(capsys, monkeypatch):
    """``--methods "bbox, vertex_mean"`` and ``--rotation "head, core"`` as ``--variants "plain,
    holes"`` (they were unknown methods ' vertex_mean', ' core', exit 2); ``--methods all`` as
    ``--variants all``."""
    from jaxpose import evaluation
    from jaxpose.errors import JaxposeError

    seen = []

    def stop(classes, **kw):
        seen.append(kw["methods"])
        raise JaxposeError("stop: the methods are what this test reads")

    monkeypatch.setattr(evaluation, "evaluate", stop)
    monkeypatch.setattr(evaluation, "evaluate_rotation", stop)
    common = ["--classes", "chair", "--instances", "2", "--variants", "plain"]
    assert cli.main(["evaluate", *common, "--methods", "bbox, vertex_mean"]) == 1
    assert cli.main(["evaluate", *common, "--rotation", " head, core "]) == 1
    assert cli.main(["evaluate", *common, "--methods", "all"]) == 1  # as --variants all (was "unknown method 'all'")
    assert seen == [["bbox", "vertex_mean"], ["head", "core"], None]
    assert "stop: the methods" in _err(capsys)


def test_evaluate_and_tune_take_classes_of_data_alike(tmp_path, capsys, monkeypatch):
    """``jaxpose evaluate --data DIR --classes a,b`` takes those classes of DIR, as ``jaxpose tune``
    does, through one code path (it was refused: "--classes and --instances choose from the built-in
    dataset"); an unknown class is refused by both in one message naming the classes DIR holds, a
    repeat and --instances with --data by both as usage errors."""
    from jaxpose import evaluation, tuning
    from jaxpose.errors import JaxposeError

    tetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    for name in ("a", "b", "c"):
        (tmp_path / name).mkdir()
        for k in range(2):
            (tmp_path / name / f"pose_{k}.obj").write_text(tetra)
    (tmp_path / "b" / "broken.ply").write_text("not a mesh: b is not read unless chosen")
    seen = []

    def stop(classes, **kw):
        seen.append(sorted(classes))
        raise JaxposeError("stop: the classes are what this test reads")

    monkeypatch.setattr(evaluation, "evaluate", stop)
    monkeypatch.setattr(tuning, "tune", lambda classes, **kw: stop(classes))
    data = ["--data", str(tmp_path)]
    assert cli.main(["evaluate", *data, "--classes", "c, a", "--methods", "bbox", "--variants", "plain"]) == 1
    assert cli.main(["tune", *data, "--classes", "c,a", "--holdout", "0", "--steps", "0"]) == 1
    assert seen == [["a", "c"], ["a", "c"]]
    assert "stop: the classes" in _err(capsys)
    errors = []
    for command in (["evaluate", "--methods", "bbox"], ["tune", "--steps", "0"]):
        assert cli.main([*command, *data, "--classes", "a,cat"]) == 1
        errors.append(_err(capsys).strip().splitlines()[-1])
    assert errors == [f"jaxpose: error: no classes ['cat'] in {tmp_path}; found ['a', 'b', 'c']"] * 2
    for extra, message in ((["--classes", "a,a"], "--classes names 'a' twice; give each once"),
                           (["--instances", "3"], "--instances chooses from the built-in dataset; --data takes "
                                                   "every mesh of each class of DIR")):
        errors = []
        for command in (["evaluate", "--methods", "bbox"], ["tune", "--steps", "0"]):
            assert cli.main([*command, *data, *extra]) == 2, (command, extra)
            errors.append(_err(capsys).strip())
        assert errors == [f"jaxpose: error: {message}"] * 2, errors
    # without --data: the built-in dataset's classes, checked alike before any work (usage errors)
    errors = []
    for command in (["evaluate", "--methods", "bbox"], ["tune", "--steps", "0"]):
        assert cli.main([*command, "--classes", "chair,cat"]) == 2
        errors.append(_err(capsys).strip())
    assert errors == ["jaxpose: error: unknown class 'cat'; expected one of human, dolphin, chair, tree, pot, "
                      "desktop_computer, hand, dog, guitar, piano, spider, horse"] * 2


def test_a_class_that_is_an_empty_folder_or_a_near_name_is_told_so(tmp_path, capsys, monkeypatch):
    """``--data DIR --classes x`` (evaluate, tune, one code path): a folder DIR/x that holds no
    meshes is said to ("DIR/x holds no mesh files"), and a name that differs from a class only by
    case or by Unicode normalization (NFD, as macOS stores names, against the NFC typed) names the
    class meant; both said "no classes ['x'] in DIR", as of a name DIR does not hold at all."""
    import unicodedata

    from jaxpose import evaluation, tuning

    monkeypatch.setattr(evaluation, "evaluate", lambda *a, **k: pytest.fail("the work started"))
    monkeypatch.setattr(tuning, "tune", lambda *a, **k: pytest.fail("the work started"))
    tetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    cafe = unicodedata.normalize("NFC", "Caf\u00e9")
    for name in ("Dog", cafe):
        (tmp_path / name).mkdir()
        (tmp_path / name / "pose_0.obj").write_text(tetra)
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("no mesh here")
    typed = unicodedata.normalize("NFD", cafe)
    assert typed != cafe  # (the oracle: two spellings of one name)
    found = f"; found [{cafe!r}, 'Dog']"  # (the classes to choose from, in every case: review)
    cases = [("empty", f"{tmp_path / 'empty'} holds no mesh files (.glb, .gltf, .obj, .off, .ply, .stl){found}"),
             ("dog", f"no class 'dog' in {tmp_path} (did you mean 'Dog'?){found}"),
             (typed, f"no class {typed!r} in {tmp_path} (did you mean {cafe!r}?: the same letters in another Unicode "
                     f"normalization, {ascii(typed)} is not {ascii(cafe)}){found}"),
             ("cat", f"no classes ['cat'] in {tmp_path}{found}")]
    for classes, message in cases:
        for command in (["evaluate", "--methods", "bbox"], ["tune", "--steps", "0"]):
            assert cli.main([*command, "--data", str(tmp_path), "--classes", classes]) == 1, (command, classes)
            assert _err(capsys).strip().splitlines()[-1] == f"jaxpose: error: {message}", (command, classes)


def test_rotation_all_reads_as_the_other_lists_all(capsys, monkeypatch):
    """``--rotation 'all,'`` / ``' all'`` was "unknown rotation methods ['all']" (the raw text was
    compared with "all"), where ``--variants 'all,'`` and ``--methods ' all '`` are every one (review):
    every frame; a list of names stays that list."""
    from jaxpose import evaluation
    from jaxpose.errors import JaxposeError

    seen = []

    def stop(classes, methods=None, **kw):
        seen.append(methods)
        raise JaxposeError("stop: the methods are what this test reads")

    monkeypatch.setattr(evaluation, "evaluate_rotation", stop)
    for text in ("all,", " all", "all"):
        assert cli.main(["evaluate", "--rotation", text, "--classes", "chair", "--instances", "2",
                         "--variants", "plain"]) == 1, text
        assert "stop: the methods" in _err(capsys)
    assert cli.main(["evaluate", "--rotation", "core, pca_vertices", "--classes", "chair", "--instances", "2",
                     "--variants", "plain"]) == 1
    assert seen == [None, None, None, ["core", "pca_vertices"]]


@pytest.mark.parametrize("flag, what, every", [("--methods", "method", True), ("--variants", "variant", True),
                                               ("--rotation", "rotation method", True), ("--classes", "class", False)])
@pytest.mark.parametrize("text", ["", " , "])
def test_every_comma_list_option_that_names_nothing_is_refused_alike(capsys, monkeypatch, flag, what, every, text):
    """A comma-list option of evaluate or tune given no name ('' from an unset shell variable, ' , ')
    is refused in one wording, before any work: --variants '' and --rotation '' said "unknown
    variants []" and "unknown rotation methods []" where --methods '' and --classes '' said
    "--methods names no method (''); give some, comma-separated, or all"."""
    from jaxpose import datasets, evaluation, tuning

    for module, name in ((evaluation, "evaluate"), (evaluation, "evaluate_rotation"), (tuning, "tune"),
                         (datasets, "make_dataset")):
        monkeypatch.setattr(module, name, lambda *a, **k: pytest.fail("the work started"))
    expected = (f"jaxpose: error: {flag} names no {what} ({text!r}); give some, comma-separated"
                + (", or all" if every else ""))
    commands = [["evaluate"] + (["--rotation", "head"] if flag == "--variants" else [])]
    if flag in ("--variants", "--classes"):  # tune's comma lists
        commands.append(["tune", "--steps", "0"])
    for command in commands:
        assert cli.main([*command, flag, text]) == 2, command
        assert _err(capsys).strip() == expected, command


def test_an_empty_folder_name_is_refused(tmp_path, capsys, monkeypatch):
    """``--data ""`` (an unset shell variable) read the working directory's sub-folders as the
    classes (review: evaluate since --classes took --data's classes, tune before), and tune's
    ``--holdout-data ""`` was taken as none: each is refused as a usage error, before any work."""
    from jaxpose import evaluation, tuning

    (tmp_path / "k1").mkdir()
    trimesh.creation.box().export(tmp_path / "k1" / "a.ply")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(evaluation, "evaluate", lambda *a, **k: pytest.fail("the work started"))
    monkeypatch.setattr(tuning, "tune", lambda *a, **k: pytest.fail("the work started"))
    for argv, flag in ((["evaluate", "--data", "", "--methods", "bbox"], "--data"),
                       (["tune", "--data", " ", "--steps", "0"], "--data"),
                       (["tune", "--holdout-data", "", "--steps", "0"], "--holdout-data")):
        assert cli.main(argv) == 2, argv
        assert _err(capsys).strip().splitlines()[-1].startswith(f"jaxpose: error: {flag} names no folder ("), argv


def test_evaluate_output_paths_are_checked_before_the_work(tmp_path, capsys, no_work):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    for args, fragment in ((["--json", str(blocker / "r.json")], "is a file"),
                           (["--plots", str(blocker)], "is a file"),
                           (["--json", str(blocker)], "exists"),
                           (["--json", str(tmp_path)], "is a folder")):
        assert cli.main(["evaluate", "--methods", "bbox", *args]) == 2, args  # usage: an unusable output path
        assert fragment in _err(capsys), args


def test_evaluate_small_run_legend_progress_and_files(tmp_path, capsys):
    """The documented small version: progress lines on stderr when it is not a terminal, a legend,
    ms per object apart from the first call, gamma only with the OCSVM, missing folders made."""
    out = tmp_path / "new" / "r.json"
    code = cli.main(["evaluate", "--classes", "chair,pot", "--instances", "2", "--variants", "plain",
                     "--methods", "bbox,surface_centroid", "--json", str(out), "--plots", str(tmp_path / "figs")])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "jaxpose evaluate: [0/2] plain: first call of each method (compiles)" in captured.err
    assert "jaxpose evaluate: [2/2] done" in captured.err
    text = captured.out
    assert "2 classes x 2 objects" in text and "gamma" not in text.splitlines()[0]
    assert "lower is better" in text and "ms/object" in text and "compilation" in text
    assert out.exists() and (tmp_path / "figs" / "consistency_plain.png").exists()


def test_a_closed_pipe_ends_quietly_with_exit_0(tmp_path):
    """`jaxpose ... | head`: the reader leaves before the table is printed; the files were written
    first, the exit status is 0 and nothing is said on stderr."""
    out = tmp_path / "r.json"
    proc = subprocess.Popen([sys.executable, "-m", "jaxpose", "evaluate", "--classes", "chair", "--instances", "2",
                             "--variants", "plain", "--methods", "bbox", "--json", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # like `| head -0`
    with proc.stderr:
        err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 0, err
    assert "error" not in err and "Traceback" not in err, err
    assert out.exists()


def test_help_describes_every_option():
    from jaxpose.cli.tune import parser

    for action in parser()._actions:
        assert action.help, action.option_strings
    run = subprocess.run([sys.executable, "-m", "jaxpose", "--help"], capture_output=True, text=True, cwd=ROOT,
                         timeout=120)
    assert run.returncode == 0 and "one-class SVMs." not in run.stdout
    assert "robust" in run.stdout and "Exit codes" in run.stdout
    for command in ("normalize", "evaluate"):
        sub = cli.build_parser()._subparsers._group_actions[0].choices[command]
        for action in sub._actions:
            assert action.help, (command, action.option_strings)
    # normalize refuses the OCSVM's options under another method, so their help says whose they are
    # (--seed said "random seed")
    from jaxpose.config import OCSVM_ONLY

    normalize = cli.build_parser()._subparsers._group_actions[0].choices["normalize"]
    ocsvm_only = [action for action in normalize._actions if action.dest in OCSVM_ONLY]
    assert len(ocsvm_only) == len(OCSVM_ONLY)
    for action in ocsvm_only:
        assert "ocsvm" in action.help, action.option_strings
    # --resolution's meaning and default for the default method (robust) too; it said only "grid resolution
    # of the volume moments (>= 8)", the OCSVM's grid
    from jaxpose.config import GridConfig, RobustConfig

    resolution = next(action for action in normalize._actions if action.dest == "resolution").help
    assert f"robust: voxels along the main body's largest extent (default {RobustConfig().resolution})" in resolution
    assert f"ocsvm: cells per axis of the volume integral's grid (default {GridConfig().resolution})" in resolution


def test_tune_bounds_instances_before_the_work(capsys, monkeypatch):
    """tune --instances 1000000000 built the dataset in memory for ever; refused before any work."""
    from jaxpose import datasets

    monkeypatch.setattr(datasets, "make_dataset", lambda *a, **k: pytest.fail("the work started"))
    assert cli.main(["tune", "--instances", "201"]) == 2
    assert "--instances must be <= 200" in _err(capsys)


@pytest.mark.parametrize("argv, flag", [(["--gamma", "0"], "--gamma"), (["--nu", "0.99"], "--nu"),
                                        (["--method", "robust", "--power", "0"], "--power"),
                                        (["--scale-weight", "-1"], "--scale-weight")])
def test_tune_refusals_name_the_option_as_typed(capsys, monkeypatch, argv, flag):
    """A bad start or weight is refused naming the option the user typed: it said "gamma0 must be
    a finite number > 0" for --gamma 0 (nu0, power0, scale_weight alike)."""
    from jaxpose import datasets

    monkeypatch.setattr(datasets, "make_dataset", lambda *a, **k: pytest.fail("the work started"))
    assert cli.main(["tune", *argv]) == 2
    err = _err(capsys)
    assert err.startswith(f"jaxpose: error: {flag} must be ") and err.count("\n") == 1, err


@pytest.mark.parametrize("command", ["tune", "bench"])
def test_tune_and_bench_check_json_before_the_work(tmp_path, capsys, command):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert cli.main([command, "--json", str(blocker / "r.json")]) == 2
    err = _err(capsys)
    assert "is a file" in err
    assert err.startswith("jaxpose: error: ") and err.count("\n") == 1, err  # every command's one line (tune's was 'jaxpose tune: error:')


def test_a_glob_pattern_the_shell_expanded_is_named(tmp_path, monkeypatch, capsys):
    """`--glob *.off` unquoted reaches jaxpose as `--glob a.off b.off`: after the INPUTs, an
    unrecognized argument (now with the hint to quote it); before them, b.off became an INPUT and
    the folder search took only what matched a.off, without a word (now refused: exit 2, nothing
    done). One expanded name alone is warned about."""
    from jaxpose import cli

    scans = tmp_path / "scans"
    scans.mkdir()
    tetra = "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
    for name in ("a.off", "c.off"):
        (scans / name).write_text(tetra)
    here = tmp_path / "here"
    here.mkdir()
    for name in ("a.off", "b.off"):
        (here / name).write_text(tetra)
    monkeypatch.chdir(here)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        cli.main(["normalize", str(scans), "-o", str(out), "--glob", "a.off", "b.off"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "unrecognized arguments: b.off; did the shell expand --glob's pattern" in err and "--glob '*.off'" in err
    # only where the extra argument is a file of the glob's suffix here (the hint came with any unknown option)
    for extra in (["--bogus"], ["c.off"], ["a.ply"]):
        (here / "a.ply").write_text("")
        with pytest.raises(SystemExit):
            cli.main(["normalize", str(scans), "-o", str(out), "--glob", "a.off", *extra])
        err = capsys.readouterr().err
        assert f"unrecognized arguments: {extra[0]}" in err and "did the shell expand" not in err, err
    assert cli.main(["normalize", "--glob", "a.off", "b.off", str(scans), "-o", str(out), "--method", "vertex_mean"]) == 2
    err = capsys.readouterr().err
    assert "--glob a.off and the INPUTs b.off are files here: the shell expanded --glob's pattern" in err, err
    assert not out.exists()
    (here / "b.off").unlink()
    assert cli.main(["normalize", "--glob", "a.off", str(scans), "-o", str(out), "--method", "vertex_mean",
                     "--workers", "1"]) == 0
    assert "warning: --glob a.off has no wildcard and names a file here" in capsys.readouterr().err


def test_an_input_after_a_bare_rotation_is_named_as_the_input(tmp_path, capsys):
    """`--rotation body.off -o out.ply`: argparse gives --rotation's optional METHOD the next word;
    the refusal says so (it read only "invalid choice: 'body.off'"); a method or no method as before."""
    from jaxpose import cli

    body = tmp_path / "body.off"
    body.write_text("OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")
    with pytest.raises(SystemExit) as info:
        cli.main(["normalize", "--rotation", str(body), "-o", str(tmp_path / "out.ply")])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert f"invalid choice: '{body}'" in err and "looks like the INPUT: --rotation takes the word after it as its " \
        "METHOD, so put the INPUT before --rotation" in err, err
    with pytest.raises(SystemExit):
        cli.main(["normalize", str(body), "--rotation", "bogus"])
    err = capsys.readouterr().err
    assert "invalid choice: 'bogus' (choose from core, head," in err and "looks like the INPUT" not in err, err
    for argv in (["--rotation"], ["--rotation", "pca_vertices"]):
        assert cli.main(["normalize", str(body), "-o", str(tmp_path / "out.ply"), "--force", "--method", "vertex_mean",
                         *argv]) == 0


def test_one_file_writes_its_mesh_and_transform_both_or_neither(tmp_path, monkeypatch, capsys):
    """A Ctrl-C that lands between the mesh and its transform JSON is held until both are written
    (it left out.ply without out.transform.json, under "nothing partial was left"); a JSON that
    cannot be written takes the mesh this run made with it (a rerun refused out.ply as existing)."""
    import os
    import signal

    from jaxpose import cli, mesh
    from jaxpose.batch import interrupts

    body = tmp_path / "body.off"
    body.write_text("OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")
    out, json_path = tmp_path / "out.ply", tmp_path / "out.transform.json"
    export = mesh.export

    def export_then_ctrl_c(*args, **kwargs):
        written = export(*args, **kwargs)
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C right after the mesh
        return written

    monkeypatch.setattr(mesh, "export", export_then_ctrl_c)
    with interrupts.SignalGuard():
        assert cli.main(["normalize", str(body), "-o", str(out), "--method", "vertex_mean"]) == 130
    assert out.is_file() and json_path.is_file()  # both whole
    monkeypatch.setattr(mesh, "export", export)
    out.unlink()
    json_path.unlink()
    write_atomic = mesh.write_atomic

    def json_fails(path, data, force=False):
        if str(path).endswith(".json"):
            raise OSError(28, "No space left on device")
        return write_atomic(path, data, force=force)

    monkeypatch.setattr(mesh, "write_atomic", json_fails)
    assert cli.main(["normalize", str(body), "-o", str(out), "--method", "vertex_mean"]) == 1
    assert "No space left on device" in capsys.readouterr().err
    assert not out.exists() and not json_path.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["body.off"]  # no temporary either


def test_core_weight_choices_are_the_alignments():
    """--core-weight's choices are a literal of evaluation.alignment.CORE_WEIGHTS (the command line
    imports no NumPy): pinned equal, the default first; --instances' bounds are config.check_instances' (one check)."""
    import argparse

    from jaxpose.cli.common import add_core_options, check_dataset_choice
    from jaxpose.errors import InvalidInputError
    from jaxpose.evaluation.alignment import CORE_WEIGHTS

    parser = argparse.ArgumentParser()
    add_core_options(parser)
    action = next(a for a in parser._actions if a.dest == "core_weight")
    assert tuple(action.choices) == CORE_WEIGHTS and action.default == CORE_WEIGHTS[0]
    for bad, message in ((1, "--instances must be >= 2, got 1"), (201, "--instances must be <= 200")):
        with pytest.raises(InvalidInputError, match=message):
            check_dataset_choice(bad, None)
