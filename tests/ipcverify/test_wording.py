"""The wording layer: library messages name no command-line flag; each verdict is worded once.

* the scan: no non-docstring string literal of ipcverify outside the CLI and the wording layer
  holds a flag of the click app (and the scan does catch a planted one);
* the same error said to a Python caller and to a command-line user;
* each verdict's words appear verbatim in the summary, the CLI's output and the HTML page of one
  certificate;
* a remedy an error carries works: applied, the refused call succeeds.
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import numpy as np
import pytest

import ipcverify
from ipcverify._wording._audience import Audience, speaking
from ipcverify._wording._spelling import PARAMETERS, Remedy, render
from ipcverify._wording._verdicts import domain_verdict, status_verdict, theorem1_verdict
from ipcverify.errors import InvalidInputError, SampleSizeError

PACKAGE = Path(ipcverify.__file__).parent
ALLOWED = ("cli", "_wording")  # the two places that may spell a flag


def _flags() -> set[str]:
    """Every long option of the click app, its subcommands included."""
    import click

    from ipcverify.cli import app

    found: set[str] = set()

    def walk(cmd: click.Command) -> None:
        for p in cmd.params:
            found.update(o for o in [*p.opts, *p.secondary_opts] if o.startswith("--"))
        if isinstance(cmd, click.Group):
            for sub in cmd.commands.values():
                walk(sub)

    walk(app)
    return found


def _flag_literals(source: str, flags: set[str]) -> list[tuple[int, str]]:
    """(line, flag) of each flag in a string literal of ``source`` that is not a docstring."""
    pattern = re.compile(
        r"(?<![\w-])(" + "|".join(sorted(map(re.escape, flags), key=len, reverse=True)) + r")(?![\w-])"
    )
    tree = ast.parse(source)
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                docstrings.add(id(body[0].value))
    return [
        (node.lineno, m.group(1))
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
        for m in pattern.finditer(node.value)
    ]


def test_the_click_app_has_the_flags_the_scan_looks_for():
    flags = _flags()
    assert len(flags) > 50 and {"--epsilon", "--domain-flag-rate", "--data", "--out"} <= flags
    # every flag a library message may name is one the CLI has (a renamed flag fails here)
    assert {s.cli.split()[0] for s in PARAMETERS.values()} <= flags


def test_no_library_message_spells_a_command_line_flag():
    flags = _flags()
    found = [
        f"{path.relative_to(PACKAGE.parent).as_posix()}:{line}: {flag}"
        for path in sorted(PACKAGE.rglob("*.py"))
        if path.relative_to(PACKAGE).parts[0] not in ALLOWED
        for line, flag in _flag_literals(path.read_text(encoding="utf-8"), flags)
    ]
    assert found == [], "spell these through ipcverify._wording (option, Remedy):\n" + "\n".join(found)


def test_the_scan_catches_a_planted_flag_and_spares_docstrings():
    flags = _flags()
    planted = '''
def f(n):
    """Pass --epsilon 0.1 (a docstring may name a flag)."""
    raise ValueError(f"too few samples ({n}); use a larger --epsilon or --delta")
'''
    assert _flag_literals(planted, flags) == [(4, "--epsilon"), (4, "--delta")]
    assert _flag_literals('x = "an --epsilonic word, a re-delta"', flags) == []


def test_one_error_said_to_python_and_to_the_command_line():
    from ipcverify.guard._domain import DomainModel

    z = np.random.default_rng(0).normal(size=(30, 4))
    with pytest.raises(SampleSizeError) as py:
        DomainModel.fit(z[:, :2], z[:, 2:], flag_rate=0.01)
    with speaking(Audience.CLI), pytest.raises(SampleSizeError) as cli:
        DomainModel.fit(z[:, :2], z[:, 2:], flag_rate=0.01)
    py_text, cli_text = str(py.value), str(cli.value)
    # 30 inputs allow a flag rate of 1/31 at least, rounded up to 0.0323
    assert "flag_rate=0.0323 works" in py_text and "--domain-flag-rate" not in py_text
    assert "--domain-flag-rate 0.0323 works" in cli_text and "flag_rate=" not in cli_text
    assert "\n" not in py_text and "\n" not in cli_text  # one line each
    assert py.value.remedies == cli.value.remedies == (Remedy("flag_rate", 0.0323),)
    assert render(py.value.remedies[0]) == "flag_rate=0.0323"


def test_a_remedy_applied_makes_the_call_succeed():
    from ipcverify.guard._domain import DomainModel

    rng = np.random.default_rng(1)
    groups = np.repeat(np.arange(12), 10)  # 12 runs: a flag rate of at least 1/13
    z = rng.normal(size=(12, 4))[groups] + 0.1 * rng.normal(size=(120, 4))
    with pytest.raises(SampleSizeError) as refused:
        DomainModel.fit(z[:, :2], z[:, 2:], flag_rate=0.05, groups=groups)
    (remedy,) = refused.value.remedies
    assert remedy.parameter == "flag_rate" and 0.05 < float(remedy.value) < 0.1  # type: ignore[arg-type]
    fitted = DomainModel.fit(z[:, :2], z[:, 2:], **{remedy.parameter: remedy.value}, groups=groups)
    assert fitted.flag_rate == remedy.value and fitted.n_groups == 12


def test_the_recalibrate_remedy_works():
    from ipcverify import calibrate, example

    ex = example(400, seed=2)
    once = calibrate(ex.model, ex.data, 0.2, 0.05, domain=None)
    with pytest.raises(InvalidInputError) as refused:
        calibrate(once, ex.data, 0.2, 0.05, domain=None)
    (remedy,) = refused.value.remedies
    assert render(remedy) in str(refused.value)
    twice = calibrate(once, ex.data, 0.2, 0.05, domain=None, **{remedy.parameter: remedy.value})
    assert twice.calibration is not None


def test_the_smallest_rate_a_few_groups_allow_works():
    from ipcverify import Grouped, calibrate, example

    ex = example(400, seed=4, runs=20)
    with pytest.raises(SampleSizeError) as refused:
        calibrate(ex.model, ex.data, 0.05, 0.01, Grouped(column="run"), domain=None)
    (remedy,) = refused.value.remedies
    assert remedy.parameter == "epsilon" and 0.05 < float(remedy.value) < 1  # type: ignore[arg-type]
    assert render(remedy) in str(refused.value).replace("the smallest is ", "epsilon=")
    model = calibrate(ex.model, ex.data, remedy.value, 0.01, Grouped(column="run"), domain=None)
    assert model.calibration is not None


@pytest.fixture(scope="module")
def certified(tmp_path_factory):
    """One certificate written by the CLI: its summary, its console output and its page."""
    from ipcverify import calibrate, example, train
    from ipcverify.data import save_dataset
    from ipcverify.io import save_model
    from ipcverify.training import TrainConfig

    ex = example(1500, seed=3)
    parts = ex.data.split((0.4, 0.3, 0.3), seed=0)
    fit, cal, test = parts.train, parts.calibration, parts.test
    assert fit is not None and cal is not None and test is not None
    d = tmp_path_factory.mktemp("certified")
    trained = train(
        fit, ex.model.config, TrainConfig(epochs=2, val_fraction=0.0, patience=None, seed=0)
    ).model
    save_model(calibrate(trained, cal, 0.2, 0.05), d / "m.pt")
    save_dataset(test, d / "test.csv")
    save_dataset(fit, d / "train.csv")
    return d


def test_each_verdict_is_worded_alike_in_the_summary_the_cli_and_the_page(certified, run_cli, monkeypatch):
    from ipcverify.cli.app import console

    monkeypatch.setattr(console, "width", 400)  # one table row a line
    d = certified
    args = ["certify", d / "m.pt", "--data", d / "test.csv", "--train-data", d / "train.csv"]
    res = run_cli(*args, "--out", d / "c")
    assert res.code == 0, res.stderr
    doc = json.loads((d / "c" / "certificate.json").read_text())
    page = (d / "c" / "report.html").read_text()
    summary = doc["summary"]
    checks = {c["check"]: c["verdict"] for c in summary["checks"]}
    t1 = doc["theorem1"]
    dom = doc["domain"]
    with speaking(Audience.CLI):  # the CLI wrote all three
        words = {
            "status": status_verdict(doc["status"]).split(": ", 1)[-1],
            "Theorem 1": theorem1_verdict(t1["vacuous"]),
            "domain": domain_verdict(
                present=True,
                radius_zero=dom["threshold"] == 0,
                queries=dom["n"],
                well_above=dom["well_above_flag_rate"],
                row_level=dom["row_level_column"] is not None,
            ),
        }
    assert checks["Theorem 1 (paper)"] == words["Theorem 1"]
    assert checks["domain of validity"] == words["domain"]
    assert words["status"] in summary["verdict"] and doc["status_text"] == status_verdict(doc["status"])
    for name, said in words.items():
        assert said in res.stdout, f"{name}: {said!r} not in the CLI's output"
        assert said in page or said.replace("'", "&#x27;") in page, f"{name}: {said!r} not on the page"
