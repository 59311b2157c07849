"""``python -m case_studies.quad_landing reproduce --quick``: the summary's structure and the paper's claims.

The claims are checked as far as the quick sizes can support them (Clopper--Pearson, one-sided
at the stated confidence; the family of checks below is small and each uses delta <= 0.05):

* Table I: the buffer-1 rate is not significantly above 1 %; lag hurts (every larger buffer's
  rate is significantly above buffer 1's) and the rate never falls significantly as the
  buffer grows.
* Landing: no unsafe IPC landing in any run and all 10 paper-style runs safe; the IPC's safe
  rate is not significantly below 99 %; the baseline is unsafe in most runs (lower bound
  above 1/2).
* The certified bound is at least the empirical unsafe rate and is not contradicted by it.
"""

from __future__ import annotations

import json
import re

import pytest

from case_studies.quad_landing.cli import main
from ipcverify.bounds import clopper_pearson_lower, clopper_pearson_upper

DELTA = 0.05
pytestmark = pytest.mark.slow


def _run(argv: list[str]) -> int:
    try:
        main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    code = _run(["reproduce", "--out", str(out), "--quick", "--quiet"])
    assert code == 0
    return out, json.loads((out / "summary.json").read_text())


def test_summary_has_the_documented_structure(quick):
    _, s = quick
    for b in ("1", "2", "3", "4", "5"):
        row = s["table1"][b]
        assert {"n", "violations", "rate", "upper", "interval", "paper_rate"} <= set(row)
        assert row["n"] >= 300 and 0 <= row["violations"] <= row["n"]
        assert row["rate"] == pytest.approx(row["violations"] / row["n"])
    for side in ("ipc", "baseline"):
        land = s["landing"][side]
        assert {"runs", "safe", "unsafe", "aborted"} <= set(land)
        assert (
            land["safe"] + land["unsafe"] + land["aborted"]
            == land["runs"]
            == s["settings"]["sizes"]["mc_runs"]
        )
        assert land["paper_runs"]["runs"] == 10
    # summary.json is a published format: these keys are never renamed or removed
    assert set(s) >= {
        "format", "version", "quick", "settings", "seeds", "paper", "ipc", "table1", "table1_rising",
        "landing", "landing_buffer1", "machine", "jobs", "backend", "claims", "stage_seconds",
        "runtime_seconds",
    }  # fmt: skip
    assert set(s["landing"]) >= {
        "buffer_size", "tracking_tolerance", "max_measurements", "ipc", "baseline", "closed_loop", "coverage",
    }  # fmt: skip
    assert set(s["claims"]) == {
        "table1_buffer1_at_most_1pct", "table1_rates_rising", "ipc_safe_99pct_monte_carlo",
        "ipc_safe_all_paper_runs", "baseline_unsafe_in_most_runs", "certified_bound_at_least_empirical",
    }  # fmt: skip
    assert all(set(c) == {"holds", "supported", "detail"} for c in s["claims"].values())
    assert set(s["ipc"]) == {"k1", "k3"} and set(s["landing_buffer1"]) == {"buffer_size", "ipc", "baseline"}
    assert 0 < s["landing"]["ipc"]["certified_unsafe_bound"] <= 1
    assert s["landing"]["coverage"]["shift_detected"] in (True, False)
    assert s["quick"] is True and s["runtime_seconds"] > 0


def test_report_is_one_self_contained_file(quick):
    out, _ = quick
    page = (out / "report.html").read_text()
    assert page.startswith("<!DOCTYPE html>")
    assert not re.search(r"""(src|href)=["'](?!data:)""", page)  # nothing fetched from elsewhere
    assert page.count("data:image/png;base64,") >= 4
    for name in ("table1", "topview", "campaign", "trajectories", "coverage"):
        assert (out / "figures" / f"{name}.png").stat().st_size > 1000
    assert (out / "certificates" / "ipc_k1" / "certificate.json").exists()


def test_table1_claims(quick):
    _, s = quick
    t = s["table1"]
    k, n = t["1"]["violations"], t["1"]["n"]
    assert clopper_pearson_lower(k, n, DELTA) <= 0.01
    up1 = clopper_pearson_upper(k, n, DELTA)
    for b in ("2", "3", "4", "5"):
        assert clopper_pearson_lower(t[b]["violations"], t[b]["n"], DELTA) > up1  # lag hurts
    for a, b in (("1", "2"), ("2", "3"), ("3", "4"), ("4", "5")):
        # no significant decrease from one buffer size to the next
        assert clopper_pearson_upper(t[b]["violations"], t[b]["n"], DELTA) >= clopper_pearson_lower(
            t[a]["violations"], t[a]["n"], DELTA
        )


def test_landing_claims(quick):
    _, s = quick
    ipc, base = s["landing"]["ipc"], s["landing"]["baseline"]
    assert ipc["unsafe"] == 0 and ipc["paper_runs"]["unsafe"] == 0
    assert ipc["paper_runs"]["safe"] == ipc["paper_runs"]["runs"] == 10
    assert clopper_pearson_upper(ipc["safe"], ipc["runs"], DELTA) >= 0.99
    assert clopper_pearson_lower(base["unsafe"], base["runs"], DELTA) > 0.5
    # every accepted landing decision of the IPC re-verified exactly
    assert all(
        r["certificate_verified"] for r in ipc["paper_runs"]["runs_detail"] if r["turnoff"] is not None
    )


def test_certified_bound_claims(quick):
    _, s = quick
    ipc = s["landing"]["ipc"]
    cert = ipc["certified"]
    assert cert["union_bound"] == pytest.approx(min(1.0, cert["max_queries"] * cert["epsilon"]))
    assert cert["refined_bound"] <= cert["union_bound"] + 1e-12
    rate = ipc["unsafe"] / ipc["runs"]
    assert ipc["certified_unsafe_bound"] >= rate
    assert clopper_pearson_lower(ipc["unsafe"], ipc["runs"], DELTA) <= cert["refined_bound"]
    assert s["claims"]["certified_bound_at_least_empirical"]["holds"]


def test_reproduce_reports_bad_input_on_one_line(tmp_path, capsys):
    not_a_dir = tmp_path / "file"
    not_a_dir.write_text("x")
    assert _run(["reproduce", "--out", str(not_a_dir), "--quick", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and ("is a file" in err or "not a directory" in err)
    assert len(err.strip().splitlines()) == 1
    bad = tmp_path / "bad.toml"
    bad.write_text("[landing]\ncap = 3\n")
    assert _run(["reproduce", "--out", str(tmp_path / "o"), "--settings", str(bad), "--quiet"]) == 2
    assert "unknown key landing.cap" in capsys.readouterr().err
