"""Tests of safe model files."""

from __future__ import annotations

import os

import numpy as np
import pytest
import torch

from ipcverify.contract._model import IPCModel, IPCNetwork, network_fingerprint
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import ModelFileError
from ipcverify.io._modelio import load_model, save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train


def test_save_load_gives_identical_outputs(tmp_path):
    ds = make_lagged_perception(300, seed=0)
    model = train(ds, train_config=TrainConfig(epochs=2)).model
    p = tmp_path / "m.pt"
    save_model(model, p)
    back = load_model(p)
    a, b = model.predict_unguarded(ds.x, ds.yhat), back.predict_unguarded(ds.x, ds.yhat)
    assert np.array_equal(a.centers, b.centers)
    assert np.array_equal(a.shapes, b.shapes)
    assert back.metadata["train_data_hash"] == ds.content_hash()
    assert back.config == model.config


def test_malicious_model_file_is_refused_and_never_runs(tmp_path, runs_code):
    marker = tmp_path / "PWNED"
    p = tmp_path / "evil.pt"
    torch.save({"format": "ipcverify-model", "format_version": 1, "x": runs_code(str(marker))}, p)
    # sanity: the payload does run when loaded unsafely
    torch.load(p, weights_only=False)
    assert marker.exists()
    marker.unlink()
    with pytest.raises(ModelFileError, match=r"refused to load: the file holds objects other than tensors"):
        load_model(p)
    assert not marker.exists()


def test_not_a_model_file(tmp_path):
    p = tmp_path / "junk.pt"
    p.write_bytes(b"definitely not a zip or pickle")
    with pytest.raises(ModelFileError, match=r"junk\.pt: not a readable model file"):
        load_model(p)


def test_other_torch_file(tmp_path):
    p = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, p)
    with pytest.raises(ModelFileError, match="not an ipcverify model file"):
        load_model(p)


def test_future_version(tmp_path):
    p = tmp_path / "v9.pt"
    torch.save({"format": "ipcverify-model", "format_version": 9}, p)
    with pytest.raises(
        ModelFileError,
        match=r"model format version 9 is not supported \(this ipcverify reads versions 1, 2\)",
    ):
        load_model(p)


def _drop_a_weight(state):
    del state["body.0.weight"]


def _nan_bias(state):
    state["body.0.bias"][0] = float("nan")


@pytest.mark.parametrize(
    ("damage", "match"),
    [
        pytest.param(_drop_a_weight, "damaged model file", id="missing-weight"),
        pytest.param(_nan_bias, r"parameter 'body\.0\.bias' holds non-finite values", id="non-finite-weight"),
    ],
)
def test_a_damaged_state_dict_is_refused(tmp_path, damage, match):
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(4,), param="cholesky")))
    p = tmp_path / "m.pt"
    save_model(m, p)
    payload = torch.load(p, weights_only=True)
    damage(payload["state_dict"])
    torch.save(payload, p)
    with pytest.raises(ModelFileError, match=match):
        load_model(p)


def test_save_is_atomic(tmp_path, monkeypatch):
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(4,), param="cholesky")))
    p = tmp_path / "m.pt"
    save_model(m, p)
    before = p.read_bytes()

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(torch, "save", boom)
    with pytest.raises(OSError):
        save_model(m, p)
    assert p.read_bytes() == before
    assert os.listdir(tmp_path) == ["m.pt"]


def test_paper_head_files_stay_version_1_and_lowrank_files_are_version_2(tmp_path):
    ds = make_lagged_perception(300, seed=0)
    for recipe, version in (("v1", 1), ("paper", 1), ("tight", 2)):
        model = train(ds, train_config=TrainConfig.recipe(recipe, epochs=1), recipe=recipe).model
        p = tmp_path / f"{recipe}.pt"
        save_model(model, p)
        payload = torch.load(p, weights_only=True)
        assert payload["format_version"] == version
        if version == 1:  # exactly the keys an ipcverify without the low-rank head reads
            assert set(payload["config"]) == {"x_dim", "y_dim", "hidden", "param", "center", "activation"}
        back = load_model(p)
        assert back.config == model.config and network_fingerprint(back.network) == network_fingerprint(
            model.network
        )
        np.testing.assert_array_equal(
            back.predict_unguarded(ds.x, ds.yhat).shapes, model.predict_unguarded(ds.x, ds.yhat).shapes
        )


def test_a_file_written_before_the_lowrank_head_loads_unchanged(tmp_path):
    """A version-1 file as ipcverify wrote it before recipes existed: built by hand, no new keys."""
    torch.manual_seed(3)
    net = IPCNetwork(ModelConfig(x_dim=2, y_dim=3, param="cholesky"))
    config = {
        "x_dim": 2,
        "y_dim": 3,
        "hidden": [64, 128],
        "param": "cholesky",
        "center": "offset",
        "activation": "relu",
    }
    payload = {
        "format": "ipcverify-model",
        "format_version": 1,
        "config": config,
        "state_dict": net.state_dict(),
        "metadata": {"train_config": {"epochs": 20, "alpha": 1.0}},
        "calibration": None,
        "domain": None,
    }
    p = tmp_path / "old.pt"
    torch.save(payload, p)
    back = load_model(p)
    assert back.config == ModelConfig.recipe("v1", x_dim=2, y_dim=3)
    assert network_fingerprint(back.network) == network_fingerprint(net)
    x, yhat = np.ones((4, 2)), np.zeros((4, 3))
    np.testing.assert_array_equal(
        back.predict_unguarded(x, yhat).shapes, IPCModel(net).predict_unguarded(x, yhat).shapes
    )


