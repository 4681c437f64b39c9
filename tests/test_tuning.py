"""Gradient-based tuning of (gamma, nu): ``jaxpose.tuning.tune`` and ``jaxpose tune``."""
from __future__ import annotations

import json

import jax
import numpy as np
import pytest
import trimesh

import jaxpose
from jaxpose import tuning
from jaxpose.cli import main
from jaxpose.mesh import sample_surface

FAST = dict(resolution=8, refine=2, band=256, tol=1e-3)


pytestmark = pytest.mark.usefixtures("x64_module")  # every test in float64


def _classes(count=120, n=4):
    rng = np.random.default_rng(0)
    shapes = {"box": trimesh.creation.box([1.0, 0.6, 0.3]), "capsule": trimesh.creation.capsule(height=1.0, radius=0.3)}
    out = {}
    for name, mesh in shapes.items():
        objs = []
        for i in range(n):
            m = mesh.copy()
            m.apply_scale(rng.uniform(0.9, 1.1, size=3))
            objs.append(sample_surface(m, count, seed=i))
        out[name] = objs
    return out


def test_tune_result_is_json_and_moves_parameters():
    messages = []
    res = tuning.tune(_classes(), steps=2, lr=0.1, holdout=0.5, progress=messages.append, **FAST)
    json.dumps(res)  # JSON-able
    assert len(res["trajectory"]) == 3 and len(messages) == 3
    first = res["trajectory"][0]
    assert first["gamma"] == pytest.approx(47.0) and first["nu"] == pytest.approx(0.5)
    assert all(np.isfinite(t["grad"]).all() for t in res["trajectory"])
    assert res["trajectory"][1]["gamma"] != pytest.approx(47.0)
    assert 0.0 < res["nu"] < 1.0 and res["gamma"] > 0
    for part in ("train", "holdout"):
        assert res[part]["sigma_tr_start"] > 0 and res[part]["sigma_tr_end"] > 0
    assert res["train"]["objects"] == 4 and res["holdout"]["objects"] == 4
    # whole classes are held out (issue 3: "splits classes into tuning and held-out sets")
    assert res["train"]["classes"] == 1 and res["holdout"]["classes"] == 1
    assert set(res["train"]["names"]) | set(res["holdout"]["names"]) == {"box", "capsule"}
    assert not set(res["train"]["names"]) & set(res["holdout"]["names"])
    assert res["train"]["sigma_tr_end"] <= res["train"]["sigma_tr_start"] + 1e-12  # best point kept


def test_holdout_splits_whole_classes():
    classes = {f"c{i}": [i] * 3 for i in range(10)}
    train, test = tuning._split(classes, 0.3, seed=0)
    assert len(test) == 3 and len(train) == 7 and not set(train) & set(test)
    assert all(train[k] == classes[k] for k in train)  # objects of a class stay together
    assert tuning._split(classes, 0.3, seed=0) == (train, test)  # seeded
    assert len(tuning._split({"a": [1, 2], "b": [1, 2]}, 0.01, seed=0)[1]) == 1  # at least one held out
    with pytest.raises(jaxpose.InvalidInputError):
        tuning._split({"a": [1, 2]}, 0.5, seed=0)
    with pytest.raises(jaxpose.InvalidInputError):
        tuning._split(classes, 1.0, seed=0)


def test_tune_zero_steps_and_validation():
    res = tuning.tune(_classes(n=2), steps=0, **FAST)
    assert res["holdout"] is None and len(res["trajectory"]) == 1
    assert res["train"]["sigma_tr_end"] == pytest.approx(res["train"]["sigma_tr_start"])
    with pytest.raises(jaxpose.InvalidInputError):
        tuning.tune({"a": [np.zeros((10, 3)) + np.arange(3)]}, steps=0, **FAST)  # one object
    with pytest.raises(jaxpose.InvalidInputError):
        tuning.tune(_classes(n=2), steps=0, bogus=1)
    with pytest.raises(jaxpose.InvalidInputError):
        tuning.tune({"a": [np.random.default_rng(0).normal(size=(30, 3)), np.random.default_rng(1).normal(size=(31, 3))]}, steps=0, **FAST)


def test_gradient_matches_finite_difference_of_objective():
    classes = {"box": _classes(count=200, n=3)["box"]}
    config = jaxpose.PoseConfig.create(resolution=10, refine=2, band=512, tol=1e-6, max_iter=100_000,
                                       derivative="secant")
    stacked = tuning._stack(classes, "classes")
    class_loss, class_vg = tuning._make_loss(config, 0.0)
    theta = tuning._start_theta(47.0, 0.5)
    (_, _), grad = class_vg(theta, stacked["box"])
    e = 0.01
    # log-gamma direction: the exact derivative; compare with FD of the same loss
    fd = (float(class_loss(theta + np.array([e, 0.0]), stacked["box"])[0])
          - float(class_loss(theta - np.array([e, 0.0]), stacked["box"])[0])) / (2 * e)
    assert np.sign(fd) == np.sign(float(grad[0])) or abs(fd) < 1e-5
    assert np.all(np.isfinite(np.asarray(grad)))


def test_cli_tune_on_folder(tmp_path, capsys):
    for name, mesh in {"boxes": trimesh.creation.box([1.0, 0.5, 0.3]), "caps": trimesh.creation.capsule()}.items():
        (tmp_path / "data" / name).mkdir(parents=True)
        for i in range(2):
            m = mesh.copy()
            m.apply_scale(1.0 + 0.05 * i)
            m.export(tmp_path / "data" / name / f"{i}.ply")
    out = tmp_path / "r.json"
    old = jax.config.jax_enable_x64
    rc = main(["tune", "--data", str(tmp_path / "data"), "--steps", "1", "--count", "100", "--json", str(out),
               "--resolution", "8", "--band", "256", "--tol", "1e-3"])
    assert rc == 0
    assert jax.config.jax_enable_x64 == old  # the CLI restores the x64 flag
    res = json.loads(out.read_text())
    assert len(res["trajectory"]) == 2 and res["train"]["classes"] == 2
    assert "sigma_tr" in capsys.readouterr().out


def test_cli_tune_usage_and_errors(tmp_path, capsys):
    assert tuning.cli(["--steps", "x"]) == 2
    assert tuning.cli(["--data", str(tmp_path / "missing"), "--steps", "0"]) == 1
    assert tuning.cli(["--solver", "newton"]) == 2
    # an existing --json is refused before any work (bench and evaluate do the same), kept intact
    out = tmp_path / "r.json"
    out.write_text("keep")
    assert tuning.cli(["--data", str(tmp_path / "missing"), "--json", str(out)]) == 1
    assert "use --force" in capsys.readouterr().err
    assert out.read_text() == "keep"


def test_lazy_export():
    assert jaxpose.tuning.tune is tuning.tune
