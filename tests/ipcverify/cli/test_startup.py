"""The CLI starts without the heavy libraries (docs/develop.md, "Start-up"; docs/cli.md).

Importing ``ipcverify`` or ``ipcverify.cli``, and running ``--help``, ``--version`` and every
command's ``--help``, must not import torch, Numba, SciPy, pandas, matplotlib, cvxpy, Clarabel,
rosbags or ONNX: they are imported inside the commands that use them. Each check runs in a fresh
interpreter (this test process has them all loaded already) and reads its ``sys.modules``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import click

ROOT = Path(__file__).resolve().parents[3]
#: Libraries that cost tenths of a second or more to import (numpy, click and rich do not).
HEAVY = (
    "torch",
    "numba",
    "scipy",
    "pandas",
    "pyarrow",
    "matplotlib",
    "cvxpy",
    "clarabel",
    "rosbags",
    "onnx",
    "onnxruntime",
    "sklearn",
)

_PROBE = """
import contextlib, io, json, sys
heavy = {heavy!r}
out = {{"after_import_ipcverify": None, "runs": []}}
import ipcverify
out["after_import_ipcverify"] = sorted(m for m in heavy if m in sys.modules)
from ipcverify.cli import main
for argv in {argvs!r}:
    text = io.StringIO()
    with contextlib.redirect_stdout(text), contextlib.redirect_stderr(text):
        try:
            main(argv)
            code = 0
        except SystemExit as exc:
            code = exc.code
    out["runs"].append({{"argv": argv, "code": code, "chars": len(text.getvalue())}})
{extra}
out["heavy"] = sorted(m for m in heavy if m in sys.modules)
print(json.dumps(out))
"""


def _command_paths(group: click.Group, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Every command and sub-command of ``group``, as the words that name it."""
    paths: list[tuple[str, ...]] = []
    for name, cmd in group.commands.items():
        paths.append((*prefix, name))
        if isinstance(cmd, click.Group):
            paths += _command_paths(cmd, (*prefix, name))
    return paths


def _probe(argvs: list[list[str]], extra: str = "") -> dict:
    """Run ``ipcverify ARGV`` for each ARGV (then the code ``extra``) in a fresh interpreter."""
    code = _PROBE.format(heavy=HEAVY, argvs=argvs, extra=extra)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_help_and_version_of_every_command_load_no_heavy_library():
    from ipcverify.cli import app

    commands = _command_paths(app)
    assert {("predict",), ("certify",), ("ingest", "bag")} <= set(commands)  # the walk found them all
    argvs = [["--version"], ["--help"], []] + [[*c, "--help"] for c in commands]
    out = _probe(argvs)
    assert out["after_import_ipcverify"] == []
    assert [r["code"] for r in out["runs"]] == [0] * len(argvs), out["runs"]
    assert all(r["chars"] > 20 for r in out["runs"]), out["runs"]  # each printed its help or version
    assert out["heavy"] == [], f"imported at start-up: {out['heavy']} (move the import into the command)"


def test_the_probe_sees_a_heavy_import():
    """The check above can fail: importing what a command calls loads the heavy libraries."""
    out = _probe([["predict", "no-such-model.pt", "no-such-data.csv", "--out", "o.npz"]])
    assert out["runs"][0]["code"] == 2  # click refuses the missing file before the command body runs
    assert out["heavy"] == []
    out = _probe([], extra="import ipcverify.contract._calibrate")
    assert {"scipy", "pandas", "numba"} <= set(out["heavy"])


def test_the_defaults_written_out_in_the_cli_are_the_librarys():
    """Defaults and choices the CLI spells out (so that --help imports nothing heavy) match their owners."""
    from ipcverify.certification._lipschitz import DEFAULT_RADIUS
    from ipcverify.cli import app
    from ipcverify.guard._domain import DEFAULT_FLAG_RATE
    from ipcverify.io.ingest._formats import FORMATS
    from ipcverify.io.ingest._quantity import QUANTITIES, UP_AXES

    def option(path: tuple[str, ...], name: str) -> click.Parameter:
        cmd: click.Command = app
        for word in path:
            assert isinstance(cmd, click.Group)
            cmd = cmd.commands[word]
        return next(p for p in cmd.params if p.name == name)

    domain_flag_rate = option(("calibrate",), "domain_flag_rate")
    assert domain_flag_rate.default is None and f"[default: {DEFAULT_FLAG_RATE:g}," in str(
        domain_flag_rate.help
    )
    assert option(("certify",), "lipschitz_radius").default == DEFAULT_RADIUS
    for path in (("ingest", "bag"), ("ingest", "trajectories")):
        quantity = option(path, "quantity").type
        assert isinstance(quantity, click.Choice) and tuple(quantity.choices) == QUANTITIES
        up = option(path, "up").type
        assert isinstance(up, click.Choice) and tuple(up.choices) == tuple(UP_AXES)
    for name in ("fmt", "truth_format", "estimate_format"):
        fmt = option(("ingest", "trajectories"), name).type
        assert isinstance(fmt, click.Choice) and tuple(fmt.choices) == FORMATS
    from ipcverify.demo import DEMO_MAX_SAMPLES, DEMO_MIN_TRAIN

    assert f"({DEMO_MIN_TRAIN:,} to {DEMO_MAX_SAMPLES:,})" in (option(("demo",), "n_samples").help or "")
