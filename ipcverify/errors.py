"""Exceptions raised by ipcverify.

Every error a user can cause by bad input subclasses :class:`InvalidInputError`
(itself a :class:`ValueError`); the CLI turns those into a one-line message and
exit status 2. Messages state the rule that was broken and what to do about it.

Data that can be used but probably should not be as it is raises a :class:`DataWarning`
(a Python warning); advice that may not apply is a :class:`Hint`. The CLI prints each as one
``warning:`` or ``hint:`` line on stderr.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ipcverify._wording._spelling import Remedy

__all__ = [
    "IPCVerifyError",
    "InvalidInputError",
    "DataError",
    "ModelFileError",
    "SetError",
    "SampleSizeError",
    "IPCVerifyWarning",
    "DataWarning",
    "Hint",
]


class IPCVerifyError(Exception):
    """Base class of every error raised on purpose by ipcverify.

    An error whose fix is a parameter value carries it as facts: :attr:`remedies`, each a
    :class:`~ipcverify._wording._spelling.Remedy` (which parameter, what value) with which the
    refused call succeeds, all else equal. The message says the same in words, for the audience of
    the running code (``--domain-flag-rate 0.091`` on the command line, ``flag_rate=0.091`` in
    Python).

    Attributes
    ----------
    remedies : tuple of Remedy
        Parameter values that fix the error, each on its own (empty: none is known).

    Examples
    --------
    >>> from ipcverify import calibrate, example
    >>> ex = example(200)
    >>> try:
    ...     calibrate(calibrate(ex.model, ex.data, 0.2, 0.05, domain=None), ex.data, 0.2, 0.05)
    ... except InvalidInputError as err:
    ...     print(err.remedies[0].parameter, err.remedies[0].value)
    recalibrate True
    """

    def __init__(self, *args: object, remedies: Iterable[Remedy] = ()) -> None:
        super().__init__(*args)
        self.remedies: tuple[Remedy, ...] = tuple(remedies)


class InvalidInputError(IPCVerifyError, ValueError):
    """The caller passed something ipcverify cannot use; the message says what to fix."""


class DataError(InvalidInputError):
    """A dataset file or array is missing columns, empty, ragged or non-finite."""


class ModelFileError(InvalidInputError):
    """A model file is missing, corrupt, of an unknown format, or unsafe to load."""


class SetError(InvalidInputError):
    """A set (ellipsoid, box, polytope) was given non-finite or degenerate parameters."""


class SampleSizeError(InvalidInputError):
    """Too few samples for the requested (epsilon, delta); the message gives the minimum."""


class IPCVerifyWarning(UserWarning):
    """Base class of the warnings ipcverify issues on purpose."""


class DataWarning(IPCVerifyWarning):
    """The data were accepted, but something about them weakens or voids what is certified."""


class Hint(IPCVerifyWarning):
    """Advice that may not apply (e.g. rows that may be correlated); the message says how to check."""
