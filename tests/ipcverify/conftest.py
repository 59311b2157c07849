"""Fixtures of the library's tests (the CLI runner: ../conftest.py; strict numerics: ../../conftest.py)."""

from __future__ import annotations

import types

import numpy as np
import pytest
import torch


def _flat(net: torch.nn.Module) -> tuple[list[str], list[torch.Size], np.ndarray]:
    """Names, shapes and the float64 concatenation of every trainable parameter."""
    names, shapes, parts = [], [], []
    for k, v in net.named_parameters():
        names.append(k)
        shapes.append(v.shape)
        parts.append(v.detach().double().numpy().ravel())
    return names, shapes, np.concatenate(parts)


def _unflat(names, shapes, vec) -> dict[str, torch.Tensor]:
    """Inverse of ``flat``: a parameter dictionary (float64) from one vector."""
    out, i = {}, 0
    for k, s in zip(names, shapes, strict=True):
        size = int(np.prod(s))
        out[k] = torch.tensor(vec[i : i + size].reshape(s), dtype=torch.float64)
        i += size
    return out


def _random_in_box(box, rng: np.random.Generator, m: int, corners: bool) -> tuple[np.ndarray, ...]:
    """``m`` points ``(x, y, yhat)`` uniform in a DataBox, or at random corners of it."""

    def draw(lo, hi):
        if corners:
            return np.where(rng.random((m, lo.size)) < 0.5, lo, hi)
        return lo + (hi - lo) * rng.random((m, lo.size))

    return draw(box.x_lo, box.x_hi), draw(box.y_lo, box.y_hi), draw(box.yhat_lo, box.yhat_hi)


@pytest.fixture(scope="session")
def ball() -> types.SimpleNamespace:
    """Helpers of the Lipschitz tests: ``flat``, ``unflat`` (parameters <-> one vector), ``random_in_box``."""
    return types.SimpleNamespace(flat=_flat, unflat=_unflat, random_in_box=_random_in_box)
