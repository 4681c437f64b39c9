"""Every snippet of the README runs as written: the Python block, and each command of the
command-line block (in-process, in a temporary folder). The two fresh-machine commands are the
install plus the main job and the install plus the tests: the second is what .ci/run runs."""
import re
import shlex
from pathlib import Path

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
