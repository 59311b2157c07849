"""The nonconformity score both network kinds share: how far ``y`` lies outside the raw set.

A network ``net`` maps ``(x, yhat)`` to a centre ``c``, a shape matrix ``C`` and
``log det(C^T C)``; its raw set is ``E(c, C) = {y : ||C (y - c)|| <= 1}``. The score
``g = ||C (y - c)||`` is what training penalises and calibration ranks.
:class:`ScoredNetwork` defines :meth:`~ScoredNetwork.score` once for the paper's heads
(:class:`ipcverify.network.IPCNetwork`) and the low-rank ensemble
(:class:`ipcverify.network.LowRankEnsemble`).

Examples
--------
>>> import torch
>>> class Unit(ScoredNetwork):
...     def forward(self, x, yhat):
...         return yhat, torch.eye(2).expand(len(x), 2, 2), torch.zeros(len(x))
>>> g, logdet = Unit().score(torch.zeros(1, 1), torch.tensor([[3.0, 4.0]]), torch.zeros(1, 2))
>>> float(g[0]), float(logdet[0])
(5.0, 0.0)
"""

from __future__ import annotations

import torch
from torch import nn


class ScoredNetwork(nn.Module):
    """An ``nn.Module`` whose forward returns ``(centre (B, n), C (B, n, n), log det(C^T C) (B,))``."""

    def score(
        self, x: torch.Tensor, y: torch.Tensor, yhat: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``g = ||C (y - c)||`` (B,) and ``log det(C^T C)`` (B,)."""
        center, C, logdet = self(x, yhat)
        g = torch.linalg.vector_norm(torch.einsum("bij,bj->bi", C, y - center), dim=1)
        return g, logdet
