"""Tests of the ONNX export: ONNX Runtime reproduces the model's sets; unexportable models are refused."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")

from ipcverify.calibration import Mondrian  # noqa: E402
from ipcverify.contract._calibrate import calibrate  # noqa: E402
from ipcverify.data._synthetic import make_lagged_perception  # noqa: E402
from ipcverify.errors import InvalidInputError  # noqa: E402
from ipcverify.io._modelio import save_model  # noqa: E402
from ipcverify.io._onnx import build_onnx, check_onnx, export_onnx, onnx_session  # noqa: E402
from ipcverify.network._architecture import ModelConfig  # noqa: E402
from ipcverify.training._train import TrainConfig, train  # noqa: E402


@pytest.fixture(scope="module")
def data():
    return make_lagged_perception(1500, seed=0), make_lagged_perception(1500, seed=1)


def _model(data, **kw):
    kw = {"hidden": (16, 32), **kw}
    return train(data[0], ModelConfig(x_dim=6, y_dim=3, **kw), TrainConfig(epochs=2)).model


@pytest.mark.parametrize(
    "kw",
    [
        {},
        {"members": 1, "linear_center": False, "activation": "tanh", "hidden": (8,)},
        {"param": "cholesky"},
        {"param": "full"},
        {"param": "cholesky", "center": "raw", "activation": "tanh"},
    ],
    ids=["lowrank-ensemble", "lowrank-1-tanh", "chol", "full", "raw-tanh"],
)
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_onnx_runtime_reproduces_the_calibrated_sets(data, tmp_path, kw, dtype):
    model = calibrate(_model(data, **kw), data[1], 0.05, 0.01)
    info = export_onnx(model, tmp_path / "ipc.onnx", dtype=dtype, without_domain=True)
    assert info.calibrated and info.scale == model.calibration.threshold.scale
    test = make_lagged_perception(300, seed=2)
    chk = check_onnx(model, info.path, test.x, test.yhat)
    engine_tol = 1e-12 if dtype == "float64" else 1e-5
    assert max(chk.vs_engine_center, chk.vs_engine_shape) <= engine_tol
    assert chk.passes(1e-5)  # torch runs in float32


def test_the_calibration_is_in_the_graph(data, tmp_path):
    raw = _model(data)
    cal = calibrate(raw, data[1], 0.05, 0.01)
    test = make_lagged_perception(5, seed=3)
    outs = []
    for m, name in ((raw, "raw.onnx"), (cal, "cal.onnx")):
        export_onnx(m, tmp_path / name, without_domain=True)
        outs.append(onnx_session(tmp_path / name).run(["shape"], {"x": test.x, "yhat": test.yhat})[0])
    np.testing.assert_allclose(outs[1] * cal.calibration.threshold.scale, outs[0], rtol=1e-12, atol=0)
    meta = build_onnx(cal, without_domain=True).metadata_props
    props = {p.key: p.value for p in meta}
    assert props["calibrated"] == "true" and float(props["scale"]) == cal.calibration.threshold.scale
    assert props["mode"] == "pac" and props["domain_test"] == "not included"
    assert {p.key: p.value for p in build_onnx(raw).metadata_props}["domain_test"] == "none in the model"


def test_a_model_with_a_domain_test_is_exported_only_without_it_on_request(data, tmp_path):
    cal = calibrate(_model(data), data[1], 0.05, 0.01)
    assert cal.domain is not None
    with pytest.raises(InvalidInputError, match=r"domain-of-validity test .* pass without_domain=True"):
        export_onnx(cal, tmp_path / "cal.onnx")
    assert not (tmp_path / "cal.onnx").exists()
    no_domain = calibrate(_model(data), data[1], 0.05, 0.01, domain=None)
    assert export_onnx(no_domain, tmp_path / "plain.onnx").calibrated  # nothing left out: no flag needed


def test_mondrian_models_are_refused(data, tmp_path):
    m = calibrate(
        _model(data), make_lagged_perception(3000, seed=4), 0.1, 0.05, Mondrian(column="x_5", bins=2)
    )
    with pytest.raises(
        InvalidInputError, match=r"calibrated per group \(2 quantile bins of x_5\).*calibrate it globally"
    ):
        export_onnx(m, tmp_path / "m.onnx")
    assert not (tmp_path / "m.onnx").exists()


def test_bad_dtype_and_float64_elu_are_refused(data, tmp_path):
    with pytest.raises(InvalidInputError, match="dtype must be 'float64' or 'float32'"):
        export_onnx(_model(data), tmp_path / "a.onnx", dtype="float16")  # type: ignore[arg-type]
    elu = _model(data, activation="elu")
    with pytest.raises(InvalidInputError, match="no float64 Elu"):
        export_onnx(elu, tmp_path / "b.onnx")
    info = export_onnx(elu, tmp_path / "c.onnx", dtype="float32")
    test = make_lagged_perception(50, seed=5)
    assert check_onnx(elu, info.path, test.x, test.yhat).passes(1e-5)


def test_cli_export_writes_and_checks(run_cli, data, tmp_path):
    model = calibrate(_model(data), data[1], 0.05, 0.01)
    save_model(model, tmp_path / "model.pt")
    res = run_cli("export", tmp_path / "model.pt", "--onnx", tmp_path / "model.onnx")
    assert res.code == 2 and not (tmp_path / "model.onnx").exists()
    assert res.stderr.startswith("error: this model carries a domain-of-validity test")
    assert "pass --no-domain" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    res = run_cli("export", tmp_path / "model.pt", "--onnx", tmp_path / "model.onnx", "--no-domain")
    assert res.code == 0, res.stderr
    assert (tmp_path / "model.onnx").is_file()
    assert "calibrated (scale" in res.stdout and "checked in ONNX Runtime" in res.stdout
    assert res.stderr.startswith("warning: the ONNX graph has no domain-of-validity test")


def test_cli_export_refuses_mondrian_with_exit_2(run_cli, data, tmp_path):
    m = calibrate(
        _model(data), make_lagged_perception(3000, seed=4), 0.1, 0.05, Mondrian(column="x_5", bins=2)
    )
    save_model(m, tmp_path / "mondrian.pt")
    res = run_cli("export", tmp_path / "mondrian.pt", "--onnx", tmp_path / "m.onnx")
    assert res.code == 2
    assert res.stderr.startswith("error: cannot export a model calibrated per group")
    assert len(res.stderr.strip().splitlines()) == 1
