"""Start-up of the command line: ``ipcverify --version`` and ``--help`` against ``import numpy, click``.

Run ``python -m benchmarks.bench_startup`` (about a minute on 2 cores). It writes
``benchmarks/startup_results.json``. Target (issue 29, point 4): ``ipcverify --help`` and
``ipcverify --version`` take at most 3 times as long as ``python -c "import numpy, click"``.

Every command is a fresh interpreter (``subprocess``), the way a user or a script starts it:

* ``bare`` -- ``python -c "import numpy, click"``, the reference;
* ``version``, ``help``, ``predict_help`` -- ``ipcverify --version``, ``--help``, ``predict --help``;
* ``predict`` -- the first real ``ipcverify predict`` of a process: a calibrated default-recipe
  model (with its domain of validity) on a 100-row CSV file;
* ``import_torch`` -- ``python -c "import torch"``, for scale: what ``predict`` no longer pays.

``ipcverify`` is run as its console script runs it (``from ipcverify.cli import main;
sys.exit(main())``) by the same interpreter. The commands are run in turns (one of each, then
the next round), after one warm-up round that is not counted, so that a change of load on the
shared machine touches all of them alike; wall time and CPU time (user + system, of the child)
are recorded per run and their medians reported, with the load average before and after. One
extra run per command records which heavy libraries it imported.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from benchmarks.timing import run_child

__all__ = ["TARGET_FACTOR", "HEAVY", "bench_startup", "main"]

OUT = Path(__file__).with_name("startup_results.json")
ROOT = Path(__file__).resolve().parent.parent
#: ``--help`` and ``--version`` may take at most this many times the bare ``import numpy, click``.
TARGET_FACTOR = 3.0
#: Libraries whose import costs tenths of a second or more.
HEAVY = ("torch", "numba", "scipy", "pandas", "pyarrow", "matplotlib", "cvxpy", "clarabel", "rosbags", "onnx")
_CLI = "import sys; from ipcverify.cli import main; sys.exit(main())"
_PROBE = (
    "import atexit, json, sys\n"
    "def _write():\n"
    "    open({path!r}, 'w').write(json.dumps(sorted(m for m in {heavy!r} if m in sys.modules)))\n"
    "atexit.register(_write)\n"
)


def _model_and_queries(folder: Path, n_train: int, epochs: int) -> tuple[Path, Path]:
    """A calibrated default-recipe model file and a 100-row query file (trained in this process)."""
    from ipcverify.contract import calibrate
    from ipcverify.data import save_dataset
    from ipcverify.data._synthetic import make_lagged_perception
    from ipcverify.io import save_model
    from ipcverify.training import TrainConfig, train

    config = TrainConfig(epochs=epochs, val_fraction=0.0, patience=None)
    model = train(make_lagged_perception(n_train, seed=0), train_config=config).model
    calibrated = calibrate(model, make_lagged_perception(1000, seed=1), 0.05, 0.01)
    save_model(calibrated, folder / "calibrated.pt")
    queries = make_lagged_perception(100, seed=2)
    save_dataset(queries, folder / "queries.csv")
    return folder / "calibrated.pt", folder / "queries.csv"


def _commands(model: Path, queries: Path, out: Path) -> dict[str, list[str]]:
    py = sys.executable
    return {
        "bare": [py, "-c", "import numpy, click"],
        "version": [py, "-c", _CLI, "--version"],
        "help": [py, "-c", _CLI, "--help"],
        "predict_help": [py, "-c", _CLI, "predict", "--help"],
        "predict": [py, "-c", _CLI, "predict", str(model), str(queries), "--out", str(out), "--force"],
        "import_torch": [py, "-c", "import torch"],
    }


def _describe(argv: list[str]) -> str:
    """The command as a user types it."""
    if argv[2] == _CLI:
        return " ".join(["ipcverify", *argv[3:]])
    return f'python -c "{argv[2]}"'


def _run(argv: list[str]) -> tuple[float, float, int]:
    """Wall and CPU seconds (user + system of the child) of one run, and its exit status."""
    res = run_child(argv, cwd=ROOT)
    if res.returncode != 0:
        print(res.stderr, file=sys.stderr)
    return res.wall_s, res.cpu_s, res.returncode


def _heavy_imports(argv: list[str], folder: Path) -> list[str] | None:
    """The heavy libraries one run of ``argv`` imported (None for a command that is not ipcverify's)."""
    if argv[2] != _CLI:
        return None
    path = folder / "modules.json"
    code = _PROBE.format(path=str(path), heavy=HEAVY) + _CLI
    subprocess.run([argv[0], "-c", code, *argv[3:]], cwd=ROOT, capture_output=True, check=False)
    return list(json.loads(path.read_text())) if path.exists() else None


def bench_startup(repeats: int = 9, n_train: int = 2000, epochs: int = 5) -> dict[str, Any]:
    """Median wall and CPU time of each command over ``repeats`` rounds, the ratios and the target.

    The model that ``predict`` reads is the default recipe trained ``epochs`` epochs on ``n_train``
    synthetic samples (its size, not its quality, is what start-up depends on).
    """
    if repeats < 1:
        raise ValueError("repeats must be at least 1")
    load_before = [round(v, 2) for v in os.getloadavg()]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        model, queries = _model_and_queries(folder, n_train, epochs)
        commands = _commands(model, queries, folder / "sets.npz")
        runs: dict[str, list[tuple[float, float, int]]] = {name: [] for name in commands}
        first = {name: _run(argv) for name, argv in commands.items()}  # warm-up round, not counted
        for _ in range(repeats):
            for name, argv in commands.items():
                runs[name].append(_run(argv))
        heavy = {name: _heavy_imports(argv, folder) for name, argv in commands.items()}
    out: dict[str, Any] = {}
    for name, argv in commands.items():
        walls, cpus, codes = zip(*runs[name], strict=True)
        out[name] = {
            "command": _describe(argv).replace(str(folder), "TMP"),
            "wall_s": statistics.median(walls),
            "cpu_s": statistics.median(cpus),
            "wall_s_runs": list(walls),
            "cpu_s_runs": list(cpus),
            "first_run_wall_s": first[name][0],
            "exit_codes": sorted(set(codes) | {first[name][2]}),
            "heavy_modules_imported": heavy[name],
        }
    bare = out["bare"]["wall_s"]
    ratios = {name: r["wall_s"] / bare for name, r in out.items() if name != "bare"}
    worst = max(ratios["help"], ratios["version"])
    return {
        "repeats": repeats,
        "model": f"default recipe, {n_train} training rows, {epochs} epochs, calibrated with a domain test",
        "load_average_before": load_before,
        "load_average_after": [round(v, 2) for v in os.getloadavg()],
        "commands": out,
        "ratio_to_bare": ratios,
        "target": {
            "what": "ipcverify --help and --version wall time / python -c 'import numpy, click' (medians)",
            "limit": TARGET_FACTOR,
            "value": worst,
            "met": worst <= TARGET_FACTOR,
        },
        "all_succeeded": all(code == 0 for r in out.values() for code in r["exit_codes"]),
    }


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9, help="rounds of every command (default 9)")
    parser.add_argument("--quick", action="store_true", help="2 rounds and a tiny model: a smoke test")
    parser.add_argument("--out", type=Path, default=OUT, help=f"JSON output (default {OUT.name} beside this)")
    args = parser.parse_args(argv)
    from benchmarks.common import machine_info, write_json

    result = {
        "command": "python -m benchmarks.bench_startup" + (" --quick" if args.quick else ""),
        "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": machine_info(),
        **(bench_startup(2, n_train=300, epochs=1) if args.quick else bench_startup(args.repeats)),
    }
    write_json(args.out, result)
    for name, r in result["commands"].items():
        ratio = result["ratio_to_bare"].get(name)
        print(
            f"{name:13s} wall {r['wall_s']:6.3f} s  cpu {r['cpu_s']:6.3f} s"
            + ("" if ratio is None else f"  x{ratio:5.2f} of bare")
            + f"  heavy: {r['heavy_modules_imported']}"
        )
    t = result["target"]
    print(f"target: {t['what']} <= {t['limit']:g}: {t['value']:.2f} ({'met' if t['met'] else 'NOT met'})")
    return result


if __name__ == "__main__":
    main()
