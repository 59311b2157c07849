"""benchmarks/bench_unseen_logs.py: the documented pipeline on real logs, followed as its messages say."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from benchmarks.bench_unseen_logs import (
    DELTA,
    EPSILON,
    MH04_LOG,
    OUT,
    Log,
    _advice,
    _radius,
    findings,
    markdown_table,
    refusal,
    replay_table,
    run_log,
)
from ipcverify.calibration._share_bound import run_floor

ROOT = Path(__file__).resolve().parents[2]
EXCERPT = ROOT / "tests" / "ipcverify" / "io" / "ingest" / "data" / "euroc_mh04"
RECORD = json.loads(OUT.read_text())


def _named_epsilon(message: str) -> str:
    """The smallest epsilon a refusal for too few runs names."""
    return message.split("the smallest is ", 1)[1].split(" ", 1)[0]


def test_the_page_shows_the_records_tables():
    page = (ROOT / "docs" / "real_logs.md").read_text()
    assert markdown_table(RECORD) in page
    assert replay_table(RECORD) in page
    assert findings(RECORD) in page  # every number of "What the logs show" comes from the record
    assert f"({RECORD['runtime_seconds']:.0f} s on 2 cores)" in page
    readme = " ".join((ROOT / "README.md").read_text().split())
    last = [log["steps"][-1] for log in RECORD["logs"]]
    eps = sorted(step["certified_epsilon"] for step in last)
    alarm = RECORD["cross_room"]["monitor"]["domain_alarm_index"]
    assert (
        f"refuses ε = {RECORD['epsilon']:g} and names the smallest ε their runs allow "
        f"({eps[0]:g} to {eps[-1]:g})"
    ) in readme
    assert f"raises its out-of-domain alarm after {alarm + 1} of 20 runs" in readme


def test_every_log_follows_its_refusals_to_a_claim_about_runs():
    for log in RECORD["logs"]:
        steps = log["steps"]
        assert steps[0]["options"] == [] and steps[0]["refused_at"] == "calibrate"
        for before, after in zip(steps, steps[1:], strict=False):  # each step does what the last said
            if "several columns could name the runs" in before["message"]:
                assert after["options"][:2] == ["--group-column", log["group_column_name"]]
            if "too few" in before["message"]:
                assert after["options"][-2:] == ["--epsilon", _named_epsilon(before["message"])]
        done = steps[-1]
        assert done["status"] == "CERTIFIED" and done["unit"] == "run"
        assert done["unit_column"] == log["group_column_name"] == done["by_runs"]["column"]
        runs = done["calibration_runs"]
        assert runs["n_runs"] == log["parts"]["calibration"]["groups"]
        # the smallest epsilon named is at least the floor 1 - delta^(1/G) (proofs/run_claims.md §1)
        assert run_floor(runs["n_runs"], DELTA) <= done["certified_epsilon"] == done["epsilon"] < 1
        r = done["by_runs"]
        assert r["runs"] == log["parts"]["test"]["groups"] and 0 <= r["with_violation"] <= r["runs"]
        assert r["lower"] <= r["mean_share"] <= r["upper"] and r["lower"] <= done["certified_epsilon"]
        assert done["test"]["statistic"] == "mean" and done["test"]["rate"] == r["mean_share"]
        assert 0 <= done["rows_outside"] <= done["test_rows"] == log["parts"]["test"]["rows"]
        if runs["design_effect"] is not None:
            assert runs["effective_rows"] <= runs["n_rows"]


def test_the_monitor_is_silent_on_held_out_runs_and_alarms_in_another_room():
    logs = {log["name"]: log for log in RECORD["logs"]}
    for name in ("KITTI 00", MH04_LOG.name):  # the acceptance: no alarm on held-out blocks and flights
        log, mon = logs[name], logs[name]["monitor"]
        assert not mon["alarm"] and not mon["domain_alarm"] and mon["exit"] == 0
        assert mon["observations"] == log["parts"]["test"]["groups"] == len(mon["shares"])
        assert mon["epsilon"] == log["steps"][-1]["certified_epsilon"]
        # the monitor's per-run shares are the certificate's: their mean is its test statistic
        mean = sum(mon["shares"]) / len(mon["shares"])
        assert abs(mean - log["steps"][-1]["by_runs"]["mean_share"]) < 1e-6
    cross = RECORD["cross_room"]
    mon = cross["monitor"]
    assert mon["observations"] == 20 and len(mon["runs"]) == 20 and sum(mon["run_rows"]) == cross["rows"]
    assert mon["epsilon"] == logs[MH04_LOG.name]["steps"][-1]["certified_epsilon"]
    assert mon["domain_alarm"], "the MH_04 contract replayed in V1_02 raises no alarm"
    i = mon["domain_alarm_index"]
    crossed = [k for k, v in enumerate(mon["domain_log_e"]) if v >= mon["alarm_level"]]
    assert crossed[0] == i  # the alarm is where the e-value first reaches ln(1/delta)
    assert abs(sum(mon["shares"]) / 20 - cross["steps"][0]["by_runs"]["mean_share"]) < 1e-6
    assert all(s < mon["epsilon"] for s in mon["shares"]) and not mon["alarm"]  # why no violation alarm
    assert cross["steps"][0]["shift_warning"]  # the certificate in V1_02 warns of the shift
    refused = cross["refusals"]
    assert refused["certify"]["exit"] == refused["monitor"]["exit"] == 2  # the runs' column is not named
    named = refused["monitor --group-column run"]  # named: the same replay, the same domain alarm
    assert named["exit"] == 1 and f"DOMAIN ALARM at group {mon['runs'][i]!r}" in named["message"]


@pytest.mark.slow
def test_a_small_real_log_is_refused_then_certified_as_the_refusal_says(tmp_path):
    # the committed excerpt of the MH_04 files: 4 runs of at most 20 s, split in 2 s segments
    stems = ["vislam_rp_0", "vislam_rp_5", "vislam_ba_0", "vislam_ba_3"]
    ingest = ["--max-gap", "3", "--truth", "{evo}/groundtruth.txt.gz"]
    for stem in stems:
        ingest += ["--estimate", f"{{evo}}/{stem}.txt"]
    log = Log(
        "excerpt", "MH_04 excerpt", tuple(ingest), ("--block", "2", "--name-groups", "segment"), "segment"
    )
    got = run_log(log, {"rpg": tmp_path, "evo": EXCERPT}, tmp_path)
    first, second, *later = got["steps"]
    # the runs and the segments could both be the units: calibrate asks, the next step says
    assert first["refused_at"] == "calibrate" and "several columns could name the runs" in first["message"]
    assert second["options"] == ["--group-column", "segment"]
    # a few segments are too few for epsilon = 0.1: the refusal names the smallest, the next step uses it
    assert second["refused_at"] == "calibrate" and "too few" in second["message"]
    named = _named_epsilon(second["message"])
    assert later and later[0]["options"] == ["--group-column", "segment", "--epsilon", named]
    done = later[0]
    assert done["status"] in ("CERTIFIED", "CONTRADICTED") and done["unit"] == "run"
    assert done["certified_epsilon"] == float(named) > EPSILON
    r = done["by_runs"]
    assert r["runs"] == got["parts"]["test"]["groups"] and done["test"]["n"] == r["runs"]
    assert r["lower"] <= r["mean_share"] <= r["upper"] <= 1
    assert done["rows_outside"] <= done["test_rows"] == got["parts"]["test"]["rows"]
    assert got["rows"] == sum(p["rows"] for p in got["parts"].values())


def test_advice_follows_only_what_a_message_asks_for():
    ambiguous = {
        "refused_at": "calibrate",
        "message": "error: c.csv: several columns could name the runs ('segment' (10 groups), "
        "'run' (2 groups)); say which one's groups are independent runs, ... (CLI: --group-column COL), "
        "or ... (CLI: --unit row)",
    }
    assert _advice(ambiguous, [], "segment") == ["--group-column", "segment"]
    few = {
        "refused_at": "calibrate",
        "message": "error: 10 groups of column 'segment' are too few for a pac expected-share claim at "
        "epsilon=0.1, delta=0.01: at least 46 groups are needed. ...; collect more independent groups, "
        "or raise --epsilon (with 10 groups the smallest is 0.378 at this delta) or --delta, or use --mode "
        "marginal",
    }
    options = ["--group-column", "segment"]
    assert _advice(few, options, "segment") == [*options, "--epsilon", "0.378"]
    assert refusal(few["message"]) == "10 segments are too few for ε = 0.1; the smallest they allow is 0.378"
    none = {**few, "message": few["message"].replace("0.378", "1")}
    assert _advice(none, options, "segment") is None  # nothing below 1 to raise it to
    domain = "error: the domain test at flag rate 0.01 needs at least 99 calibration inputs; got 57"
    refused = {
        "refused_at": "calibrate",
        "message": f"{domain} -- ... (with 57 inputs the flag rate must be at least 1/58: --domain-flag-rate 0.0173 works)",  # noqa: E501
    }
    assert _advice(refused, [], "run") == ["--domain-flag-rate", "0.0173"]
    both = {"refused_at": "calibrate", "message": f"error: 2 requirements are not met: (1) ... (2) {domain}"}
    assert _advice(both, [], "run") is None  # the guarantee itself is out of reach, and no value is named
    told = "refit it with whole groups (calibrate --domain-group-column run --domain-flag-rate 0.091) to tell"
    shifted = {"shift_warning": True, "domain_statement": f"... shifted, or ...; {told} the two apart."}
    assert _advice(shifted, ["--domain-flag-rate", "0.018"], "run") == [
        "--domain-group-column", "run", "--domain-flag-rate", "0.091"
    ]  # fmt: skip
    assert _advice({**shifted, "shift_warning": False}, [], "run") is None


def test_the_radius_is_the_balls_with_that_volume():
    assert abs(_radius(math.log(4 / 3 * math.pi * 2.0**3), 3) - 2.0) < 1e-12
