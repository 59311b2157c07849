"""The exit-status contract of every command (docs/cli.md): 0 success, 1 a verdict against the model,
2 a user error, 3 an internal error (one line; the traceback only with --debug), 130 interrupted."""

from __future__ import annotations

import warnings

import click
import pytest

import ipcverify.demo as demo  # the demo command imports run_demo from here when it runs
from ipcverify.cli.app import EXIT_INTERNAL, EXIT_USER, EXIT_VERDICT, run_group
from ipcverify.errors import DataWarning, Hint


def _crash(*args, **kwargs):
    raise RuntimeError("something inside broke")


def test_an_internal_error_exits_3_with_one_line_and_a_pointer_to_debug(run_cli, monkeypatch, tmp_path):
    monkeypatch.setattr(demo, "run_demo", _crash)
    res = run_cli("demo", "--out", tmp_path / "d")
    assert res.code == EXIT_INTERNAL == 3
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr
    assert lines[0].startswith("error: internal error (RuntimeError: something inside broke)")
    assert "--debug" in lines[0] and "please report it" in lines[0]


def test_debug_prints_the_traceback_and_keeps_the_status(run_cli, monkeypatch, tmp_path):
    monkeypatch.setattr(demo, "run_demo", _crash)
    res = run_cli("--debug", "demo", "--out", tmp_path / "d")
    assert res.code == 3
    assert (
        "Traceback (most recent call last)" in res.stderr
        and "RuntimeError: something inside broke" in res.stderr
    )
    assert res.stderr.strip().splitlines()[-1].startswith("error: internal error")
    user = run_cli("--debug", "train", tmp_path / "missing.csv", "--out", tmp_path / "m.pt")
    assert user.code == EXIT_USER == 2  # --debug changes what is printed, never the status
    assert "Traceback" in user.stderr and user.stderr.strip().splitlines()[-1].startswith("error: ")


def test_the_debug_flag_does_not_stick_to_the_next_command_line(run_cli, monkeypatch, tmp_path):
    monkeypatch.setattr(demo, "run_demo", _crash)
    run_cli("--debug", "demo", "--out", tmp_path / "d")
    res = run_cli("demo", "--out", tmp_path / "d")
    assert res.code == 3 and "Traceback" not in res.stderr


def test_an_os_error_without_a_file_is_internal_and_with_a_file_is_the_users(run_cli, monkeypatch, tmp_path):
    def no_space(*args, **kwargs):
        raise OSError(28, "No space left on device", str(tmp_path / "d" / "train.csv"))

    monkeypatch.setattr(demo, "run_demo", no_space)
    res = run_cli("demo", "--out", tmp_path / "d")
    assert res.code == 2 and res.stderr == f"error: {tmp_path / 'd' / 'train.csv'}: No space left on device\n"
    monkeypatch.setattr(demo, "run_demo", lambda *a, **k: (_ for _ in ()).throw(OSError("socket closed")))
    assert run_cli("demo", "--out", tmp_path / "d").code == 3


def test_running_out_of_memory_is_the_users_with_what_to_shrink(run_cli, monkeypatch, tmp_path):
    def too_big(*args, **kwargs):
        raise MemoryError("Unable to allocate 728. TiB for an array with shape (100000000000000,)")

    monkeypatch.setattr(demo, "run_demo", too_big)
    res = run_cli("demo", "--out", tmp_path / "d")
    assert res.code == EXIT_USER == 2 and "Traceback" not in res.stderr
    assert (
        res.stderr.startswith("error: out of memory (Unable to allocate 728. TiB")
        and res.stderr.count("\n") == 1
    )
    assert "use smaller inputs or settings" in res.stderr


def _group_with(body) -> click.Group:
    @click.group()
    def g() -> None:
        """A test program."""

    @g.command("go")
    def go() -> None:
        body()

    return g


def _run(group: click.Group, args: list[str]) -> int:
    with pytest.raises(SystemExit) as exc:
        run_group(group, args, "prog")
    return int(exc.value.code or 0)


def test_warnings_and_hints_are_one_line_each_and_ctrl_c_exits_130(capsys):
    def warn() -> None:
        warnings.warn(DataWarning("rows repeat\n  (three of them)"), stacklevel=1)
        warnings.warn(Hint("a 'run' column"), stacklevel=1)

    assert _run(_group_with(warn), ["go"]) == 0
    assert capsys.readouterr().err == "warning: rows repeat (three of them)\nhint: a 'run' column\n"

    def interrupt() -> None:
        raise KeyboardInterrupt

    assert _run(_group_with(interrupt), ["go"]) == 130
    assert capsys.readouterr().err.endswith("error: interrupted\n")


def test_a_verdict_exits_1_and_the_bare_program_prints_its_help(capsys):
    def contradicted() -> None:
        raise SystemExit(EXIT_VERDICT)

    assert _run(_group_with(contradicted), ["go"]) == 1
    assert _run(_group_with(lambda: None), []) == 0
    out = capsys.readouterr().out
    assert "A test program." in out and "--debug" in out  # the global flag is on every program
