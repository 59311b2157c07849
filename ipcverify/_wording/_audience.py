"""Who reads a message: a Python caller (the default), or a command-line user while a CLI command runs.

The CLI's click group (:class:`ipcverify.cli.app.CliGroup`) runs every command inside
``speaking(Audience.CLI)``; a message made inside is rendered for the command line. The audience
is a context variable, so it is restored when the block ends (also on an error).

Examples
--------
>>> audience().value
'python'
>>> with speaking(Audience.CLI):
...     audience().value
'cli'
"""

from __future__ import annotations

import enum
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar


class Audience(enum.Enum):
    """Who reads a message: a Python caller, or a command-line user."""

    PYTHON = "python"
    CLI = "cli"


_AUDIENCE: ContextVar[Audience] = ContextVar("ipcverify_audience", default=Audience.PYTHON)


def audience() -> Audience:
    """The audience of the running code (:attr:`Audience.PYTHON` unless a CLI command runs)."""
    return _AUDIENCE.get()


@contextmanager
def speaking(to: Audience) -> Iterator[None]:
    """Render every message made inside the block for ``to``.

    Examples
    --------
    >>> with speaking(Audience.CLI):
    ...     audience().value
    'cli'
    >>> audience().value
    'python'
    """
    token = _AUDIENCE.set(to)
    try:
        yield
    finally:
        _AUDIENCE.reset(token)
