"""One documented predict, guarded: the sets come with the domain verdict, and the unguarded
path must be asked for by name (issue 39, item 2)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ipcverify import Ellipsoid, IPCModel, calibrate, example, save_model
from ipcverify.cli import app
from ipcverify.contract import Predictions
from ipcverify.data import save_dataset

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def contract() -> IPCModel:
    return calibrate(example(2000, seed=0).model, example(2000, seed=1).data, epsilon=0.1, delta=0.05)


def test_predict_gives_the_sets_with_the_domain_verdict(contract):
    test = example(200, seed=2).data
    far = test.x.copy()
    far[:10] += 30.0  # ten queries far from every calibration input
    p = contract.predict(far, test.yhat)
    assert isinstance(p, Predictions) and isinstance(p.sets, Ellipsoid)
    assert not p.in_domain[:10].any() and p.in_domain[10:].mean() > 0.9
    assert p.domain is not None and p.domain.outside >= 10 and p.outside == int((~p.in_domain).sum())


def test_the_unguarded_path_is_asked_for_by_name_and_gives_the_same_sets(contract):
    test = example(50, seed=3).data
    far = test.x + 30.0
    guarded = contract.predict(far, test.yhat)
    bare = contract.predict_unguarded(far, test.yhat)
    assert not hasattr(bare, "in_domain")  # no verdict: nothing says these sets carry no guarantee
    np.testing.assert_allclose(bare.shapes, guarded.shapes, rtol=1e-12)
    assert not guarded.in_domain.any()
    assert "WITHOUT the domain-of-validity test" in (IPCModel.predict_unguarded.__doc__ or "")
    # the names a user meets: one predict, guarded; the unguarded one says so in its name
    bare_paths = {n for n in dir(IPCModel) if n.startswith("predict")} - {"predict"}
    assert bare_paths == {"predict_unguarded", "predict_raw"}


def test_a_degenerate_set_is_refused_as_an_ellipsoid_but_kept_and_marked(contract):
    p = contract.predict(example(20, seed=4).data.x, example(20, seed=4).data.yhat)
    broken = Predictions(
        centers=p.centers,
        shapes=np.where(np.arange(20)[:, None, None] == 3, 0.0, p.shapes),
        in_domain=p.in_domain,
        singular=np.arange(20) == 3,
        calibrated=True,
    )
    with pytest.raises(Exception, match=r"1 of 20 sets are degenerate \(first at query 3\)"):
        _ = broken.sets


def test_the_cli_predict_writes_the_domain_verdict(tmp_path, contract):
    save_model(contract, tmp_path / "c.pt")
    q = example(100, seed=5).data
    save_dataset(q, tmp_path / "q.parquet")
    res = CliRunner().invoke(app, ["predict", str(tmp_path / "c.pt"), str(tmp_path / "q.parquet"),
                                   "--out", str(tmp_path / "sets.npz")])  # fmt: skip
    assert res.exit_code == 0, res.output
    with np.load(tmp_path / "sets.npz") as z:
        np.testing.assert_array_equal(z["in_domain"], contract.predict(q.x, q.yhat).in_domain)


def test_the_readme_example_runs_guarded_and_split_by_runs(tmp_path, monkeypatch):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    code = re.search(r"<!-- readme:python -->\n```python\n(.*?)```", text, re.S)
    assert code, "README.md: the Python example under <!-- readme:python --> is missing"
    source = code.group(1)
    assert "group_column=" in source and ".predict(" in source and "predict_unguarded" not in source
    save_dataset(example(3000, seed=0, runs=100).data, tmp_path / "log.parquet")
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {}
    exec(compile(source, "README.md", "exec"), namespace)  # noqa: S102 - the project's own README
    p = namespace["p"]
    assert isinstance(p, Predictions) and p.domain is not None
    assert namespace["contract"].calibration.kind == "grouped"  # the log's runs: a claim about runs
