"""Table I: counts, simultaneous intervals, rising rates."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.reproduction.table1 import RatesRising, Table1Row, table1
from ipcverify.errors import InvalidInputError


def test_table1_counts_and_simultaneous_intervals(make_ipc):
    from ipcverify.data._dataset import PerceptionDataset

    m = make_ipc(True)
    x = np.zeros((50, 12))
    x[:, 2] = 1.0
    near = PerceptionDataset(x, np.zeros((50, 3)), np.zeros((50, 3)))
    far = PerceptionDataset(x, np.full((50, 3), 1e3), np.zeros((50, 3)))
    rows = table1(m, {2: far, 1: near}, delta=0.1)
    assert rows.buffers == (1, 2)
    assert rows.row(1).violations == 0 and rows.row(2).violations == 50
    assert rows.row(1).confidence == 0.9 and rows.row(1).paper_rate == 0.0019
    assert rows.rising() == RatesRising(strict=True, separated=True)
    assert rows.to_dict()["2"]["violations"] == 50
    with pytest.raises(InvalidInputError, match="no row for buffer size 3"):
        rows.row(3)
    with pytest.raises(InvalidInputError, match="at least one"):
        table1(m, {})


def test_a_row_in_summary_json_is_keyed_by_buffer_size_and_has_path_counts_only_with_paths():
    kw = dict(buffer_size=3, n=10, violations=2, rate=0.2, upper=0.5, interval=(0.03, 0.56),
              confidence=0.95, paper_rate=0.0205)  # fmt: skip
    bare = Table1Row(**kw, paths=None, paths_with_violations=None).to_dict()
    assert bare == {"n": 10, "violations": 2, "rate": 0.2, "upper": 0.5, "interval": [0.03, 0.56],
                    "confidence": 0.95, "paper_rate": 0.0205}  # fmt: skip
    assert list(bare) == ["n", "violations", "rate", "upper", "interval", "confidence", "paper_rate"]
    paths = Table1Row(**kw, paths=4, paths_with_violations=1).to_dict()
    assert list(paths) == [*bare, "paths", "paths_with_violations"]
    assert (paths["paths"], paths["paths_with_violations"]) == (4, 1)
    assert RatesRising(strict=True, separated=False).to_dict() == {"strict": True, "separated": False}
