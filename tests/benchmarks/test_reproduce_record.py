"""benchmarks/reproduce_record.py: the full reproduction's numbers that the docs quote."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.reproduce_record import extract, main

ROOT = Path(__file__).resolve().parents[2]
RECORD = json.loads((ROOT / "benchmarks" / "reproduce_full_results.json").read_text())


def _outcomes(o: dict) -> str:
    return f"{o['safe']} / {o['unsafe']} / {o['aborted']}"


def _contract_row(name: str, c: dict) -> str:
    """The row of the three contracts' table as `reproduce` prints it."""
    rates = " | ".join(f"{100 * c['table1'][str(b)]:.2f} %" for b in range(1, 6))
    widths = " / ".join(f"{100 * w:.1f}" for w in c["hover_half_widths_median"])
    mc = c["landing"]
    paper = _outcomes(c["landing_paper_runs"])
    return f"| {name} | {rates} | {paper} | {_outcomes(mc)} of {mc['runs']} | {widths} |"


def test_the_results_page_quotes_the_recorded_full_run():
    page = (ROOT / "docs" / "reproduce_results.md").read_text()
    rows = [_contract_row(name, c) for name, c in RECORD["contracts"].items()]
    assert len(rows) == 3 and [r for r in rows if r not in page] == []
    for name, c in RECORD["contracts"].items():
        counts = " | ".join(
            f"{100 * v / n:.2f} % ({v}/{n};" for v, n in (c["table1_counts"][str(b)] for b in range(1, 6))
        )
        assert all(part in page for part in counts.split(" | ")), name
    cert = RECORD["contracts"]["default_calibrated"]["certified"]
    quoted = (
        f"≤ {100 * cert['union']:.2f} % (M = 8 measurements × ε = 0.001961; "
        f"refined with the measured number of measurements: {100 * cert['refined']:.2f} %)"
    )
    assert quoted in page
    base = RECORD["baseline"]
    assert f"{base['unsafe']}/{base['runs']} unsafe" in page


def test_the_readme_quotes_the_recorded_full_run():
    readme = " ".join((ROOT / "README.md").read_text().split())
    cert = RECORD["contracts"]["default_calibrated"]["certified"]
    assert f"Certified P(unsafe) ≤ {100 * cert['union']:.2f} %" in readme
    assert f"refined with the measured number of measurements: {100 * cert['refined']:.2f} %" in readme
    base = RECORD["baseline"]
    assert f"the baseline fails in {base['unsafe']} of {base['runs']}" in readme


def test_extract_refuses_a_quick_summary_and_main_writes_what_it_extracts(tmp_path):
    with pytest.raises(ValueError, match="--quick"):
        extract({"quick": True})
    summary = {
        "quick": False,
        "version": 1,
        "landing": {"baseline": {"runs": 3, "safe": 1, "unsafe": 2, "aborted": 0, "extra": 0.5}},
        "contracts": {
            "c": {
                "table1": {"1": 0.5},
                "table1_detail": {"1": {"violations": 1, "n": 2, "rate": 0.5}},
                "landing": {"runs": 3, "safe": 3, "unsafe": 0, "aborted": 0},
                "landing_paper_runs": None,
                "hover_half_widths": {"median": [0.01, 0.02, 0.03]},
                "empirical_vs_certified": {"certified_union": 0.1, "certified_refined": 0.05},
            }
        },
    }
    (tmp_path / "s.json").write_text(json.dumps(summary))
    record = main([str(tmp_path / "s.json"), "--out", str(tmp_path / "r.json")])
    assert json.loads((tmp_path / "r.json").read_text()) == record
    assert record["baseline"] == {"runs": 3, "safe": 1, "unsafe": 2, "aborted": 0}
    c = record["contracts"]["c"]
    assert c["table1_counts"] == {"1": [1, 2]} and c["landing_paper_runs"] is None
    assert c["certified"] == {"union": 0.1, "refined": 0.05}
