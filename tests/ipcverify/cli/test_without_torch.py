"""``predict``, ``monitor``, ``evaluate`` (of a model file) and ``split`` run without torch, same output.

Each command runs in a fresh interpreter in which importing torch raises (a ``sys.meta_path``
blocker), and its output is compared with the model as training made it (built from the torch
network) in this process.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._prediction import monitor_log, predict_sets
from ipcverify.data._dataset import load_dataset, load_inputs, save_dataset
from ipcverify.data._files import write_json
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.io._modelio import save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train

ROOT = Path(__file__).resolve().parents[3]

_BLOCKED = """
import json, sys

class _NoTorch:
    def find_spec(self, name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ImportError(f"torch is blocked in this test ({name})")
        return None

sys.meta_path.insert(0, _NoTorch())
from ipcverify.cli import main
try:
    main(sys.argv[1:])
    code = 0
except SystemExit as exc:
    code = exc.code
print(json.dumps({"code": code, "torch": any(m.split(".")[0] == "torch" for m in sys.modules)}))
"""


def _run_without_torch(*args: object) -> tuple[int, str]:
    res = subprocess.run(
        [sys.executable, "-c", _BLOCKED, *map(str, args)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )
    last = json.loads(res.stdout.strip().splitlines()[-1])
    assert last["torch"] is False
    return last["code"], res.stderr


@pytest.fixture(scope="module", params=["tight", "v1"])
def calibrated(request, tmp_path_factory):
    """A calibrated model of the recipe (with its domain of validity), its file, and data files."""
    d = tmp_path_factory.mktemp(request.param)
    train_ds, cal_ds, log = (make_lagged_perception(n, seed=s) for n, s in ((400, 0), (1200, 1), (300, 2)))
    hidden = {"tight": (8,), "v1": (8, 8)}[request.param]
    mc = ModelConfig.recipe(
        request.param, x_dim=6, y_dim=3, hidden=hidden, **({"members": 2} if request.param == "tight" else {})
    )
    tc = TrainConfig.recipe(request.param, epochs=2, val_fraction=0.0, patience=None)
    model = calibrate(train(train_ds, mc, tc, recipe=request.param).model, cal_ds, 0.05, 0.01)
    assert model.domain is not None and model._network is not None  # built from the torch network
    save_model(model, d / "calibrated.pt")
    save_dataset(log, d / "log.csv")
    return model, d


def test_predict_runs_without_torch_and_gives_the_same_sets(calibrated, tmp_path):
    model, d = calibrated
    code, err = _run_without_torch("predict", d / "calibrated.pt", d / "log.csv", "--out", tmp_path / "s.npz")
    assert code == 0, err
    ref = predict_sets(model, load_inputs(d / "log.csv"))
    with np.load(tmp_path / "s.npz") as got:
        assert np.array_equal(got["center"], ref.centers) and np.array_equal(got["shape"], ref.shapes)
        assert np.array_equal(got["in_domain"], ref.in_domain)
        assert np.array_equal(got["domain_distance"], ref.distance)


def test_monitor_and_evaluate_run_without_torch(calibrated, tmp_path):
    model, d = calibrated
    code, err = _run_without_torch("monitor", d / "calibrated.pt", d / "log.csv", "--out", tmp_path / "m")
    assert code in (0, 1), err
    ref = monitor_log(model, load_dataset(d / "log.csv"))
    write_json(tmp_path / "ref.json", ref)
    got = json.loads((tmp_path / "m" / "monitor.json").read_text())
    assert got == json.loads((tmp_path / "ref.json").read_text())  # every number, exactly
    assert (code == 1) == (ref.alarm_index is not None)
    assert (tmp_path / "m" / "monitor.png").read_bytes()[:4] == b"\x89PNG"
    code, err = _run_without_torch("evaluate", d / "calibrated.pt", d / "log.csv", "--json")
    assert code == 0, err


def test_split_runs_without_torch_and_writes_the_parts_split_file_writes(tmp_path):
    log = ROOT / "data" / "euroc_mh04_vislam.csv"
    code, err = _run_without_torch(
        "split", log, "--by", "method,run", "--out", tmp_path / "cli", "--seed", "4"
    )
    assert code == 0, err
    from ipcverify.data import split_file

    lib = split_file(log, tmp_path / "lib", group_column=["method", "run"], seed=4)
    for p in lib.parts:
        assert (tmp_path / "cli" / p.path.name).read_bytes() == p.path.read_bytes()
