"""docgen/docs_certify.py: the worked example of docs/certify.md and its pictures."""

from __future__ import annotations

import json

import numpy as np

from docgen.docs_certify import FIGURES, main, run_example
from ipcverify import load_model
from ipcverify.contract._prediction import predict_sets
from ipcverify.data import PerceptionInputs, load_dataset

QUICK = ("--epochs", "2")


def test_the_example_certifies_what_an_independent_count_of_the_test_set_finds(tmp_path):
    numbers = run_example(tmp_path, n=3000, train_args=QUICK)["numbers"]
    on_disk = json.loads((tmp_path / "certificate" / "certificate.json").read_text())
    assert on_disk["test"]["violations"] == numbers["test_violations"]
    assert on_disk["test"]["n"] == numbers["test_n"] == 1500  # the 50 % test split
    model = load_model(tmp_path / "calibrated.pt")
    test = load_dataset(tmp_path / "test.csv")
    pred = predict_sets(model, PerceptionInputs(test.x, test.yhat))
    scores = np.linalg.norm(np.einsum("bij,bj->bi", pred.shapes, test.y - pred.centers), axis=1)
    assert int((scores > 1.0).sum()) == numbers["test_violations"]
    assert numbers["calibration_n"] == 750 and 0 < numbers["calibration_k"] <= 750


def test_main_writes_the_three_figures_and_the_numbers(tmp_path):
    numbers = main(
        [
            "--n",
            "3000",
            "--img",
            str(tmp_path),
            "--out",
            str(tmp_path / "n.json"),
            "--train-args",
            "--epochs 2",
        ]
    )
    assert json.loads((tmp_path / "n.json").read_text()) == numbers
    for name in FIGURES:
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_numbers_docs_certify_quotes_are_those_of_the_committed_run():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    page = (root / "docs" / "certify.md").read_text()
    r = json.loads((root / "docgen" / "docs_certify_results.json").read_text())
    assert r["n_samples"] == 20_000 and r["train_args"] == []  # the page's example, as written
    quoted = [
        f"│ {r['calibration_n']} │ {r['calibration_k']} │ {r['calibration_scale']:>7.5g} │",
        f"is at most {r['certified_epsilon']:.3g}",
        f"{r['test_violations']} of {r['test_n']} fresh test samples",
        f"is at most {r['test_upper_bound']:.4g}",
        f"│ mean log-volume    │ {r['mean_log_volume']:.2f}",
        f"│ domain of validity │ as expected in distribution: {r['domain_outside']}/{r['test_n']} test "
        "queries outside",
    ]
    assert [q for q in quoted if q not in page] == []
