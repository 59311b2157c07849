"""A failed or refused command loses nothing: no input overwritten by an output, no partial set of files.

docs/develop.md: bad input gets one ``error:`` line and exit status 2, and loses nothing -- an output
path that is one of the command's inputs is refused before anything is read or written, and a
command that writes several files writes none of them when it fails.
"""

from __future__ import annotations

import shlex
import shutil
from pathlib import Path

import numpy as np
import pytest

from ipcverify.contract._calibrate import calibrate
from ipcverify.data._dataset import save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.io._modelio import save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train


@pytest.fixture(scope="module")
def originals(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("originals")
    f = {
        name: d / name for name in ("data.csv", "data.npz", "model.pt", "problems.json", "gt.csv", "est.csv")
    }
    save_dataset(make_lagged_perception(300, seed=2), f["data.csv"])
    save_dataset(make_lagged_perception(300, seed=2), f["data.npz"])
    mc = ModelConfig.recipe("tight", x_dim=6, y_dim=3, hidden=(8,), members=2)
    tc = TrainConfig.recipe("tight", epochs=1, val_fraction=0.0, patience=None)
    model = train(make_lagged_perception(300, seed=0), mc, tc).model
    save_model(calibrate(model, make_lagged_perception(1000, seed=1), 0.05, 0.01), f["model.pt"])
    f["problems.json"].write_text(
        '{"inner": {"type": "ellipsoid", "center": [0, 0], "shape": [[1, 0], [0, 1]]}, '
        '"outer": {"type": "box", "lower": [-2, -2], "upper": [2, 2]}}',
        encoding="utf-8",
    )
    rows = [f"{int(0.05 * i * 1e9)},{0.05 * i},0,0,1,0,0,0" for i in range(200)]
    for name in ("gt.csv", "est.csv"):
        f[name].write_text("#timestamp,x,y,z,qw,qx,qy,qz\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return f


# id | the input the output would replace (as the error names it) | the command line; {name} is a copy
# of that original in a fresh folder, and --out / --onnx points at one of those copies.
SAME_FILE = """
train-data             | DATA       | train {data.csv} --out {data.csv} --epochs 1
calibrate-data         | DATA       | calibrate {model.pt} {data.csv} --epsilon 0.05 --delta 0.01 --out {data.csv}
calibrate-model        | MODEL      | calibrate {model.pt} {data.csv} --epsilon 0.05 --delta 0.01 --out {model.pt} --recalibrate
predict-data           | DATA       | predict {model.pt} {data.npz} --out {data.npz}
export-model           | MODEL      | export {model.pt} --onnx {model.pt} --no-domain
prove-problems         | PROBLEMS   | prove-containment {problems.json} --out {problems.json}
ingest-truth           | --truth    | ingest trajectories --truth {gt.csv} --estimate {est.csv} --format euroc --out {gt.csv}
ingest-estimate        | --estimate | ingest trajectories --truth {gt.csv} --estimate {est.csv} --format euroc --out {est.csv}
ingest-bag             | PATH       | ingest bag {data.csv} --truth /gt --estimate /est --out {data.csv}
"""  # noqa: E501 (one case per line)
CASES = [tuple(cell.strip() for cell in line.split("|")) for line in SAME_FILE.strip().splitlines()]


@pytest.mark.parametrize(("name", "command"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_an_output_that_is_an_input_is_refused_and_the_input_kept(
    originals, tmp_path, run_cli, name, command
):
    copies = {}
    for key, original in originals.items():
        copies[key] = tmp_path / key
        shutil.copy(original, copies[key])
    before = {key: p.read_bytes() for key, p in copies.items()}
    for key, path in copies.items():
        command = command.replace("{" + key + "}", shlex.quote(str(path)))
    res = run_cli(*shlex.split(command))
    assert res.code == 2, res.stderr
    assert res.stderr.startswith("error: ") and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert f"is also the input {name}; writing it would destroy that input" in res.stderr
    assert {key: p.read_bytes() for key, p in copies.items()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(copies)  # nothing else written


def test_an_output_reached_through_a_link_is_the_input(originals, tmp_path, run_cli):
    data = tmp_path / "data.csv"
    shutil.copy(originals["data.csv"], data)
    (tmp_path / "link.csv").symlink_to(data)
    before = data.read_bytes()
    res = run_cli("train", tmp_path / "link.csv", "--out", data, "--epochs", "1")
    assert res.code == 2 and "is also the input DATA" in res.stderr
    assert data.read_bytes() == before


def test_a_failed_demo_leaves_no_files_and_keeps_the_old_ones(tmp_path, run_cli, monkeypatch):
    """The demo writes its six files only once every step has succeeded."""
    from ipcverify import demo

    out = tmp_path / "demo"
    out.mkdir()
    (out / "train.csv").write_text("an earlier run's file\n", encoding="utf-8")
    res = run_cli("demo", "--n", "3", "--out", out, "--force")
    assert res.code == 2 and "the demo needs --n between 100 and 10,000,000; got 3" in res.stderr
    assert [p.name for p in out.iterdir()] == ["train.csv"]

    def calibration_fails(*args, **kwargs):
        raise demo.InvalidInputError("calibration failed")

    monkeypatch.setattr(demo, "calibrate", calibration_fails)  # a failure after training
    res = run_cli("demo", "--n", "150", "--out", out / "new")
    assert res.code == 2 and res.stderr == "error: calibration failed\n"
    assert not (out / "new").exists()
    assert (out / "train.csv").read_text(encoding="utf-8") == "an earlier run's file\n"


def test_the_demo_refuses_bad_sizes_before_computing_anything(tmp_path):
    from ipcverify.demo import run_demo
    from ipcverify.errors import InvalidInputError

    for kwargs, match in (
        ({"n_train": 99}, r"n_train between 100 and 10,000,000; got 99"),
        ({"n_train": 10**7 + 1}, r"got 10000001"),
        ({"n_train": np.float64(500.0)}, r"got np\.float64\(500\.0\)"),
        ({"n_calibration": 687}, r"n_calibration between 688 and"),
        ({"seed": -1}, r"the demo's seed must be a non-negative integer; got -1"),
    ):
        with pytest.raises(InvalidInputError, match=match):
            run_demo(tmp_path / "d", **kwargs)
    assert not (tmp_path / "d").exists()
