"""`ingest trajectories` rebuilds the shared real log (data/euroc_mh04_vislam.csv) from its public sources.

The committed excerpt (data/euroc_mh04/README.md) holds the first 20 s of two real-time runs
(vislam_rp) and the first 30 s of two bundle-adjusted runs (vislam_ba, keyframes up to 2.1 s
apart here, hence --max-gap 3). The rows built from it must be the log's rows of those runs,
row for row: every sample start in the excerpt's span, the same values to 1e-6 (the log
is written with 7 significant digits).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ipcverify.io.ingest import IngestOptions, ingest_trajectories

ROOT = Path(__file__).resolve().parents[4]
EXCERPT = Path(__file__).resolve().parent / "data" / "euroc_mh04"
LOG = ROOT / "data" / "euroc_mh04_vislam.csv"
NUMBERS = [
    *(f"x_{i}" for i in range(5)),
    *(f"y_{i}" for i in range(3)),
    *(f"yhat_{i}" for i in range(3)),
    "t",
]
RUNS = {"vislam_rp": (0, 5), "vislam_ba": (0, 3)}


def _expected(method: str, run: int, span: float) -> pd.DataFrame:
    log = pd.read_csv(LOG)
    rows = log[(log["method"] == method) & (log["run"] == run) & (log["t"] + 0.5 < span)]
    return rows.reset_index(drop=True)


@pytest.mark.parametrize("method", sorted(RUNS))
def test_library_rebuilds_the_rows_of_the_shared_log(method):
    runs = RUNS[method]
    df = ingest_trajectories(
        EXCERPT / "groundtruth.txt.gz",
        [EXCERPT / f"{method}_{k}.txt" for k in runs],
        runs=[str(k) for k in runs],
        options=IngestOptions(max_gap=3.0),
        tags={"method": method},
    )
    for k in runs:
        est = np.loadtxt(EXCERPT / f"{method}_{k}.txt")
        want = _expected(method, k, est[-1, 0] - est[0, 0])
        got = df[df["run"] == str(k)].reset_index(drop=True)
        assert len(got) == len(want) > 60
        np.testing.assert_allclose(got[NUMBERS].to_numpy(), want[NUMBERS].to_numpy(), rtol=0, atol=1e-6)


def test_the_default_max_gap_drops_the_samples_across_keyframe_gaps():
    df = ingest_trajectories(EXCERPT / "groundtruth.txt.gz", [EXCERPT / "vislam_ba_0.txt"], runs=["0"])
    est = np.loadtxt(EXCERPT / "vislam_ba_0.txt")
    assert 0 < len(df) < len(_expected("vislam_ba", 0, est[-1, 0] - est[0, 0])) / 2
    dropped = df.attrs["ipcverify.io.ingest"]["runs"][0]["dropped"]
    assert dropped["estimate_gap"] > 0 and dropped["truth_gap"] == 0


def test_cli_rebuilds_them_and_writes_the_manifest(run_cli, tmp_path):
    out = tmp_path / "rp.csv"
    res = run_cli(
        "ingest", "trajectories", "--truth", EXCERPT / "groundtruth.txt.gz",
        "--estimate", EXCERPT / "vislam_rp_0.txt", "--estimate", EXCERPT / "vislam_rp_5.txt",
        "--run", "0", "--run", "5", "--format", "tum", "--max-gap", "3", "--tag", "method=vislam_rp",
        "--out", out,
    )  # fmt: skip
    assert res.code == 0, res.stderr
    assert "run 0: 78 of 78 samples kept; dropped: none" in res.stdout
    got = pd.read_csv(out)
    assert list(got.columns) == [*NUMBERS[:-1], "run", "t", "method"]
    est = np.loadtxt(EXCERPT / "vislam_rp_5.txt")
    want = _expected("vislam_rp", 5, est[-1, 0] - est[0, 0])
    np.testing.assert_allclose(got[got["run"] == 5][NUMBERS].to_numpy(), want[NUMBERS].to_numpy(), atol=1e-6)
    manifest = json.loads((tmp_path / "rp.manifest.json").read_text())
    assert manifest["options"]["max_gap"] == 3.0 and manifest["rows"] == len(got)
    assert [i["role"] for i in manifest["inputs"]] == ["truth", "estimate", "estimate"]
    assert (
        manifest["inputs"][1]["sha256"]
        == __import__("hashlib").sha256((EXCERPT / "vislam_rp_0.txt").read_bytes()).hexdigest()
    )
    assert manifest["tags"] == {"method": "vislam_rp"} and manifest["ipcverify_version"]
