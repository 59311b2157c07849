"""docs/quickstart.md's real-log section, run as written on the bundled log: a certificate about flights.

The commands between ``<!-- quickstart:runs -->`` markers are run one by one from a copy of the
repository's ``data/`` folder, exactly as the page types them; the certificate must state its
unit (flights) and the epsilon the flights allow, and the page's numbers must be the ones the
commands print.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "quickstart.md"


def _commands() -> list[list[str]]:
    text = PAGE.read_text(encoding="utf-8")
    block = re.search(r"<!-- quickstart:runs -->\n```bash\n(.*?)```\n<!-- /quickstart:runs -->", text, re.S)
    assert block is not None, "the quickstart's real-log block is missing"
    return [shlex.split(line) for line in block.group(1).splitlines() if line.strip()]


@pytest.mark.slow
def test_the_quickstart_ends_in_a_certificate_about_flights(run_cli, tmp_path):
    shutil.copytree(ROOT / "data", tmp_path / "data")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        outputs = []
        for argv in _commands():
            assert argv[0] == "ipcverify"
            res = run_cli(*argv[1:])
            assert res.code == 0, f"{' '.join(argv)}: {res.stderr}"
            outputs.append(res)
    finally:
        os.chdir(cwd)
    page = " ".join(PAGE.read_text(encoding="utf-8").split())
    plan = " ".join(outputs[2].stdout.split())
    found = re.search(
        r"the smallest expected share of a new run's rows outside that can be certified is ([0-9.]+)", plan
    )
    assert found is not None and f"at δ = 0.05 is {found.group(1)}" in page
    need = re.search(r"an expected share of 0.1 needs at least (\d+) runs", plan)
    assert need is not None and f"(an expected share of 0.1 would need {need.group(1)} flights)" in page
    cert = json.loads((tmp_path / "mh04" / "certificate" / "certificate.json").read_text())
    assert cert["summary"]["unit"] == "group" and cert["summary"]["unit_column"] == "flight"
    assert (
        cert["calibration"]["guarantee_kind"] == "expected-share" and cert["calibration"]["epsilon"] == 0.33
    )
    assert cert["runs"]["n_runs"] == 8 and cert["test"]["n"] == 4 and cert["test"]["statistic"] == "mean"
    verdict = outputs[-1].stdout.splitlines()[0]
    assert verdict.startswith(cert["status"]) and cert["status"] in ("CERTIFIED", "CONTRADICTED")
    assert "expected fraction of a new group's samples" in cert["summary"]["claim"]
    assert "at most 0.33" in cert["summary"]["claim"]
    # the same commands at epsilon 0.1 are refused, naming the smallest epsilon the flights allow
    argv = [a if a != "0.33" else "0.1" for a in _commands()[3]]
    os.chdir(tmp_path)
    try:
        refused = run_cli(*argv[1:], "--force")
    finally:
        os.chdir(cwd)
    assert refused.code == 2 and f"the smallest is {found.group(1)}" in refused.stderr
