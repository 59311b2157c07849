"""The command line: collect writes a dataset; bad input is one line and exit status 2."""

from __future__ import annotations

import pandas as pd
import pytest

from case_studies.quad_landing.cli import main


def _run(capsys, *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_collect_writes_the_dataset(tmp_path, capsys):
    out = tmp_path / "data.parquet"
    code, stdout, _ = _run(capsys, "collect", "--buffer-size", "1", "--n", "25", "--seed", "3",
                           "--out", out, "--quiet")  # fmt: skip
    assert code == 0 and out.exists() and (tmp_path / "data.stats.json").exists()
    assert len(pd.read_parquet(out)) == 25
    assert "25 samples" in stdout and "detection rate" in stdout
    (tmp_path / "data.stats.json").write_text("{}", encoding="utf-8")  # an earlier run's
    code, _, stderr = _run(capsys, "collect", "--n", "5", "--out", out, "--quiet")
    assert code == 2 and stderr == (
        f"error: --out {out}: data.parquet and data.stats.json exist; pass --force to replace them, or "
        "choose another path\n"
    )
    assert len(pd.read_parquet(out)) == 25
    code, _, _ = _run(capsys, "collect", "--n", "5", "--seed", "3", "--out", out, "--quiet", "--force")
    assert code == 0 and len(pd.read_parquet(out)) == 5


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["collect", "--n", "0", "--out", "{d}/x.parquet"], "--n"),
        (["collect", "--n", "5", "-k", "-1", "--out", "{d}/x.parquet"], "--buffer-size"),
        (["collect", "--n", "5", "--out", "{d}/x.txt"], ".parquet or .csv"),
        (["collect", "--n", "5", "--out", "{d}/missing/x.csv"], "does not exist"),
        (["collect", "--n", "5", "--out", "{d}/x.csv", "--config", "{d}/nope.toml"],
         "does not exist"),
        (["collect", "--n", "5", "--out", "{d}/x.csv", "--config", "{d}/bad.toml"],
         "unknown key"),
        (["collect", "--n", "5"], "--out"),
        (["fly"], "No such command"),
        (["sensitivity", "--out", "{d}/s", "--only", "warp-speed"], "unknown sensitivity variants"),
        (["reader-timing", "--frames", "3"], "--frames"),
    ],
)  # fmt: skip
def test_cli_bad_input_is_one_line_and_status_2(tmp_path, capsys, args, match):
    (tmp_path / "bad.toml").write_text("[camera]\nfocal = 3\n")
    code, _, stderr = _run(capsys, *[a.format(d=tmp_path) for a in args])
    assert code == 2
    assert stderr.startswith("error: ") and len(stderr.strip().splitlines()) == 1
    assert match in stderr
    assert not list(tmp_path.glob("x.*"))


def test_cli_reader_timing_prints_the_toml_lines(capsys):
    code, stdout, _ = _run(capsys, "reader-timing", "--frames", "12")
    assert code == 0
    assert "detector_ms = [" in stdout and "cpu_scale = " in stdout and "parallel_speedup = " in stdout
