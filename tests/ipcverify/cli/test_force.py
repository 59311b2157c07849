"""No silent overwrite, no empty success, and hints after the error they go with (docs/cli.md, "Outputs").

Every command that writes refuses an output that exists (exit 2, one ``error:`` line naming
``--force``) and leaves it as it was; with ``--force`` it replaces it, leaving no other file; a
missing output folder is created and the command says so. A folder output counts the files the
command writes, not the folder.
"""

from __future__ import annotations

import shlex
import warnings
from pathlib import Path

import click
import pytest

from ipcverify.contract._calibrate import calibrate
from ipcverify.data._dataset import save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import DataWarning, Hint, InvalidInputError
from ipcverify.io._modelio import save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("force_inputs")
    f = {name: d / f"{name}.csv" for name in ("train", "cal", "test")}
    for seed, name in enumerate(("train", "cal", "test")):
        save_dataset(make_lagged_perception((300, 1000, 300)[seed], seed=seed), f[name])
    mc = ModelConfig.recipe("tight", x_dim=6, y_dim=3, hidden=(8,), members=2)
    model = train(make_lagged_perception(300, seed=0), mc, TrainConfig.recipe("tight", epochs=1)).model
    f["model"], f["calibrated"] = d / "model.pt", d / "calibrated.pt"
    save_model(model, f["model"])
    save_model(calibrate(model, make_lagged_perception(1000, seed=1), 0.05, 0.01), f["calibrated"])
    f["problems"] = d / "problems.json"
    f["problems"].write_text(
        '{"inner": {"type": "ellipsoid", "center": [0, 0], "shape": [[1, 0], [0, 1]]}, '
        '"outer": {"type": "box", "lower": [-2, -2], "upper": [2, 2]}}',
        encoding="utf-8",
    )
    for name, wobble in (("gt", 0.0), ("est", 0.01)):  # the estimate wobbles sideways about the truth
        rows = [f"{0.05 * i:.2f} {0.05 * i} {wobble * (i % 7)} 0 0 0 0 1" for i in range(200)]
        f[name] = d / f"{name}.txt"
        f[name].write_text("\n".join(rows) + "\n", encoding="utf-8")
    return f


# id | the command line ({out} is a folder that does not exist yet) | the files it writes there
WRITERS = """
train     | train {train} --out {out}/m.pt --recipe v1 --epochs 1 --hidden 8           | m.pt
calibrate | calibrate {model} {cal} --epsilon 0.05 --delta 0.01 --out {out}/c.pt       | c.pt
predict   | predict {calibrated} {test} --out {out}/s.npz                               | s.npz
monitor   | monitor {calibrated} {test} --out {out}                                     | monitor.json monitor.png
certify   | certify {calibrated} --data {test} --out {out}                              | certificate.json report.html
split     | split {test} --out {out}                                                    | train.csv calibration.csv test.csv split.json
prove     | prove-containment {problems} --out {out}/c.json                             | c.json
export    | export {model} --onnx {out}/m.onnx                                          | m.onnx
ingest    | ingest trajectories --truth {gt} --estimate {est} --out {out}/o.csv         | o.csv o.manifest.json
"""  # noqa: E501 (one case per line)
CASES = [tuple(cell.strip() for cell in line.split("|")) for line in WRITERS.strip().splitlines()]


def _argv(command: str, inputs: dict[str, Path], out: Path) -> list[str]:
    paths = {k: shlex.quote(str(v)) for k, v in inputs.items()}
    return shlex.split(command.format(out=shlex.quote(str(out)), **paths))


@pytest.mark.parametrize(("command", "names"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_an_existing_output_is_refused_and_kept_and_force_replaces_it(
    inputs, tmp_path, run_cli, command, names
):
    out = tmp_path / "new" / "folder"
    argv = _argv(command, inputs, out)
    first = run_cli(*argv)
    assert first.code == 0, first.stderr
    assert f"created the folder {out}\n" in first.stdout
    files = [out / name for name in names.split()]
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in files)
    written = {p: p.read_bytes() for p in files}

    again = run_cli(*argv)
    assert again.code == 2 and again.stdout == ""
    assert again.stderr.startswith("error: ") and len(again.stderr.strip().splitlines()) == 1
    assert "pass --force to replace" in again.stderr
    assert {p: p.read_bytes() for p in files} == written  # nothing was touched

    for p in files:  # an earlier run's files, to see that --force replaces every one of them
        p.write_bytes(b"an earlier run's file")
    forced = run_cli(*argv, "--force")
    assert forced.code == 0, forced.stderr
    assert "created the folder" not in forced.stdout
    assert all(p.read_bytes() != b"an earlier run's file" for p in files)
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in files)  # no scratch left


