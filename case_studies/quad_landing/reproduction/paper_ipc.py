"""The paper's IPC, trained the paper's way: ``[paper]`` of ``reproduce.toml``, learned once, cached.

The network and loss are the library's recipe ``"paper"`` (:class:`ipcverify.training.HingeSelection`): an MLP
on ``concat(x_C, yhat_C)`` with hidden layers (64, 128) and ReLU, 12 outputs (the centre,
predicted outright, and the nine entries of ``C``), the hinge ``max(0, t / alpha + 1)`` plus
``lambda (-log|C^T C|)``, Adam at 1e-3 for 20 epochs on the training set (5,000 samples in
the full run), inputs standardised. What the paper leaves open is stated here and in
``docs/reproduce.md``: ``alpha``, ``lambda`` and the batch size are chosen by
:class:`ipcverify.training.HingeSelection` on held-out *training* rows only, and the network
starts with its centre output at ``yhat`` (:meth:`ipcverify.network.IPCNetwork.start_at_estimate`).

From the one trained network come two contracts (:mod:`.contracts`):

* ``paper_raw`` — the network as trained, uncalibrated, as the paper flew it: **no guarantee**;
* ``paper_calibrated`` — the same network PAC-calibrated at ``[paper] epsilon, delta`` on the
  calibration set, with its domain of validity, like ipcverify's default.

The settings are :class:`.config.PaperParams`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from case_studies.quad_landing.reproduction.config import PaperParams
from case_studies.quad_landing.reproduction.learn import row_level_calibration
from ipcverify.contract import IPCModel
from ipcverify.data import PerceptionDataset
from ipcverify.data._files import atomic_write
from ipcverify.errors import ModelFileError
from ipcverify.io import load_model, save_model
from ipcverify.network import ModelConfig
from ipcverify.training import train

__all__ = ["PaperModels", "learn_paper_ipc", "cached_paper_ipc"]


@dataclass(frozen=True)
class PaperModels:
    """The paper's network as trained (``raw``) and PAC-calibrated (``calibrated``)."""

    raw: IPCModel
    calibrated: IPCModel


def learn_paper_ipc(
    train_data: PerceptionDataset, calibration_data: PerceptionDataset, params: PaperParams
) -> PaperModels:
    """Train the paper's IPC (its unstated settings chosen on training rows), then calibrate a copy.

    Examples
    --------
    >>> from case_studies.quad_landing.data.datasets import as_dataset, collect_mixed
    >>> from case_studies.quad_landing.data.approach import ApproachParams
    >>> ap = ApproachParams.defaults(hover_points=1)
    >>> tr = as_dataset(collect_mixed(300, buffer_size=1, seed=0, approach=ap))
    >>> cal = as_dataset(collect_mixed(700, buffer_size=1, seed=1, approach=ap))
    >>> p = PaperParams.defaults(epochs=1, alphas=[0.1], lams=[0.01], epsilon=0.05, delta=0.01)
    >>> models = learn_paper_ipc(tr, cal, p)
    >>> models.raw.calibration is None, models.calibrated.calibration.mode, models.raw.n_parameters
    (True, 'pac', 10892)
    """
    mc = ModelConfig.recipe("paper", x_dim=train_data.x_dim, y_dim=train_data.y_dim, hidden=params.hidden)
    raw = train(train_data, mc, params.train_config(), select=params.selection()).model  # ipcverify's threads
    calibrated = row_level_calibration(raw, calibration_data, params.epsilon, params.delta,
                                       params.coverage_quantile)  # fmt: skip
    return PaperModels(raw=raw, calibrated=calibrated)


def _key(
    train_data: PerceptionDataset, calibration_data: PerceptionDataset, params: PaperParams
) -> dict[str, Any]:
    table = {k: (list(v) if isinstance(v, tuple) else v) for k, v in params.to_table().items()}
    return {
        "train": train_data.content_hash(),
        "calibration": calibration_data.content_hash(),
        "params": json.loads(json.dumps(table)),
        "torch": torch.__version__,
        "model_format": 1,
    }


def cached_paper_ipc(
    directory: str | Path,
    train_data: PerceptionDataset,
    calibration_data: PerceptionDataset,
    params: PaperParams,
) -> tuple[PaperModels, bool]:
    """:func:`learn_paper_ipc`, reusing ``directory/paper_{raw,calibrated}.pt`` if made from the same inputs.

    Returns
    -------
    models : PaperModels
    cached : bool
        True if the files were reused.
    """
    d = Path(directory)
    raw_path, cal_path, key_path = d / "paper_raw.pt", d / "paper_calibrated.pt", d / "paper.key.json"
    key = _key(train_data, calibration_data, params)
    if raw_path.exists() and cal_path.exists() and key_path.exists():
        try:
            if json.loads(key_path.read_text()) == key:
                return PaperModels(load_model(raw_path), load_model(cal_path)), True
        except (json.JSONDecodeError, OSError, ModelFileError):
            pass
    models = learn_paper_ipc(train_data, calibration_data, params)
    save_model(models.raw, raw_path)
    save_model(models.calibrated, cal_path)
    text = json.dumps(key, indent=1) + "\n"
    atomic_write(key_path, lambda fh: fh.write(text), "w")
    return models, False
