"""Perception data.

The dataset of (x, y, yhat) triples, its checks, tables on disk, atomic files and the synthetic demo
data.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.data._checks import (
        GROUP_NAMES,
        MIN_DISTINCT_SHARE,
        MOSTLY_OUTSIDE,
        SURPRISE,
        check_informative,
        group_like_columns,
        input_ranges,
        warn_correlated_rows,
        warn_outside_training,
    )
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
        dumps_json,
        file_sha256,
        json_data,
        json_float,
        write_json,
    )
    from ipcverify.data._split import (
        group_codes,
        split_fractions,
        split_parts,
    )
    from ipcverify.data._synthetic import (
        FRAME_TIME,
        make_lagged_perception,
    )
    from ipcverify.data._tables import (
        SUFFIXES,
        data_file,
        frame_blocks,
        numbered_columns,
        read_blocks,
        refuse_unknown_columns,
    )

__all__ = [
    "FRAME_TIME",
    "GROUP_NAMES",
    "MIN_DISTINCT_SHARE",
    "MOSTLY_OUTSIDE",
    "SUFFIXES",
    "SURPRISE",
    "DatasetSplits",
    "PerceptionDataset",
    "PerceptionInputs",
    "atomic_write",
    "check_informative",
    "data_file",
    "dumps_json",
    "file_sha256",
    "frame_blocks",
    "group_codes",
    "group_like_columns",
    "input_ranges",
    "json_data",
    "json_float",
    "load_dataset",
    "load_inputs",
    "make_lagged_perception",
    "numbered_columns",
    "read_blocks",
    "refuse_unknown_columns",
    "save_dataset",
    "split_fractions",
    "split_parts",
    "warn_correlated_rows",
    "warn_outside_training",
    "write_json",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
