"""Shared test fixtures and helpers (strict numerics for every test: ../conftest.py)."""

from __future__ import annotations

import dataclasses

import pytest


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
