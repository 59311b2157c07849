"""CLI: prove-containment and check-certificate."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

BALL = {"type": "ellipsoid", "center": [0.0, 0.0], "shape": [[1.0, 0.0], [0.0, 1.0]]}
HALF_BALL = {"type": "ellipsoid", "center": [0.1, 0.0], "shape": [[2.0, 0.0], [0.0, 2.0]]}
PROBLEMS = [
    {"inner": BALL, "outer": {"type": "box", "lower": [-1.0, -1.0], "upper": [1.0, 1.0]}},
    {"inner": BALL, "outer": {"type": "box", "lower": [-0.5, -1.0], "upper": [1.0, 1.0]}},
    {"inner": HALF_BALL, "outer": BALL},
    {"inner": BALL, "outer": HALF_BALL},
    {"inner": BALL, "outer": {"type": "polytope", "A": [[1.0, 1.0]], "b": [1.4142135623730951]}},
    {"inner": BALL, "outer": {"type": "polytope", "A": [[1.0, 1.0]], "b": [2.0]}, "method": "socp"},
]
EXPECTED = ["PROVEN", "REFUTED", "PROVEN", "REFUTED", "PROVEN", "PROVEN"]


def _write(path: Path, data) -> Path:
    path.write_text(json.dumps(data))
    return path


def test_prove_then_check(tmp_path, run_cli):
    out = tmp_path / "certs.json"
    res = run_cli("prove-containment", _write(tmp_path / "p.json", PROBLEMS), "--out", out)
    assert res.code == 0, res.stderr
    certs = json.loads(out.read_text())
    assert [c["status"] for c in certs] == EXPECTED
    assert "problem 1: REFUTED" in res.stdout
    # inputs round-trip exactly, including the float sqrt(2)
    assert certs[4]["outer"]["b"] == [1.4142135623730951]
    res = run_cli("check-certificate", out)
    assert res.code == 0, res.stdout + res.stderr
    assert f"all {len(PROBLEMS)} certificates re-verified" in res.stdout
    assert not list(tmp_path.glob(".*tmp"))  # no temp file left behind


def test_single_problem_object(tmp_path, run_cli):
    out = tmp_path / "c.json"
    res = run_cli("prove-containment", _write(tmp_path / "p.json", PROBLEMS[0]), "--out", out)
    assert res.code == 0
    assert [c["status"] for c in json.loads(out.read_text())] == ["PROVEN"]


def test_check_certificate_fails_on_a_forged_proof(tmp_path, run_cli):
    out = tmp_path / "certs.json"
    run_cli("prove-containment", _write(tmp_path / "p.json", PROBLEMS[:3]), "--out", out)
    certs = json.loads(out.read_text())
    certs[0]["outer"]["upper"] = [0.9, 1.0]  # claims PROVEN, no longer true
    forged = _write(tmp_path / "forged.json", certs)
    res = run_cli("check-certificate", forged)
    assert res.code == 1
    assert "certificate 0: FAILED: claims PROVEN" in res.stdout
    assert "certificate 2: PROVEN re-verified" in res.stdout
    assert "1 of 3 certificates failed: 0" in res.stdout


def test_check_certificate_fails_on_a_bad_witness(tmp_path, run_cli):
    out = tmp_path / "certs.json"
    run_cli("prove-containment", _write(tmp_path / "p.json", PROBLEMS[1:2]), "--out", out)
    certs = json.loads(out.read_text())
    certs[0]["witness"] = [0.0, 0.0]
    res = run_cli("check-certificate", _write(tmp_path / "bad.json", certs))
    assert res.code == 1
    assert "claims REFUTED" in res.stdout


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("{not json", "not valid JSON"),
        ("3", "expected one problem object"),
        (json.dumps([PROBLEMS[0], {"inner": BALL}]), "problem 1: field 'outer' is missing"),
        (
            json.dumps([{"inner": BALL, "outer": {"type": "box", "lower": [0.0, 0.0], "upper": ["a", 1.0]}}]),
            r"problem 0: field 'outer.upper\[0\]'",
        ),
        (
            json.dumps([{"inner": {**BALL, "shape": [[1.0, 2.0], [2.0, 4.0]]}, "outer": BALL}]),
            "problem 0: field 'inner'.*singular",
        ),
    ],
)
def test_bad_problems_give_one_line_errors(tmp_path, run_cli, content, match):
    import re

    p = tmp_path / "p.json"
    p.write_text(content)
    out = tmp_path / "out.json"
    res = run_cli("prove-containment", p, "--out", out)
    assert res.code == 2
    assert res.stderr.startswith("error: ")
    assert len(res.stderr.strip().splitlines()) == 1
    assert re.search(match, res.stderr), res.stderr
    assert not out.exists()


def test_bad_certificate_file(tmp_path, run_cli):
    res = run_cli("check-certificate", _write(tmp_path / "c.json", [{"status": "MAYBE"}]))
    assert res.code == 2
    assert "certificate 0: field 'status'" in res.stderr


def test_existing_output_survives_a_failed_run(tmp_path, run_cli):
    out = tmp_path / "certs.json"
    out.write_text("old")
    p = tmp_path / "p.json"
    p.write_text("[{}]")
    assert run_cli("prove-containment", p, "--out", out).code == 2
    assert out.read_text() == "old"


def test_method_sdp_decides_boxes_and_polytopes_by_the_s_lemma(tmp_path, run_cli):
    out = tmp_path / "certs.json"
    res = run_cli("prove-containment", _write(tmp_path / "p.json", PROBLEMS), "--out", out, "--method", "sdp")
    assert res.code == 0, res.stderr
    certs = json.loads(out.read_text())
    assert [c["status"] for c in certs] == EXPECTED  # the same verdicts as the closed form
    # every problem without its own method is decided by the SDP; problem 5 names socp
    assert [c["method"] for c in certs] == ["sdp"] * 5 + ["socp"]
    assert "problem 0: PROVEN (sdp, box" in res.stdout
    assert len(certs[0]["multipliers"]["lambda"]) == 4  # one multiplier per face
    res = run_cli("check-certificate", out)
    assert res.code == 0, res.stdout
    assert "face LMIs" in res.stdout


def test_method_that_does_not_apply_names_the_problem(tmp_path, run_cli):
    out = tmp_path / "certs.json"
    res = run_cli(
        "prove-containment", _write(tmp_path / "p.json", PROBLEMS), "--out", out, "--method", "socp"
    )
    assert res.code == 2
    assert "error: " in res.stderr and "problem 2: method 'socp' does not apply to an ellipsoid" in res.stderr
    assert "--method socp" in res.stderr
    assert not out.exists()  # nothing is written when a problem is refused


def test_unknown_method_option_is_a_usage_error(tmp_path, run_cli):
    res = run_cli(
        "prove-containment",
        _write(tmp_path / "p.json", PROBLEMS),
        "--out",
        tmp_path / "c.json",
        "--method",
        "lmi",
    )
    assert res.code == 2
    assert "Invalid value for '--method'" in res.stderr and "'closed-form', 'socp', 'sdp'" in res.stderr
