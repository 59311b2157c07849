"""How many threads torch trains on: an explicit option, else ``OMP_NUM_THREADS``, else one.

ipcverify's networks are small (a batch of 128 rows through two layers of 64): a second
thread has little to split, and on a machine where other processes keep the cores busy
torch's threads wait for each other. Measured on 2 cores (``python -m benchmarks.bench_threads``,
``benchmarks/threads_results.json``, ``docs/benchmarks.md``), training on one thread is as
fast as on two on an idle machine and several times faster beside busy processes, and the
model is the same. So training runs on :data:`DEFAULT_THREADS` unless the caller says
otherwise, in this order:

1. an explicit number (``train(..., threads=N)``, ``ipcverify train --threads N``);
2. the user's ``OMP_NUM_THREADS``: torch reads it when it starts, and its thread count is
   then left as torch set it;
3. :data:`DEFAULT_THREADS`.

The setting is torch's process-wide one (``torch.set_num_threads``); :func:`torch_threads`
restores the previous value when training ends. The module imports no torch until a
context is entered, so the CLI can show the default.
"""

from __future__ import annotations

import numbers
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager

from ipcverify._wording._spelling import option
from ipcverify.errors import InvalidInputError

#: torch threads for training when neither an option nor ``OMP_NUM_THREADS`` says otherwise.
DEFAULT_THREADS = 1
#: The environment variable the user sets threads with (read by torch at start-up).
THREADS_VARIABLE = "OMP_NUM_THREADS"


def check_threads(threads: object) -> int:
    """``threads`` if it is an integer >= 1; otherwise a one-line error that says what to pass.

    Examples
    --------
    >>> check_threads(2)
    2
    >>> check_threads(0)
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: threads must be an integer >= 1; got 0
    """
    if isinstance(threads, bool) or not isinstance(threads, numbers.Integral) or threads < 1:
        raise InvalidInputError(f"{option('threads')} must be an integer >= 1; got {threads!r}")
    return int(threads)


def _variable_set(environ: Mapping[str, str]) -> bool:
    """Whether the environment sets a thread count OpenMP accepts (``N`` or ``N,M,...``, N >= 1).

    An empty or malformed value is one OpenMP ignores (with a warning of its own), so it does
    not count as the user's choice.
    """
    first = environ.get(THREADS_VARIABLE, "").split(",")[0].strip()
    return first.isdigit() and int(first) >= 1


def resolve_threads(threads: int | None = None, environ: Mapping[str, str] | None = None) -> int | None:
    """The torch thread count training should set, or None to leave torch's (the user's variable).

    Parameters
    ----------
    threads : int, optional
        An explicit number (validated by :func:`check_threads`); it wins.
    environ : mapping, optional
        The environment (default ``os.environ``); a valid ``OMP_NUM_THREADS`` in it means
        the user chose, and torch has already applied it.

    Returns
    -------
    int or None
        ``threads``; None if ``OMP_NUM_THREADS`` is set; else :data:`DEFAULT_THREADS`.

    Examples
    --------
    >>> resolve_threads(2, {"OMP_NUM_THREADS": "4"}), resolve_threads(None, {"OMP_NUM_THREADS": "4"})
    (2, None)
    >>> resolve_threads(None, {})
    1
    """
    if threads is not None:
        return check_threads(threads)
    if _variable_set(os.environ if environ is None else environ):
        return None
    return DEFAULT_THREADS


@contextmanager
def torch_threads(threads: int | None = None) -> Iterator[int]:
    """Run the block on :func:`resolve_threads`'s count of torch threads; restore torch's afterwards.

    Parameters
    ----------
    threads : int, optional
        An explicit number of threads; default: ``OMP_NUM_THREADS``'s, else
        :data:`DEFAULT_THREADS`.

    Yields
    ------
    int
        The number of threads torch runs the block on.

    Raises
    ------
    InvalidInputError
        If ``threads`` is not an integer >= 1 (before anything is changed).

    Examples
    --------
    >>> import torch
    >>> before = torch.get_num_threads()
    >>> with torch_threads(1) as n:
    ...     n, torch.get_num_threads()
    (1, 1)
    >>> torch.get_num_threads() == before
    True
    """
    wanted = resolve_threads(threads)
    import torch

    before = torch.get_num_threads()
    if wanted is not None and wanted != before:
        torch.set_num_threads(wanted)
    try:
        yield torch.get_num_threads()
    finally:
        if torch.get_num_threads() != before:
            torch.set_num_threads(before)
