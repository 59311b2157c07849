"""Perception data.

The dataset of (x, y, yhat) triples, its checks, tables on disk, atomic files and the synthetic demo
data.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.data._dataset import (
        DatasetSplits,
        PerceptionDataset,
        PerceptionInputs,
        load_dataset,
        load_inputs,
        save_dataset,
    )
    from ipcverify.data._files import (
        atomic_write,
        file_sha256,
        json_data,
        write_json,
    )
    from ipcverify.data._split_files import (
        SplitFiles,
        SplitPart,
        split_file,
    )
    from ipcverify.data._synthetic import (
        make_lagged_perception,
    )

__all__ = [
    "DatasetSplits",
    "PerceptionDataset",
    "PerceptionInputs",
    "SplitFiles",
    "SplitPart",
    "atomic_write",
    "file_sha256",
    "json_data",
    "load_dataset",
    "load_inputs",
    "make_lagged_perception",
    "save_dataset",
    "split_file",
    "write_json",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
