"""Perception data.

The dataset of (x, y, yhat) triples, its checks, tables on disk, atomic files and the synthetic demo
data.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.data._dataset import PerceptionDataset, PerceptionInputs, load_dataset, save_dataset
    from ipcverify.data._split_files import split_file

__all__ = [
    "PerceptionDataset",
    "PerceptionInputs",
    "load_dataset",
    "save_dataset",
    "split_file",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
