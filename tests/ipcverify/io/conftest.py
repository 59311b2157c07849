"""Fixtures of the model-file tests."""

from __future__ import annotations

import pytest


class _RunsCode:
    """Unpickling this object opens (creates) the file ``marker``: proof that the file's code ran."""

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def __reduce__(self):
        return (open, (self.marker, "w"))


@pytest.fixture
def runs_code() -> type[_RunsCode]:
    """The class of a pickled payload that would run code (create its marker file) when loaded."""
    return _RunsCode
