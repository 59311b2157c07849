"""Rules that tools check: ruff clean and formatted, fully typed (mypy, library and case study)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_ruff_is_clean():
    if shutil.which("ruff") is None:
        pytest.fail("ruff is missing: pip install -e '.[dev]'")
    res = subprocess.run(["ruff", "check", "."], cwd=ROOT, capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr


@pytest.mark.slow
def test_ruff_format_is_clean():
    if shutil.which("ruff") is None:
        pytest.fail("ruff is missing: pip install -e '.[dev]'")
    res = subprocess.run(["ruff", "format", "--check", "."], cwd=ROOT, capture_output=True, text=True)
    assert res.returncode == 0, "run `ruff format .`:\n" + res.stdout + res.stderr


@pytest.mark.slow
def test_mypy_is_clean():
    res = subprocess.run(
        [sys.executable, "-m", "mypy", "ipcverify", "case_studies"], cwd=ROOT, capture_output=True, text=True
    )
    assert res.returncode == 0, res.stdout + res.stderr