def test_the_table_covers_every_command_that_writes():
    from ipcverify.cli import app

    writers = {c[1].split()[0] for c in CASES}
    for name, command in app.commands.items():
        options = {p.name for p in command.params}
        if isinstance(command, click.Group):
            options = {p.name for sub in command.commands.values() for p in sub.params}
        assert ("force" in options) == (name in writers | {"demo", "ingest"}), name


def test_a_folder_output_counts_the_files_written_not_the_folder(inputs, tmp_path, run_cli):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes\n", encoding="utf-8")
    res = run_cli("certify", inputs["calibrated"], "--data", inputs["test"], "--out", out)
    assert res.code == 0, res.stderr
    assert "created the folder" not in res.stdout
    assert (out / "notes.txt").read_text(encoding="utf-8") == "my notes\n"
    (out / "certificate.json").unlink()  # one of the two left: named alone
    res = run_cli("certify", inputs["calibrated"], "--data", inputs["test"], "--out", out)
    assert res.code == 2
    assert res.stderr == (
        f"error: --out {out} already holds report.html; pass --force to replace it, or choose another "
        "folder\n"
    )


def test_a_manifest_left_beside_the_table_is_named(inputs, tmp_path, run_cli):
    (tmp_path / "o.manifest.json").write_text("{}", encoding="utf-8")
    out = tmp_path / "o.csv"
    res = run_cli(
        "ingest", "trajectories", "--truth", inputs["gt"], "--estimate", inputs["est"], "--out", out
    )
    assert res.code == 2 and not out.exists()
    assert res.stderr == (
        f"error: --out {out}: o.manifest.json exists; pass --force to replace it, or choose another path\n"
    )


@pytest.mark.parametrize("force", [[], ["--force"]], ids=["plain", "force"])
def test_an_output_whose_extension_does_not_fit_is_refused_even_with_force(inputs, tmp_path, run_cli, force):
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n", encoding="utf-8")
    res = run_cli("export", inputs["model"], "--onnx", notes, *force)
    assert res.code == 2
    assert res.stderr == "error: --onnx must end in .onnx (an ONNX graph); got notes.txt\n"
    assert notes.read_text(encoding="utf-8") == "my notes\n"


def test_a_forced_export_that_fails_its_check_keeps_the_old_file(inputs, tmp_path, run_cli, monkeypatch):
    from ipcverify.io import _onnx

    old = tmp_path / "m.onnx"
    old.write_bytes(b"an earlier export")

    def disagrees(*args, **kwargs):
        return _onnx.OnnxCheck(samples=1, vs_engine_center=1.0, vs_engine_shape=1.0, vs_torch_center=1.0,
                               vs_torch_shape=1.0)  # fmt: skip

    monkeypatch.setattr(_onnx, "check_onnx", disagrees)
    res = run_cli("export", inputs["model"], "--onnx", old, "--force")
    assert res.code == 2 and f"nothing was written to {old}" in res.stderr
    assert old.read_bytes() == b"an earlier export"
    assert [p.name for p in tmp_path.iterdir()] == ["m.onnx"]  # the scratch file is gone
    res = run_cli("export", inputs["model"], "--onnx", tmp_path / "new.onnx")  # nothing to keep
    assert res.code == 2 and not (tmp_path / "new.onnx").exists()


def test_demo_refuses_a_folder_holding_its_files_before_computing_anything(tmp_path, run_cli, monkeypatch):
    from ipcverify import demo

    def must_not_run(*args, **kwargs):
        raise AssertionError("the demo ran")

    monkeypatch.setattr(demo, "run_demo", must_not_run)
    (tmp_path / "model.pt").write_bytes(b"an earlier demo's model")
    (tmp_path / "mine.txt").write_text("my notes\n", encoding="utf-8")
    res = run_cli("demo", "--out", tmp_path)
    assert res.code == 2
    assert res.stderr == (
        f"error: --out {tmp_path} already holds model.pt; pass --force to replace it, or choose another "
        "folder\n"
    )
    assert (tmp_path / "model.pt").read_bytes() == b"an earlier demo's model"


