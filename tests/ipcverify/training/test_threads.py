"""torch threads for training: explicit > OMP_NUM_THREADS > default; scoped, validated, model unchanged."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.training import _train
from ipcverify.training._objectives import TrainConfig
from ipcverify.training._selection import HingeSelection
from ipcverify.training._threads import (
    DEFAULT_THREADS,
    THREADS_VARIABLE,
    check_threads,
    resolve_threads,
    torch_threads,
)
from ipcverify.training._train import select_hinge, train

#: A count torch would never pick by itself here, so that "left as it was" and "set" differ.
ODD = 3


@pytest.fixture
def torch_at_odd():
    """torch on ODD threads for the test; the process's own setting back afterwards."""
    before = torch.get_num_threads()
    torch.set_num_threads(ODD)
    yield
    torch.set_num_threads(before)


@pytest.fixture
def seen(monkeypatch):
    """The torch thread counts every network training ran on (the low-rank and the paper's trainers)."""
    counts: list[int] = []

    def recording(fit):
        def wrapped(*args, **kwargs):
            counts.append(torch.get_num_threads())
            return fit(*args, **kwargs)

        return wrapped

    for kind, trainer in list(_train._TRAINERS.items()):
        monkeypatch.setitem(_train._TRAINERS, kind, dataclasses.replace(trainer, fit=recording(trainer.fit)))
    monkeypatch.setattr(_train, "_train_network", recording(_train._train_network))  # the selection's
    return counts


@pytest.fixture(scope="module")
def small():
    return make_lagged_perception(300, seed=0)


QUICK = TrainConfig(epochs=1)


def test_the_default_is_one_thread():
    assert DEFAULT_THREADS == 1 and THREADS_VARIABLE == "OMP_NUM_THREADS"


@pytest.mark.parametrize(
    ("threads", "environ", "expected"),
    [
        (2, {"OMP_NUM_THREADS": "4"}, 2),  # the explicit number wins
        (None, {"OMP_NUM_THREADS": "4"}, None),  # then the user's variable: torch's reading of it is kept
        (None, {"OMP_NUM_THREADS": " 4,2"}, None),  # OpenMP's nested form; the first level counts
        (None, {}, DEFAULT_THREADS),  # then ipcverify's default
        (None, {"OMP_NUM_THREADS": ""}, DEFAULT_THREADS),  # values OpenMP ignores are no choice
        (None, {"OMP_NUM_THREADS": "0"}, DEFAULT_THREADS),
        (None, {"OMP_NUM_THREADS": "two"}, DEFAULT_THREADS),
        (None, {"OMP_NUM_THREADS": "1.5"}, DEFAULT_THREADS),
        (None, {"OMP_NUM_THREADS": "-2"}, DEFAULT_THREADS),
    ],
)
def test_precedence_explicit_then_variable_then_default(threads, environ, expected):
    assert resolve_threads(threads, environ) == expected


@pytest.mark.parametrize("bad", [0, -1, 1.5, 2.0, True, "2", None])
def test_a_bad_thread_count_is_refused_with_what_to_pass(bad):
    with pytest.raises(InvalidInputError) as exc:
        check_threads(bad)
    assert str(exc.value) == f"threads must be an integer >= 1; got {bad!r}"


def test_train_runs_on_the_default_and_restores_torchs_setting(small, seen, torch_at_odd, monkeypatch):
    monkeypatch.delenv(THREADS_VARIABLE, raising=False)
    train(small, train_config=QUICK)
    assert seen == [DEFAULT_THREADS]
    assert torch.get_num_threads() == ODD


def test_train_leaves_torch_on_the_users_variable(small, seen, torch_at_odd, monkeypatch):
    monkeypatch.setenv(THREADS_VARIABLE, str(ODD))
    train(small, train_config=QUICK)
    assert seen == [ODD]
    assert torch.get_num_threads() == ODD


def test_an_explicit_count_wins_over_the_variable(small, seen, torch_at_odd, monkeypatch):
    monkeypatch.setenv(THREADS_VARIABLE, "1")
    train(small, train_config=QUICK, threads=2)
    assert seen == [2]
    assert torch.get_num_threads() == ODD


def test_the_selection_runs_on_the_same_threads_as_the_training(small, seen, torch_at_odd, monkeypatch):
    monkeypatch.delenv(THREADS_VARIABLE, raising=False)
    mc = ModelConfig.recipe("paper", x_dim=6, y_dim=3, hidden=(8, 8))
    rule = HingeSelection(alphas=(0.1, 1.0), lams=(0.01,))
    train(small, mc, TrainConfig.recipe("paper", epochs=1), select=rule, threads=2)
    assert seen == [2, 2, 2]  # two candidates, then the final network
    seen.clear()
    select_hinge(small, mc, TrainConfig.recipe("paper", epochs=1), rule)
    assert seen == [DEFAULT_THREADS, DEFAULT_THREADS]
    assert torch.get_num_threads() == ODD


def test_torchs_setting_is_restored_when_training_fails(small, torch_at_odd, monkeypatch):
    def failing(*args, **kwargs):
        assert torch.get_num_threads() == 2
        raise InvalidInputError("stop")

    trainer = dataclasses.replace(_train._TRAINERS["lowrank"], fit=failing)
    monkeypatch.setitem(_train._TRAINERS, "lowrank", trainer)
    with pytest.raises(InvalidInputError, match="stop"):
        train(small, train_config=QUICK, threads=2)
    assert torch.get_num_threads() == ODD


def test_a_bad_count_is_refused_before_torch_is_touched(small, seen, torch_at_odd):
    with pytest.raises(InvalidInputError, match=r"threads must be an integer >= 1; got 0"):
        train(small, train_config=QUICK, threads=0)
    with pytest.raises(InvalidInputError, match="got 1.5"):
        with torch_threads(1.5):  # type: ignore[arg-type]
            pass
    assert seen == [] and torch.get_num_threads() == ODD


def _same(a: torch.nn.Module, b: torch.nn.Module) -> bool:
    sa, sb = a.state_dict(), b.state_dict()
    return sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


@pytest.mark.slow
@pytest.mark.parametrize("recipe", ["tight", "paper"])
def test_one_and_two_threads_train_the_same_model(recipe):
    """Issue 40: the default changes the time, not the model.

    2,000 rows: the passes over all of them (the early-stopping loss, the Lipschitz statistic of
    Theorem 1) hold 2,000 x 64 activations, above the size torch splits between threads.
    """
    ds = make_lagged_perception(2000, seed=0)
    tc = TrainConfig.recipe(recipe, epochs=5)
    rule = HingeSelection(alphas=(0.1, 1.0), lams=(0.01,)) if recipe == "paper" else None
    one, two = (train(ds, train_config=tc, recipe=recipe, select=rule, threads=n).model for n in (1, 2))
    assert _same(one.network, two.network)
    meta_one, meta_two = dict(one.metadata), dict(two.metadata)
    if recipe == "paper":  # the selection records how long it took: the one timing in a model file
        meta_one["selection"] = {k: v for k, v in meta_one["selection"].items() if k != "seconds"}
        meta_two["selection"] = {k: v for k, v in meta_two["selection"].items() if k != "seconds"}
    assert _plain(meta_one) == _plain(meta_two)


def _plain(value: object) -> object:
    """``value`` with its arrays (the row fingerprints) as lists, so that ``==`` compares all of it."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value.tolist() if isinstance(value, np.ndarray) else value
