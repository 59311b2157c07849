"""The wording layer: how a parameter, a remedy or a verdict is said, to Python users and on the CLI.

Library code states facts and typed remedies (:class:`Remedy`: which parameter, what value); it
never spells a command-line flag. This module is the one place that knows both spellings of a
parameter (:data:`PARAMETERS`) and renders them for the audience of the running code: Python
(``flag_rate=0.0173``) by default, the command line (``--domain-flag-rate 0.0173``) while a CLI
command runs (:func:`speaking`, entered by the CLI's click group).

Examples
--------
>>> option("flag_rate", 0.0173)
'flag_rate=0.0173'
>>> with speaking(Audience.CLI):
...     option("flag_rate", 0.0173)
'--domain-flag-rate 0.0173'
>>> render(Remedy("epsilon", 0.2))
'epsilon=0.2'
"""

from __future__ import annotations

import enum
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass


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


@dataclass(frozen=True)
class Spelling:
    """One parameter as a Python caller and a CLI user spell it.

    Attributes
    ----------
    python : str
        The keyword argument (``"flag_rate"``) or call (``"Global()"``) in Python.
    cli : str
        The command-line flag (``"--domain-flag-rate"``).
    """

    python: str
    cli: str

    def __post_init__(self) -> None:
        if not self.python or not self.cli.startswith("-"):
            raise ValueError(f"a spelling needs a Python name and a CLI flag; got {self!r}")


#: Every parameter a library message may name, by its library name.
PARAMETERS: dict[str, Spelling] = {
    "flag_rate": Spelling("flag_rate", "--domain-flag-rate"),
    "domain_group_column": Spelling("DomainSpec(group_column=...)", "--domain-group-column"),
    "epsilon": Spelling("epsilon", "--epsilon"),
    "delta": Spelling("delta", "--delta"),
    "gamma": Spelling("gamma", "--gamma"),
    "group_column": Spelling("group_column", "--group-column"),
}


def option(name: str, value: object = None) -> str:
    """``name`` (with ``value``) as the current audience writes it.

    Parameters
    ----------
    name : str
        A key of :data:`PARAMETERS`.
    value : object, optional
        The value to show; floats are written with ``:g``.

    Raises
    ------
    KeyError
        If ``name`` is not a known parameter (a bug: add its spelling to :data:`PARAMETERS`).
    """
    spelled = PARAMETERS[name]
    shown = None if value is None else (f"{value:g}" if isinstance(value, float) else str(value))
    if audience() is Audience.CLI:
        return spelled.cli if shown is None else f"{spelled.cli} {shown}"
    return spelled.python if shown is None else f"{spelled.python}={shown}"


@dataclass(frozen=True)
class Remedy:
    """What would meet a refused requirement: a parameter and the value to give it.

    Attributes
    ----------
    parameter : str
        A key of :data:`PARAMETERS`.
    value : float, int, str or None
        The value that works (None: the parameter itself is the remedy).
    """

    parameter: str
    value: float | int | str | None = None

    def __post_init__(self) -> None:
        if self.parameter not in PARAMETERS:
            raise ValueError(f"unknown parameter {self.parameter!r}: add its spelling to PARAMETERS")


def render(remedy: Remedy) -> str:
    """The remedy as the current audience writes it (see :func:`option`)."""
    return option(remedy.parameter, remedy.value)


def flag_rate_floor(n: int, units: str, smallest: float) -> str:
    """What ``n`` calibration inputs (or groups) allow the domain test's flag rate.

    Examples
    --------
    >>> flag_rate_floor(57, "inputs", 0.0173)
    'with 57 inputs the flag rate must be at least 1/58: flag_rate=0.0173 works'
    """
    return f"with {n} {units} the flag rate must be at least 1/{n + 1}: {option('flag_rate', smallest)} works"
