"""Shared test fixtures and helpers."""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


@dataclasses.dataclass(frozen=True)
class CliResult:
    """What one CLI invocation produced."""

    code: int
    stdout: str
    stderr: str


@pytest.fixture
def run_cli(capsys: pytest.CaptureFixture[str]):
    """Run ``ipcverify ARGS`` in-process; returns a :class:`CliResult`."""
    from ipcverify.cli import main

    def _run(*args: str) -> CliResult:
        capsys.readouterr()
        try:
            main([str(a) for a in args])
            code = 0
        except SystemExit as exc:  # main always exits
            code = int(exc.code or 0)
        out = capsys.readouterr()
        return CliResult(code, out.out, out.err)

    return _run


@pytest.fixture(autouse=True)
def _strict_numpy():
    """Turn silent floating-point trouble into errors inside tests."""
    with np.errstate(invalid="raise", divide="raise", over="raise"):
        yield
