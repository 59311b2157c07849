"""Fixtures of the library's tests (the CLI runner: ../conftest.py; strict numerics: ../../conftest.py)."""

from __future__ import annotations

import itertools
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


def _det(m):
    """Laplace expansion: an exact determinant for small matrices, independent of the library."""
    if len(m) == 1:
        return m[0][0]
    return sum((-1) ** j * m[0][j] * _det([r[:j] + r[j + 1 :] for r in m[1:]]) for j in range(len(m)))


def _minors(m, leading: bool = False) -> list:
    """Every principal minor of ``m`` (or only the leading ones), by :func:`_det`."""
    n = len(m)
    if leading:
        subsets = [tuple(range(k)) for k in range(1, n + 1)]
    else:
        subsets = [idx for k in range(1, n + 1) for idx in itertools.combinations(range(n), k)]
    return [_det([[m[i][j] for j in idx] for i in idx]) for idx in subsets]


@pytest.fixture(scope="session")
def minors() -> types.SimpleNamespace:
    """Exact oracles of the definiteness tests, independent of ipcverify.sets._exact.

    ``det`` (Laplace expansion), ``of(m, leading=False)`` (principal minors), ``psd(m)`` (every
    principal minor ``>= 0``) and ``pd(m)`` (every leading minor ``> 0``, Sylvester).
    """
    return types.SimpleNamespace(
        det=_det,
        of=_minors,
        psd=lambda m: all(d >= 0 for d in _minors(m)),
        pd=lambda m: all(d > 0 for d in _minors(m, leading=True)),
    )
