"""benchmarks/bench_unseen_logs.py: the documented pipeline on real logs, followed as its messages say."""

from __future__ import annotations

import json
import math
from pathlib import Path

from benchmarks.bench_unseen_logs import (
    DELTA,
    OUT,
    Log,
    _advice,
    _radius,
    findings,
    markdown_table,
    run_log,
)
from ipcverify.calibration._bounds import clopper_pearson_upper

ROOT = Path(__file__).resolve().parents[2]
EXCERPT = ROOT / "tests" / "ipcverify" / "io" / "ingest" / "data" / "euroc_mh04"


def test_the_page_shows_the_records_table():
    record = json.loads(OUT.read_text())
    page = (ROOT / "docs" / "real_logs.md").read_text()
    assert markdown_table(record) in page
    assert findings(record) in page  # every number of "What the logs show" comes from the record
    assert f"({record['runtime_seconds']:.0f} s on 2 cores)" in page
    statuses = [s["status"] for s in record["cross_room"]["steps"]]
    assert statuses == ["CONTRADICTED", "CONTRADICTED"]  # the other room is never certified
    c0 = record["cross_room"]["steps"][0]  # the README quotes the room change
    readme = " ".join((ROOT / "README.md").read_text().split())
    rate, allowed = 100 * c0["test_rate"], 100 * c0["certified_epsilon"]
    assert (
        f"is CONTRADICTED ({rate:.1f} % violations against {allowed:.2f} % allowed, "
        f"{100 * c0['outside_fraction']:.1f} % of the queries outside its domain)"
    ) in readme
    monitor = record["cross_room"]["monitor"]
    assert monitor["v102"]["alarm"] and not monitor["mh04_test"]["alarm"]
    assert f"raises its alarm at row {monitor['v102']['alarm_index']:,} of" in " ".join(page.split())


def test_a_small_real_log_is_refused_then_certified_as_the_refusal_says(tmp_path):
    # the committed excerpt of the MH_04 files: 4 runs of at most 20 s
    stems = ["vislam_rp_0", "vislam_rp_5", "vislam_ba_0", "vislam_ba_3"]
    ingest = ["--max-gap", "3", "--truth", "{evo}/groundtruth.txt.gz"]
    for stem in stems:
        ingest += ["--estimate", f"{{evo}}/{stem}.txt"]
    log = Log(
        "excerpt", "MH_04 excerpt", tuple(ingest), ("--block", "2", "--name-groups", "segment"), "segment"
    )
    got = run_log(log, {"rpg": tmp_path, "evo": EXCERPT}, tmp_path)
    first, *later = got["steps"]
    assert first["refused_at"] == "calibrate" and "alpha must be at least" in first["message"]
    named = first["message"].rsplit("--domain-alpha ", 1)[1].split(" works)")[0]
    assert later and later[0]["options"] == ["--domain-alpha", named]
    done = [s for s in later if "test_rate" in s]
    assert done, later
    for step in done:  # the record's numbers are the certificate's own, and consistent
        k, n = step["test_violations"], step["test_n"]
        assert step["test_rate"] == k / n
        assert abs(step["test_upper"] - clopper_pearson_upper(k, n, DELTA)) < 1e-12
    assert got["rows"] == sum(p["rows"] for p in got["parts"].values())


def test_advice_follows_only_what_a_message_asks_for():
    domain = "error: the domain test at alpha=0.01 needs at least 99 calibration inputs; got 57"
    refused = {
        "refused_at": "calibrate",
        "message": f"{domain} -- ... (with 57 inputs alpha must be at least 1/58: --domain-alpha 0.0173 works)",  # noqa: E501
    }
    assert _advice(refused, []) == ["--domain-alpha", "0.0173"]
    both = {"refused_at": "calibrate", "message": f"error: 2 requirements are not met: (1) ... (2) {domain}"}
    assert _advice(both, []) is None  # the guarantee itself is out of reach
    told = "refit it with whole groups (calibrate --domain-group-column run --domain-alpha 0.091) to tell"
    shifted = {"shift_warning": True, "domain_statement": f"... shifted, or ...; {told} the two apart."}
    assert _advice(shifted, ["--domain-alpha", "0.018"]) == [
        "--domain-group-column", "run", "--domain-alpha", "0.091"
    ]  # fmt: skip
    assert _advice({**shifted, "shift_warning": False}, []) is None


def test_the_radius_is_the_balls_with_that_volume():
    assert abs(_radius(math.log(4 / 3 * math.pi * 2.0**3), 3) - 2.0) < 1e-12
