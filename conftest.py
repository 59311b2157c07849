"""Settings for every test and every docstring example (``tests/`` and the library's doctests).

* Matplotlib draws off screen (``MPLBACKEND=Agg``).
* NumPy raises on invalid operations, division by zero and overflow, so a silent NaN or
  infinity fails the test that produced it.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np
import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(autouse=True)
def _strict_numpy() -> Iterator[None]:
    """Turn silent floating-point trouble into errors inside tests and doctests."""
    with np.errstate(invalid="raise", divide="raise", over="raise"):
        yield