def test_a_lowrank_network_in_a_version_1_file_is_refused(tmp_path):
    model = train(make_lagged_perception(200, seed=0), train_config=TrainConfig(epochs=1)).model
    p = tmp_path / "m.pt"
    save_model(model, p)
    payload = torch.load(p, weights_only=True)
    payload["format_version"] = 1
    torch.save(payload, p)
    with pytest.raises(
        ModelFileError,
        match=r"damaged model file .a lowrank network in a version-1 file \(it needs version 2\)",
    ):
        load_model(p)


def test_a_layout_the_torch_free_reader_does_not_know_is_read_by_torch(tmp_path, monkeypatch):
    import ipcverify.io._modelio as modelio
    from ipcverify.io._torchfile import NeedsTorchError

    ds = make_lagged_perception(200, seed=0)
    model = train(ds, train_config=TrainConfig(epochs=1)).model
    p = tmp_path / "m.pt"
    save_model(model, p)
    direct = load_model(p)

    def unknown(path):
        raise NeedsTorchError("a later torch's layout")

    monkeypatch.setattr(modelio, "read_torch_file", unknown)
    via_torch = load_model(p)  # torch.load(weights_only=True), tensors turned into arrays
    assert (
        via_torch.weights.fingerprint() == direct.weights.fingerprint() == network_fingerprint(model.network)
    )
    np.testing.assert_array_equal(
        via_torch.predict_unguarded(ds.x, ds.yhat).shapes, direct.predict_unguarded(ds.x, ds.yhat).shapes
    )


def test_a_torch_object_in_a_model_file_is_refused_by_torch_too(tmp_path):
    p = tmp_path / "module.pt"
    torch.save({"format": "ipcverify-model", "format_version": 2, "net": torch.nn.Linear(2, 2)}, p)
    with pytest.raises(ModelFileError, match=r"refused to load: the file holds objects other than tensors"):
        load_model(p)


def test_row_fingerprints_are_written_as_int64_tensors_and_read_back_without_torch(tmp_path, monkeypatch):
    import ipcverify.io._modelio as modelio
    from ipcverify.contract._calibrate import calibrate
    from ipcverify.data._fingerprints import ROWS_KEY, SCHEME, recorded_rows, row_fingerprints
    from ipcverify.io._torchfile import read_torch_file

    train_ds, cal_ds = make_lagged_perception(300, seed=0), make_lagged_perception(400, seed=1)
    model = calibrate(train(train_ds, train_config=TrainConfig(epochs=1)).model, cal_ds, 0.1, 0.05)
    p = tmp_path / "m.pt"
    save_model(model, p)
    stored = read_torch_file(p)["row_fingerprints"]  # the torch-free reader: plain int64 arrays
    assert stored["scheme"] == SCHEME and stored["training"].dtype == np.int64
    assert len(stored["training"]) == 300 and len(stored["calibration"]) == 400  # 8 bytes a row

    def no_torch(*args, **kwargs):
        raise AssertionError("torch.load was called")

    monkeypatch.setattr(torch, "load", no_torch)
    back = load_model(p)
    for role, ds in (("training", train_ds), ("calibration", cal_ds)):
        rows = recorded_rows(back.metadata, role)
        assert rows.dtype == np.uint64 and not rows.flags.writeable
        np.testing.assert_array_equal(rows, np.unique(row_fingerprints(ds)))
        np.testing.assert_array_equal(rows, recorded_rows(model.metadata, role))
    assert set(back.metadata[ROWS_KEY]) == {"scheme", "training", "calibration"}
    assert "row_fingerprints" not in {k for k, v in read_torch_file(p)["metadata"].items()}  # not plain data
    assert modelio.ROWS_KEY == ROWS_KEY


@pytest.mark.parametrize(
    ("damage", "match"),
    [
        (lambda t: t.flip(0), "the fingerprints are not sorted and distinct"),
        (lambda t: t.to(torch.float64), "expected a 1-D int64 array"),
        (lambda t: t.reshape(1, -1), "expected a 1-D int64 array"),
    ],
)
def test_damaged_row_fingerprints_are_refused(tmp_path, damage, match):
    model = train(make_lagged_perception(200, seed=0), train_config=TrainConfig(epochs=1)).model
    p = tmp_path / "m.pt"
    save_model(model, p)
    payload = torch.load(p, weights_only=True)
    payload["row_fingerprints"]["training"] = damage(payload["row_fingerprints"]["training"])
    torch.save(payload, p)
    with pytest.raises(ModelFileError, match=rf"damaged row-fingerprint record \(training: {match}"):
        load_model(p)


def test_a_file_without_row_fingerprints_reads_with_none(tmp_path):
    from ipcverify.data._fingerprints import ROWS_KEY

    model = train(make_lagged_perception(200, seed=0), train_config=TrainConfig(epochs=1)).model
    p = tmp_path / "m.pt"
    save_model(model, p)
    payload = torch.load(p, weights_only=True)
    del payload["row_fingerprints"]  # as ipcverify wrote model files before them
    torch.save(payload, p)
    back = load_model(p)
    assert (
        ROWS_KEY not in back.metadata
        and back.metadata["train_data_hash"] == model.metadata["train_data_hash"]
    )