# id | the command line | the one error line's fragment: nothing done is a user error, not a success
NOTHING_DONE = """
split-one-row       | split {one_row} --out {tmp}/s             | one_row.csv has 1 row, too few for split fractions [0.6, 0.2, 0.2]: the calibration and test parts would get no row; use about 5 or more rows
check-empty-list    | check-certificate {empty}                  | empty.json: an empty list, no certificate in it; give one certificate object or a list of them
prove-empty-list    | prove-containment {empty} --out {tmp}/c.json | empty.json: an empty list, no problem in it
evaluate-bins-alone | evaluate {model} {test} --bins -2           | --bins sets the number of bins of --bin-column COL; give the column, or leave --bins out
certify-bins-alone  | certify {calibrated} --bins 3 --bin-column x_0 --out {tmp}/c | --bin-column and --bins are for binning the test data's coverage; without --data TEST there is no test data -- give --data, or leave them out
train-lam-ignored   | train {train} --out {tmp}/m.pt --lam 0.1    | --lam belongs to the hinge loss, but this run trains with recipe tight's likelihood loss and would ignore it: add --loss hinge, or leave it out
"""  # noqa: E501 (one case per line)
NOTHING = [tuple(cell.strip() for cell in line.split("|")) for line in NOTHING_DONE.strip().splitlines()]


@pytest.mark.parametrize(("command", "fragment"), [c[1:] for c in NOTHING], ids=[c[0] for c in NOTHING])
def test_a_command_that_would_do_nothing_or_ignore_an_option_refuses(
    inputs, tmp_path, run_cli, command, fragment
):
    (tmp_path / "one_row.csv").write_text(
        "".join(inputs["test"].read_text(encoding="utf-8").splitlines(keepends=True)[:2]), encoding="utf-8"
    )
    (tmp_path / "empty.json").write_text("[]", encoding="utf-8")
    paths = {**inputs, "one_row": tmp_path / "one_row.csv", "empty": tmp_path / "empty.json"}
    res = run_cli(*shlex.split(command.format(tmp=shlex.quote(str(tmp_path)), **{
        k: shlex.quote(str(v)) for k, v in paths.items()
    })))  # fmt: skip
    assert res.code == 2 and res.stdout == ""
    assert res.stderr.startswith("error: ") and len(res.stderr.strip().splitlines()) == 1
    assert fragment in res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.json", "one_row.csv"]  # nothing written


def _hinting(fail: bool) -> click.Group:
    @click.group()
    def group() -> None:
        """A program whose one command hints, warns, prints, and fails or not."""

    @group.command("go")
    def go() -> None:
        warnings.warn(Hint("look at this"), stacklevel=1)
        warnings.warn(DataWarning("this data is odd"), stacklevel=1)
        click.echo("done")
        if fail:
            raise InvalidInputError("this is wrong")

    return group


@pytest.mark.parametrize("fail", [True, False], ids=["error", "success"])
def test_a_hint_comes_after_the_error_or_the_output_and_a_warning_at_once(capsys, fail):
    from ipcverify.cli.app import run_group

    with pytest.raises(SystemExit) as exc:
        run_group(_hinting(fail), ["go"], "prog")
    err = capsys.readouterr().err.splitlines()
    assert exc.value.code == (2 if fail else 0)
    expected = (
        ["warning: this data is odd"] + (["error: this is wrong"] if fail else []) + ["hint: look at this"]
    )
    assert err == expected


def test_the_ingest_hint_follows_its_error(tmp_path, run_cli):
    """The estimate starts at the identity pose (a hint) and its stamps are nanoseconds (the error)."""
    rows = [f"{1.4e18 + 0.05 * i * 1e9:.0f} {0.05 * i} 0 0 0 0 0 1" for i in range(100)]
    (tmp_path / "ns.txt").write_text("\n".join(rows) + "\n", encoding="utf-8")
    res = run_cli("ingest", "trajectories", "--truth", tmp_path / "ns.txt", "--estimate", tmp_path / "ns.txt",
                  "--out", tmp_path / "o.csv")  # fmt: skip
    lines = res.stderr.splitlines()
    assert res.code == 2 and len(lines) == 2
    assert lines[0].startswith("error: run ns: the estimate spans") and "look like nanoseconds" in lines[0]
    assert lines[1].startswith("hint: the estimate of run ns starts at the identity pose")
