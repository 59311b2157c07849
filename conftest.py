"""Settings for every test and every docstring example (``tests/`` and the library's doctests).

* Matplotlib draws off screen (``MPLBACKEND=Agg``).
* NumPy raises on invalid operations, division by zero and overflow, so a silent NaN or
  infinity fails the test that produced it.
* torch's default generator is seeded (0) at the start of the session and of every test and
  doctest. torch seeds it from entropy at import, so an untrained network built without a seed
  (a fixture's, an example's) would differ from run to run, and a verdict drawn from it with a
  fixed confidence would fail in some runs and not others.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator

import numpy as np
import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(autouse=True)
def _strict_numpy() -> Iterator[None]:
    """Turn silent floating-point trouble into errors inside tests and doctests."""
    with np.errstate(invalid="raise", divide="raise", over="raise"):
        yield


def _seed_torch() -> None:
    """Seed torch's default generator if torch is loaded (importing it here would slow every test)."""
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.manual_seed(0)


@pytest.fixture(autouse=True, scope="session")
def _seeded_torch_session() -> Iterator[None]:
    """Before the first module-scoped fixture builds anything."""
    _seed_torch()
    yield


@pytest.fixture(autouse=True)
def _seeded_torch() -> Iterator[None]:
    """Every test and doctest starts from the same torch random state, whatever ran before it."""
    _seed_torch()
    yield
