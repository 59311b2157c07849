"""The HTML report as a person sees it: images decode, nothing loads from the network, it renders.

Headless Chromium renders the page: its DOM holds the executive summary's fields before every
other section, the summary starts on the first screen, and the banner is green for a strong
target and amber for a weak one.
"""

from __future__ import annotations

import base64
import html
import io
import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import ipcverify
from ipcverify.certification._certify import certify, labelled, write_certificate
from ipcverify.certification._report_head import display_text
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train

CHROMIUM = Path("/usr/bin/chromium")


@pytest.fixture(scope="module")
def trained():
    data = make_lagged_perception(1200, seed=60)
    model = train(
        data,
        ModelConfig(x_dim=6, y_dim=3, hidden=(16,), param="cholesky"),
        TrainConfig.recipe("v1", epochs=2),
    ).model
    return model, data


@pytest.fixture(scope="module")
def written(trained, tmp_path_factory):
    model, data = trained
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
    # the calibration's n is the rows its threshold used (one per flight for a flight-level one)
    n = res.certificate.calibration.n
    assert f"<th>calibration samples used n</th><td>{n:,}</td>" in page
    assert "counts its rows as independent samples" not in page  # no group column: nothing to caveat


def test_report_without_calibration_or_training_data(tmp_path):
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(4,), param="cholesky")))
    res = certify(m, make_lagged_perception(300, seed=63))
    write_certificate(res, tmp_path)
    page = (tmp_path / "report.html").read_text()
    assert "<b>Absent.</b>" in page and "Not computed: training data not given" in page
    assert len(_images(page)) == 3


def test_one_dimensional_truth_renders(tmp_path):
    rng = np.random.default_rng(0)
    from ipcverify.data._dataset import PerceptionDataset

    ds = PerceptionDataset(rng.normal(size=(400, 2)), rng.normal(size=(400, 1)), rng.normal(size=(400, 1)))
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=1, hidden=(4,), param="cholesky")))
    write_certificate(certify(m, ds), tmp_path)
    for raw in _images((tmp_path / "report.html").read_text()):
        Image.open(io.BytesIO(raw)).load()


FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]  # fmt: skip
STRONG_GREEN, WEAK_AMBER = (0x1B, 0x7F, 0x3B), (0xF5, 0xB4, 0x00)


@pytest.fixture(scope="module")
def weak(trained, tmp_path_factory):
    """The same network calibrated to a weak target (epsilon = 0.5), with units and labels."""
    cal = calibrate(trained[0], make_lagged_perception(1500, seed=61), 0.5, 0.01)
    res = labelled(
        certify(cal, make_lagged_perception(2000, seed=62)), units="m", labels=("forward", "left", "up")
    )
    out = tmp_path_factory.mktemp("weak")
    write_certificate(res, out)
    return out / "report.html", res


def _chromium(tmp_path: Path, page: Path, *args: str) -> str:
    if not CHROMIUM.exists():
        pytest.fail("the report tests need Debian's chromium: apt-get install -y chromium")
    profile = tmp_path / f"profile-{len(list(tmp_path.iterdir()))}"  # a fresh profile per run
    cmd = [str(CHROMIUM), *FLAGS, f"--user-data-dir={profile}", *args, page.as_uri()]
    return subprocess.run(cmd, check=True, capture_output=True, text=True, timeout=120).stdout


def _text(fragment: str) -> str:
    """The visible text of an HTML fragment, whitespace collapsed."""
    return " ".join(html.unescape(re.sub(r"<[^>]+>", " ", fragment)).split())


