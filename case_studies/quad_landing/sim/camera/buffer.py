"""The camera buffer size: one type and one validator for every place that carries it.

The buffer size is the paper's knob (Table I has a row per size). The timing model reads it
as the number of V4L2 buffers, the previous model as ``k`` frames of lag, and 0 is an ideal
camera. It is carried by a :class:`~case_studies.quad_landing.sim.flight.Flight`, the
``[collect]`` and ``[landing]`` sections, a dataset's spec and the reproduction's
``[sizes]``; all of them check it with :func:`check_buffer_size`.

Examples
--------
>>> check_buffer_size(3)
3
>>> check_buffer_size(0, name="sizes.extra_landing_buffer", lowest=1)
Traceback (most recent call last):
...
ipcverify.errors.InvalidInputError: sizes.extra_landing_buffer must be an integer in [1, 30] frames, got 0
"""

from __future__ import annotations

from typing import TypeAlias

import numpy as np

from ipcverify.errors import InvalidInputError

__all__ = ["BufferSize", "MAX_BUFFER_SIZE", "check_buffer_size"]

#: Largest buffer size accepted (frames).
MAX_BUFFER_SIZE = 30

#: A camera buffer size in frames, ``0 <= k <= MAX_BUFFER_SIZE``, as :func:`check_buffer_size` returns it.
BufferSize: TypeAlias = int


def check_buffer_size(
    size: object,
    *,
    name: str = "buffer size",
    lowest: int = 0,
    error: type[InvalidInputError] = InvalidInputError,
) -> BufferSize:
    """``size`` as a buffer size: a whole number of frames in ``[lowest, MAX_BUFFER_SIZE]``.

    Parameters
    ----------
    size : object
        The value to check: an integer (not a bool); a float with a whole value is accepted
        and returned as an int, as a TOML file or a command line may give it.
    name : str
        What to call it in the error message (e.g. ``"landing.buffer_size"``).
    lowest : int
        The smallest size the caller accepts (1 where an ideal camera makes no sense).
    error : type
        The :class:`~ipcverify.errors.InvalidInputError` subclass to raise (a configuration
        section raises :class:`~case_studies.quad_landing.settings.ConfigError`).

    Returns
    -------
    int
        ``size`` as an int.

    Raises
    ------
    InvalidInputError
        (or ``error``) if ``size`` is not a whole number in the range.

    Examples
    --------
    >>> check_buffer_size(2.0), check_buffer_size(np.int64(30))
    (2, 30)
    """
    ok = (
        not isinstance(size, bool)
        and isinstance(size, (int, float, np.integer, np.floating))
        and bool(np.isfinite(size))
        and int(size) == size
        and lowest <= size <= MAX_BUFFER_SIZE
    )
    if not ok:
        raise error(f"{name} must be an integer in [{lowest}, {MAX_BUFFER_SIZE}] frames, got {size!r}")
    return int(size)  # type: ignore[call-overload]
