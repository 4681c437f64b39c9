"""Every snippet of the README runs as written: the Python block, and each command of the
command-line block (in-process, in a temporary folder). The two fresh-machine commands are the
install plus the main job and the install plus the tests: the second is what .ci/run runs.
docs/api.md's signatures are the code's (names, order, keyword-only, defaults)."""
import re
import shlex
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def _blocks(lang):
    return re.findall(rf"```{lang}\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_is_short_and_names_the_two_commands():
    text = README.read_text()
    assert len(text.splitlines()) <= 120
    bash = _blocks("bash")
    assert bash[0].strip() == "pip install -e . && jaxpose evaluate"
    assert bash[1].strip() == 'pip install -e ".[test]" && python -m pytest -q'
    ci = (README.parent / ".ci" / "run").read_text()
    assert bash[1].strip() in ci


def test_python_snippet_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for block in _blocks("python"):
        exec(compile(block, str(README), "exec"), {})


def test_command_line_snippets_run(tmp_path, monkeypatch, capsys):
    from jaxpose import cli

    import trimesh

    monkeypatch.chdir(tmp_path)
    (tmp_path / "scans" / "a").mkdir(parents=True)  # the dataset the batch commands name
    trimesh.creation.capsule(height=1.0, radius=0.4, count=[8, 8]).export(tmp_path / "scans" / "a" / "capsule.ply")
    trimesh.creation.box(extents=(1.0, 0.6, 0.3)).export(tmp_path / "scans" / "box.obj")
    commands = [line.split("#")[0].strip() for block in _blocks("bash")[2:] for line in block.splitlines()]
    commands = [c for c in commands if c]
    assert commands and all(c.startswith("jaxpose ") for c in commands)
    printed = {}
    for command in commands:
        assert cli.main(shlex.split(command)[1:]) == 0, command
        printed[command] = capsys.readouterr().out
    assert (tmp_path / "normalized.ply").exists() and (tmp_path / "normalized.transform.json").exists()
    for out in ("normalized", "normalized-dask"):
        assert (tmp_path / out / "a" / "capsule.ply").exists() and (tmp_path / out / "box.obj").exists()

    # the figures README.md and docs/estimators.md state for the evaluate example are what it prints
    example = next(c for c in commands if c.startswith("jaxpose evaluate --variants plain,outliers,holes"))
    measured = _robust_vs_reference(printed[example])
    estimators = (README.parent / "docs" / "estimators.md").read_text()
    sentence = " ".join(estimators[estimators.index("The README's example"):].split("\n\n")[0].split())
    stated = {v: float(x.replace("\u2212", "-")) for x, v in re.findall(r"([\u2212+-]\d+\.\d) % \((\w+)\)", sentence)}
    assert stated == measured, (stated, measured)
    assert f"robust {measured['holes']:+.1f} %" in " ".join(README.read_text().split())


def test_batch_md_snippets_run(tmp_path, monkeypatch, capsys):
    """docs/batch.md's commands run as written, each alone in a folder holding the dataset they name
    (scans/, more/, list.txt; the cluster ones, --dask-local and --scheduler, are the README's test's
    and need a cluster), and its Python blocks after them (``jaxpose`` imported, as the page's
    first line implies): the normalize_files call, and the shards' tables read back and joined."""
    import shutil

    import trimesh

    import jaxpose
    from jaxpose import cli

    data = tmp_path / "data"
    (data / "scans" / "a").mkdir(parents=True)
    (data / "more").mkdir()
    trimesh.creation.capsule(height=1.0, radius=0.4, count=[8, 8]).export(data / "scans" / "a" / "pose_01.ply")
    trimesh.creation.box(extents=(1.0, 0.6, 0.3)).export(data / "scans" / "box.obj")
    trimesh.creation.icosphere(subdivisions=1).export(data / "more" / "pose_02.ply")
    trimesh.creation.icosphere(subdivisions=1).export(data / "more" / "ball.stl")
    (data / "list.txt").write_text("# a manifest\nmore/ball.stl\n")
    page = (README.parent / "docs" / "batch.md").read_text()
    commands = [line.split("  #")[0].strip() for block in re.findall(r"```text\n(.*?)```", page, flags=re.S)
                for line in block.splitlines() if line.strip().startswith("jaxpose normalize")]
    local = [c for c in commands if not any(k in c for k in ("--dask-local", "--scheduler", "://"))]
    assert len(local) >= 4, commands
    for k, command in enumerate(local):
        here = tmp_path / f"run{k}"
        shutil.copytree(data, here)
        monkeypatch.chdir(here)
        assert cli.main(shlex.split(command)[1:]) == 0, (command, capsys.readouterr().err)
        capsys.readouterr()
        assert list((here / "normalized").glob("transforms*.*")), command  # .parquet (.csv without pyarrow)
    here = tmp_path / "python"
    shutil.copytree(data, here)
    monkeypatch.chdir(here)
    blocks = re.findall(r"```python\n(.*?)```", page, flags=re.S)
    assert len(blocks) == 2
    namespace = {"jaxpose": jaxpose}
    exec(compile(blocks[0], "docs/batch.md", "exec"), namespace)
    assert len(namespace["rows"]) == 2 and namespace["failed"] == []
    for i in range(3):  # the shards' OUTDIRs the second block reads
        jaxpose.normalize_files("scans/", f"out{i}/", shard=(i, 3), workers=1)
    exec(compile(blocks[1], "docs/batch.md", "exec"), namespace)
    assert len(namespace["rows"]) == 2 and len(jaxpose.read_transforms("all.parquet")) == 2


def test_api_md_names_every_option_of_the_dataset_form():
    """docs/api.md's list of `jaxpose normalize INPUT... -o OUTDIR`'s options is the command's "many
    files" group (it left out --shard and --timeout)."""
    from jaxpose.cli import build_parser

    normalize = build_parser()._subparsers._group_actions[0].choices["normalize"]
    (group,) = [g for g in normalize._action_groups if g.title.startswith("many files")]
    flags = {a.option_strings[-1] for a in group._group_actions}
    api = " ".join((README.parent / "docs" / "api.md").read_text().split())
    listed = api[api.index("is the dataset form:"):api.index("Exit codes:", api.index("is the dataset form:"))]
    assert flags == set(re.findall(r"`(--[a-z-]+)", listed)), (flags, listed)


def test_exit_codes_are_the_commands():
    """The exit codes README.md and docs/api.md list are those `jaxpose --help` lists (the README
    left out 143, SIGTERM's, which api.md and the command's help name)."""
    from jaxpose.cli import build_parser

    def codes(text):
        text = " ".join(text.split())
        return re.findall(r"\b(\d{1,3})\b(?= \(| [A-Za-z])", text[text.index("Exit codes:"):].split(".")[0])

    helped = codes(build_parser().epilog)
    assert helped == ["0", "1", "2", "130", "143"], helped
    assert codes(README.read_text()) == helped
    api = " ".join((README.parent / "docs" / "api.md").read_text().split())
    assert re.findall(r"\b(\d{1,3}) ?[(,]", api[api.index("Exit codes:"):api.index("(SIGTERM)") + 1]) == helped


def _robust_vs_reference(text):
    """{variant: robust's sigma_tr change against the reference, in %} from format_table's output."""
    out, variant = {}, None
    for line in text.splitlines():
        if line.startswith("variant "):
            variant = line.split()[1]
        elif variant and line.startswith("robust "):
            cell = line.split()[2]
            out[variant] = None if cell == "n/a" else float(cell.rstrip("%"))
    return out


# --------------------------------------------------------------------------- docs/api.md's signatures
API = README.parent / "docs" / "api.md"
# parameters whose default in the code is a marker (not given), resolved where the pose is computed
_RESOLVED = {"power": "config.ROBUST.power", "gamma": "config.OCSVM.gamma", "nu": "config.OCSVM.nu",
             "max_points": "pose.sizes.MAX_POINTS"}
# where a function's **options go: the names docs/api.md writes out for them are that target's
_FORWARDED = {"jaxpose.normalize": "jaxpose.config.RobustConfig", "jaxpose.normalize_batch": "jaxpose.config.RobustConfig",
              "jaxpose.normalize_files": "jaxpose.batch.batch.run_batch"}


# first-column items with brackets that are not signatures (each says why); every other one must read as one
_NOT_SIGNATURES = {".settings(format)": "NormalizeOptions' method, named after its class in the same cell",
                   "task.recorded_settings(row.options)": "a call on a table row's column, not a signature"}


def _signature_item(item):
    """``(name, params)`` of a first-column item ``name``, ``name(params)`` or either with
    `` -> result`` (params: the text between the brackets, nested brackets at any depth; None
    without brackets), or None where it does not read so."""
    match = re.match(r"[A-Za-z_][\w.]*", item)
    if not match:
        return None
    name, rest = match.group(), item[match.end():]
    if not rest.startswith("("):
        return (name, None) if re.fullmatch(r"(?: -> .*)?", rest) else None
    depth = 0
    for end, char in enumerate(rest):
        depth += (char in "([{") - (char in ")]}")
        if depth <= 0:
            break
    if depth != 0 or rest[end] != ")":
        return None  # unbalanced, or closed by another bracket
    return (name, rest[1:end]) if re.fullmatch(r"(?: -> .*)?", rest[end + 1:]) else None


def _api_signatures():
    """[(written name, resolved qualified name, object, parameter text)] of every call signature in the
    first column of docs/api.md's tables (``name(params)``); an unqualified name after a qualified
    one in the same cell is looked up where that one was found (`estimators.estimate(...)`,
    `estimate_many(...)`). An item with a bracket that does not read as a signature (brackets that
    do not close, a parameter name that is not one, a signature of something not callable) fails,
    except the few of :data:`_NOT_SIGNATURES` (they were skipped without a word)."""
    import importlib
    import inspect
    import pkgutil

    import jaxpose

    modules = ["jaxpose"] + [m.name for m in pkgutil.walk_packages(jaxpose.__path__, "jaxpose.")]

    def lookup(dotted, context):
        if context is jaxpose and hasattr(jaxpose, dotted.split(".")[0]):  # a public name (normalize, not cli.normalize)
            obj = container = jaxpose
            for name in dotted.split("."):
                container, obj = obj, getattr(obj, name, None)
                if obj is None:
                    break
            else:
                return obj, f"jaxpose.{dotted}", obj if inspect.ismodule(obj) else container
        for i in range(len(dotted.split(".")), 0, -1):
            parts = dotted.split(".")
            prefix, rest = ".".join(parts[:i]), parts[i:]
            found = [m for m in modules if m == f"jaxpose.{prefix}" or m.endswith(f".{prefix}")]
            if found:
                found = [f"jaxpose.{prefix}"] if f"jaxpose.{prefix}" in found else found
                assert len(found) == 1, f"docs/api.md: {dotted!r} names one of several modules {found}"
                obj, where = importlib.import_module(found[0]), found[0]
                break
        else:
            obj, where, rest = context, getattr(context, "__name__", "jaxpose"), dotted.split(".")
        for name in rest:
            container = obj
            assert hasattr(obj, name), f"docs/api.md names {dotted!r}: {where} has no {name}"
            obj, where = getattr(obj, name), f"{where}.{name}"
        return obj, where, (obj if inspect.ismodule(obj) else container if rest else obj)

    out = []
    for row in API.read_text().splitlines():
        if not row.startswith("| `"):
            continue
        context = jaxpose
        for item in re.findall(r"`([^`]+)`", row.split(" | ")[0]):
            if item in _NOT_SIGNATURES:
                continue
            parsed = _signature_item(item)
            assert parsed is not None or "(" not in item, (
                f"docs/api.md: {item!r} does not read as a signature name(params) (add it to _NOT_SIGNATURES "
                "if it is none)")
            if parsed is None:
                continue  # no bracket: not a signature (a command line, a value)
            name, params = parsed
            start = jaxpose if "." in name or hasattr(jaxpose, name.split(".")[0]) else context
            try:
                obj, where, found_in = lookup(name, start)
            except AssertionError:
                if params is not None:  # a signature of nothing
                    raise
                continue  # a plain name the row's text places (its own test is the row's module's)
            context = found_in if "." in name else context
            names = [p.partition("=")[0].strip() for p in _split_params(params or "")]
            bad = [n for n in names if not (n.isidentifier() or n in ("*", "...", "…")
                                            or (n[:1] == "*" and n.lstrip("*").isidentifier() and len(n) - len(n.lstrip("*")) <= 2))]
            assert not bad, (f"docs/api.md: {item!r}: {bad} not parameter names (a call, not a signature? add it to "
                             "_NOT_SIGNATURES)")
            if params is not None:
                assert callable(obj), f"docs/api.md: {item!r}: {where} is not callable"
                out.append((name, where, obj, params))
    return out


def test_api_md_items_that_do_not_read_as_signatures_fail(tmp_path, monkeypatch):
    """A first-column item with a bracket that the signature check cannot read fails, naming it
    (it was skipped without a word: a default nested two brackets deep, a parameter name that is
    not one); the known non-signatures (_NOT_SIGNATURES) are passed over, a nested default read."""
    import sys

    doc = tmp_path / "api.md"
    monkeypatch.setattr(sys.modules[__name__], "API", doc)
    head = "| a | b |\n| --- | --- |\n"
    doc.write_text(head + "| `normalize_mesh(mesh_or_path, gamma=None, *, center=((1, 2), 3))` | nested |\n"
                   "| `NormalizeOptions`, `.settings(format)`, `task.recorded_settings(row.options)` | known |\n")
    assert [(s[0], s[3]) for s in _api_signatures()] == [
        ("normalize_mesh", "mesh_or_path, gamma=None, *, center=((1, 2), 3)")]
    for item in ("normalize_mesh(mesh-or-path, nope=1)", "normalize_mesh(mesh_or_path, (1, 2))",
                 "normalize_mesh(mesh_or_path", "normalize_mesh(mesh_or_path)) -> x", "normalize_mesh(a] -> x",
                 "(mesh_or_path)", "config.ROBUST(x)"):
        doc.write_text(head + f"| `{item}` | bad |\n")
        with pytest.raises(AssertionError, match=re.escape(repr(item))):
            _api_signatures()


def _split_params(text):
    """'a, b=(1, 2), *, c=None, **kw' -> ['a', 'b=(1, 2)', '*', 'c=None', '**kw'] (commas in brackets kept)."""
    parts, depth, current = [], 0, ""
    for char in text:
        depth += (char in "([{") - (char in ")]}")
        if char == "," and depth == 0:
            parts.append(current.strip())
            current = ""
        else:
            current += char
    return [p for p in parts + [current.strip()] if p]


def test_api_md_signatures_are_the_codes():
    """The signatures docs/api.md writes (``name(params)`` in its tables' first column) are the
    code's: each parameter it names exists, under that name (a keyword argument a user copies must
    work), positional or keyword-only as written (``*``), in the code's order up to an ``...``; each
    default it writes is the code's (but ``method=`` in a row per method; a marker default: the configuration value it resolves to;
    ``**options`` written out: the defaults of where they go, ``_FORWARDED``); every parameter the
    code requires is written, unless ``...`` elides some. (``baselines.center(mesh, name)`` was
    ``method=``; ``voxels.filled_voxels(mesh, ...)`` ``mesh_or_points``.)"""
    import ast
    import importlib
    import inspect

    from jaxpose.pose.estimators import METHODS

    def resolve(path):  # "jaxpose.config.ROBUST.power": attributes, importing submodules on the way
        obj = importlib.import_module("jaxpose")
        for part in path.split(".")[1:]:
            obj = getattr(obj, part) if hasattr(obj, part) else importlib.import_module(f"{obj.__name__}.{part}")
        return obj

    signatures = _api_signatures()
    assert len(signatures) >= 25, [s[0] for s in signatures]
    problems = []
    for written, where, obj, text in signatures:
        params = inspect.signature(obj).parameters
        has_kwargs = any(p.kind is p.VAR_KEYWORD for p in params.values())
        forwarded = {k: v for k, v in inspect.signature(resolve(_FORWARDED[where])).parameters.items()} \
            if where in _FORWARDED else {}
        keyword_only, order, elided = False, [], False
        for item in _split_params(text):
            if item == "*":
                keyword_only = True
                continue
            if item in ("...", "…"):
                elided = True
                continue
            if item.startswith("**"):
                if not has_kwargs:
                    problems.append(f"{written}: {item} written, the code takes no **keywords")
                continue
            name, _, default = (s.strip() for s in item.partition("="))
            param = params.get(name)
            if param is None or param.kind is param.VAR_KEYWORD:
                if name in forwarded and has_kwargs:
                    param = forwarded[name]
                else:
                    problems.append(f"{written}: no parameter {name!r} (the code's: {', '.join(params)})")
                    continue
            elif not elided:
                order.append(name)
                kw_only = param.kind is param.KEYWORD_ONLY
                if kw_only != keyword_only:
                    problems.append(f"{written}: {name} is {'keyword-only' if kw_only else 'positional'} in the code")
            if default:
                code = param.default
                if code is not inspect.Parameter.empty and not isinstance(code, (int, float, str, tuple, type(None))):
                    code = resolve(f"jaxpose.{_RESOLVED[name]}") if name in _RESOLVED else code
                try:
                    stated = ast.literal_eval(default)
                except ValueError:
                    problems.append(f"{written}: {name}={default} is not a value")
                    continue
                if name == "method" and stated != code and stated in METHODS:
                    continue  # a row per method (normalize's "robust" and "ocsvm"): the row's method, not a default
                if code is inspect.Parameter.empty or stated != code or type(stated) is bool and code is not stated:
                    problems.append(f"{written}: {name}={default}, the code's default {code!r}")
        in_code = [n for n in params if n in order]
        if in_code != order:
            problems.append(f"{written}: parameters in the order {order}, the code's {in_code}")
        if not elided:
            required = [n for n, p in params.items() if p.default is p.empty and p.kind in (p.POSITIONAL_ONLY,
                        p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and n not in order]
            if required:
                problems.append(f"{written}: the code also requires {required}")
    assert not problems, "\n".join(problems)
