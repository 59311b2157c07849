"""``ipcverify train --threads N``: passed on to the library, validated, exit status 2 when bad."""

from __future__ import annotations

import pytest

from ipcverify.data._dataset import save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.training import _train


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    path = tmp_path_factory.mktemp("threads") / "train.csv"
    save_dataset(make_lagged_perception(300, seed=0), path)
    return path


@pytest.fixture
def asked(monkeypatch):
    """The ``threads`` every call of the library's train received."""
    calls: list[object] = []
    real = _train.train

    def recording(*args, **kwargs):
        calls.append(kwargs.get("threads", "missing"))
        return real(*args, **kwargs)

    monkeypatch.setattr(_train, "train", recording)
    return calls


def test_the_option_reaches_the_library_and_its_absence_leaves_the_default(data, tmp_path, run_cli, asked):
    quick = ["--epochs", "1", "--hidden", "8"]
    assert run_cli("train", data, "--out", tmp_path / "a.pt", *quick, "--threads", "2").code == 0
    assert run_cli("train", data, "--out", tmp_path / "b.pt", *quick).code == 0
    assert asked == [2, None]  # None: OMP_NUM_THREADS if set, else the default (the library decides)
    assert (tmp_path / "a.pt").read_bytes() == (tmp_path / "b.pt").read_bytes()


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("0", "error: --threads must be an integer >= 1; got 0"),
        ("-2", "error: --threads must be an integer >= 1; got -2"),
        ("two", "'two' is not a valid integer"),
        ("1.5", "'1.5' is not a valid integer"),
    ],
)
def test_a_bad_count_exits_2_with_one_line_before_training(data, tmp_path, run_cli, asked, value, message):
    res = run_cli("train", data, "--out", tmp_path / "m.pt", "--threads", value)
    assert res.code == 2
    lines = res.stderr.strip().splitlines()
    assert message in lines[-1] and lines[-1].startswith("error:") and not res.stdout
    assert asked == [] and not (tmp_path / "m.pt").exists()