def test_the_summary_as_chromium_renders_it(weak, tmp_path):
    """The DOM Chromium builds from the page holds the summary's fields, before every other section."""
    dom = _chromium(tmp_path, weak[0], "--dump-dom")
    s = weak[1].certificate.summary
    assert dom.count('<section id="summary">') == 1
    top, rest = dom.split('<section id="summary">')
    summary, after = rest.split("</section>", 1)
    assert "<h2>" not in top and "<h2>Calibration</h2>" in after  # nothing comes before the summary
    banner = _text(re.search(r'<p class="status" id="verdict"[^>]*>(.*?)</p>', top).group(1))
    assert banner == s.verdict_text("ε")
    assert banner.startswith("CERTIFIED, WEAK TARGET (ε = 0.5: up to half the truths may lie outside)")
    text = _text(summary)
    assert f"What is guaranteed. {s.claim}" in text
    assert "target violation rate ε 0.5: weak target (ε ≥ 0.1)" in text
    assert "confidence parameter δ 0.01 (the claim holds with probability ≥ 0.99)" in text
    assert f"unit of the claim {s.unit_text()}" in text
    assert "perceived quantity y forward, left, up, in m" in text
    for c in s.checks:
        assert f"{c.name[:1].upper()}{c.name[1:]} {c.verdict} {display_text(c.detail)}" in text
    assert f"date (UTC, ISO 8601) {s.date_utc}" in text and re.fullmatch(
        r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", s.date_utc
    )
    assert f"ipcverify version {ipcverify.__version__}" in text
    assert f"network SHA-256 {s.model_sha256}" in text
    for what, digest in s.data_sha256.items():
        assert f"{what} SHA-256 {digest}" in text


def test_the_summary_is_at_the_top_of_the_first_screen(weak, written, tmp_path):
    """Measured in the rendered layout (a probe script in a copy of the page; the page has none)."""
    for page in (weak[0], written[0]):
        probe = tmp_path / f"probe-{page.parent.name}.html"
        measure = (
            "<script>function r(q){const b=document.querySelector(q).getBoundingClientRect();"
            "return [b.top,b.bottom];}document.body.setAttribute('data-probe',JSON.stringify({verdict:"
            "r('#verdict'),summary:r('#summary'),checks:r('#summary table.checks')}));</script></body>"
        )
        probe.write_text(page.read_text().replace("</body>", measure))
        dom = _chromium(tmp_path, probe, "--window-size=1100,900", "--dump-dom")
        box = json.loads(html.unescape(re.search(r'data-probe="([^"]*)"', dom).group(1)))
        assert box["verdict"][0] < 150 and box["summary"][0] < 250  # the verdict, then the summary
        assert box["checks"][0] < 600  # the checks table starts on the first screen


def _banner_pixels(rgb: np.ndarray, color: tuple[int, int, int]) -> int:
    return int((np.abs(rgb.astype(int) - np.array(color)).max(axis=-1) <= 6).sum())


def test_the_banner_is_green_for_a_strong_target_and_amber_for_a_weak_one(weak, written, tmp_path):
    """Screenshots: the first 200 rows of pixels hold the banner, in the colour of the target's strength."""
    counts = {}
    for name, page in (("strong", written[0]), ("weak", weak[0])):
        shot = tmp_path / f"{name}.png"
        _chromium(tmp_path, page, "--hide-scrollbars", "--window-size=1100,800", f"--screenshot={shot}")
        im = Image.open(shot)
        im.load()
        assert im.size == (1100, 800)
        rgb = np.asarray(im.convert("RGB"))
        counts[name] = (_banner_pixels(rgb[:200], STRONG_GREEN), _banner_pixels(rgb[:200], WEAK_AMBER))
        gray = np.asarray(im.convert("L"), dtype=float)
        assert (gray[200:] < 128).any(axis=1).mean() > 0.3  # the summary's text and tables fill the screen
    assert (
        written[1].certificate.summary.strength == "strong" and weak[1].certificate.summary.strength == "weak"
    )
    # a banner about 900 x 40 px: tens of thousands of pixels of its colour, none of the other
    assert counts["strong"][0] > 20_000 and counts["strong"][1] == 0
    assert counts["weak"][1] > 20_000 and counts["weak"][0] == 0
