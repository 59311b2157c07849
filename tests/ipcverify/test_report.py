"""The HTML report as a person sees it: images decode, nothing loads from the network, it renders."""

from __future__ import annotations

import base64
import io
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ipcverify.architecture import ModelConfig
from ipcverify.calibrate import calibrate
from ipcverify.certify import certify, write_certificate
from ipcverify.model import IPCModel, IPCNetwork
from ipcverify.synthetic import make_lagged_perception
from ipcverify.training import TrainConfig, train

CHROMIUM = Path("/usr/bin/chromium")


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    data = make_lagged_perception(1200, seed=60)
    model = train(
        data,
        ModelConfig(x_dim=6, y_dim=3, hidden=(16,), param="cholesky"),
        TrainConfig.recipe("v1", epochs=2),
    ).model
    cal = calibrate(model, make_lagged_perception(1500, seed=61), 0.05, 0.01)
    res = certify(cal, make_lagged_perception(2000, seed=62), train_data=data)
    out = tmp_path_factory.mktemp("report")
    write_certificate(res, out)
    return out / "report.html", res


def _images(page: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)]


def test_every_embedded_image_decodes(written):
    page = written[0].read_text()
    imgs = _images(page)
    assert len(imgs) == 3 == page.count("<img ")
    for raw in imgs:
        im = Image.open(io.BytesIO(raw))
        im.load()
        assert im.format == "PNG" and im.width >= 300 and im.height >= 200
        arr = np.asarray(im.convert("L"), dtype=float)
        assert arr.std() > 5  # not a blank canvas


def test_page_references_no_network_resource(written):
    full = written[0].read_text()
    page = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]+", "data:", full)  # base64 may contain '//'
    assert not re.search(r"(?i)(https?:|ftp:|//[a-z0-9])", page)
    assert not re.search(r"(?i)<(script|link|iframe|object|embed)\b", page)
    assert not re.search(r"(?i)@import|url\(", page)
    for src in re.findall(r'(?i)(?:src|href)="([^"]*)"', full):
        assert src.startswith("data:image/png;base64,")


def test_page_says_what_is_guaranteed(written):
    page = written[0].read_text()
    res = written[1]
    assert "What is guaranteed" in page and "exchangeable" in page
    assert "Theorem 1 is vacuous" in page and "NOT a guarantee" in page
    assert f"{res.certificate.test.violations:,}" in page


def test_report_without_calibration_or_training_data(tmp_path):
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(4,), param="cholesky")))
    res = certify(m, make_lagged_perception(300, seed=63))
    write_certificate(res, tmp_path)
    page = (tmp_path / "report.html").read_text()
    assert "<b>Absent.</b>" in page and "Not computed: training data not given" in page
    assert len(_images(page)) == 3


def test_one_dimensional_truth_renders(tmp_path):
    rng = np.random.default_rng(0)
    from ipcverify.data import PerceptionDataset

    ds = PerceptionDataset(rng.normal(size=(400, 2)), rng.normal(size=(400, 1)), rng.normal(size=(400, 1)))
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=1, hidden=(4,), param="cholesky")))
    write_certificate(certify(m, ds), tmp_path)
    for raw in _images((tmp_path / "report.html").read_text()):
        Image.open(io.BytesIO(raw)).load()


def test_headless_chromium_screenshot(written, tmp_path):
    if not CHROMIUM.exists():
        pytest.fail("the report screenshot test needs Debian's chromium: apt-get install -y chromium")
    shot = tmp_path / "shot.png"
    cmd = [
        str(CHROMIUM),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--hide-scrollbars",
        "--window-size=1100,3600",
        f"--screenshot={shot}",
        written[0].as_uri(),
    ]
    subprocess.run(cmd, check=True, capture_output=True, timeout=120)
    im = Image.open(shot)
    im.load()
    assert im.size == (1100, 3600)
    gray = np.asarray(im.convert("L"), dtype=float)
    # the page is rendered: dark text and the embedded plots cover a good part of the shot
    rows_with_ink = (gray < 128).any(axis=1).mean()
    assert rows_with_ink > 0.3
    # the green status banner is visible near the top
    top = np.asarray(im.convert("RGB"))[:300].reshape(-1, 3).astype(int)
    assert ((top[:, 1] > 100) & (top[:, 0] < 60) & (top[:, 2] < 90)).sum() > 1000
