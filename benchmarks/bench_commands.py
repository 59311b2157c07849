"""Wall and CPU time of the long commands the README and the docs quote, each from scratch.

Run ``python -m benchmarks.bench_commands`` on an idle machine (about 10 minutes on 2 cores;
``--full`` adds the full reproduction, about 6 minutes more). It writes
``benchmarks/command_timings.json``; the times in README.md and docs/ are the ones it
measured, given as wall time beside CPU-seconds (issue 29, point 5).

Every command runs in a fresh interpreter (``subprocess``), in an empty temporary folder, the
way a user types it after ``pip install``:

* ``demo`` -- ``ipcverify demo`` (README, "Quick start");
* ``collect`` -- ``python -m case_studies.quad_landing collect --n 5000`` (README, "Case study");
* ``train`` -- ``ipcverify train`` on those 5,000 samples (the default recipe);
* ``train_paper`` -- ``ipcverify train --recipe paper`` on them (the paper's recipe, with its
  selection of alpha, lambda and the batch size);
* ``reproduce_quick`` -- ``reproduce --quick --fly-uncalibrated`` into an empty folder
  (README and docs/reproduce.md; issue 26's target: at most 90 s);
* ``sensitivity`` -- ``python -m case_studies.quad_landing sensitivity`` (docs/case_study.md);
* ``ingest_example`` -- ``python -m docgen.ingest_example`` (docs/ingest.md's worked example:
  100 bags written, ingested, trained, calibrated and certified);
* ``certify_euroc`` -- docs/certify.md's worked example on the EuRoC log (split, train,
  calibrate by flight, certify with the report);
* ``reproduce_full`` (``--full``) -- the full run into an empty folder (target: at most 10 min).

CPU time is user + system of the child and its children (the reproduction flies in worker
processes), from ``getrusage(RUSAGE_CHILDREN)``; the load average before and after each command
shows whether the machine was idle. Each command runs once: they take seconds to minutes, and
their spread on an idle machine is a few per cent (rerun to see it).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from benchmarks.timing import run_child

__all__ = ["TARGETS", "bench_commands", "commands", "main"]

OUT = Path(__file__).with_name("command_timings.json")
ROOT = Path(__file__).resolve().parent.parent
_CLI = "import sys; from ipcverify.cli import main; sys.exit(main())"
#: docs/certify.md's worked example on the EuRoC log: split by run, train, calibrate by flight, certify.
_EUROC = (
    'set -e; cd {folder}; {py} -c "import pandas as pd; '
    "df = pd.read_csv('{root}/data/euroc_mh04_vislam.csv'); "
    "df['flight'] = df['method'] + ':' + df['run'].astype(str); "
    "df[df.run <= 3].to_csv('train.csv', index=False); "
    "df[df.run.between(4, 6)].to_csv('calibration.csv', index=False); "
    "df[df.run >= 7].to_csv('test.csv', index=False)\"; "
    "{py} -c '{cli}' train train.csv --out model.pt; "
    "{py} -c '{cli}' calibrate model.pt calibration.csv --epsilon 0.5 --delta 0.1 --group-column flight "
    "--domain-flag-rate 0.2 --out calibrated.pt; "
    "{py} -c '{cli}' certify calibrated.pt --data test.csv --train-data train.csv --units m "
    "--labels 'body x,body y,body z' --out certificate"
)
#: Wall-time limits (seconds) that an issue sets for a command.
TARGETS = {"reproduce_quick": 90.0, "reproduce_full": 600.0}


def commands(folder: Path, full: bool = False, quick: bool = False) -> dict[str, list[str]]:
    """The commands, in order (later ones read what earlier ones wrote in ``folder``).

    ``quick`` shrinks them to a smoke test of the harness (its numbers mean nothing).
    """
    py = sys.executable
    cli = [py, "-c", _CLI]
    quad = [py, "-m", "case_studies.quad_landing"]
    n = "300" if quick else "5000"
    data, model = folder / "data.parquet", folder / "ipc.pt"
    out: dict[str, list[str]] = {
        "demo": [py, "-c", _CLI, "demo", "--out", str(folder / "demo")],
        "collect": [*quad, "collect", "--buffer-size", "1", "--n", n] + ["--seed", "0", "--out", str(data)],
        "train": [py, "-c", _CLI, "train", str(data), "--out", str(model)],
        "train_paper": [*cli, "train", str(data), "--recipe", "paper", "--out", str(folder / "p.pt")],
        "reproduce_quick": [*quad, "reproduce", "--out", str(folder / "quick")]
        + ["--quick", "--fly-uncalibrated"],
    }
    out["sensitivity"] = [*quad, "sensitivity", "--out", str(folder / "sens")]
    out["ingest_example"] = [py, "-m", "docgen.ingest_example", "--out", str(folder / "ingest")]
    out["ingest_example"] += ["--figure", str(folder / "ingest.png")]
    out["certify_euroc"] = ["bash", "-c", _EUROC.format(py=py, cli=_CLI, folder=folder, root=ROOT)]
    if quick:
        del out["demo"], out["reproduce_quick"], out["sensitivity"], out["ingest_example"]
        del out["certify_euroc"]
        out["train"] += ["--epochs", "1"]
        out["train_paper"] += ["--epochs", "1"]
    if full and not quick:
        out["reproduce_full"] = [*quad, "reproduce", "--out", str(folder / "full")]
        out["reproduce_full"] += ["--fly-uncalibrated"]
    return out


def _describe(argv: list[str], folder: Path) -> str:
    """The command as a user types it (the temporary folder shown as ``TMP``)."""
    if argv[0] == "bash":
        return (
            "docs/certify.md's EuRoC example (split by run; train; calibrate --group-column flight; certify)"
        )
    words = ["ipcverify", *argv[3:]] if argv[1:3] == ["-c", _CLI] else ["python", *argv[1:]]
    return " ".join(words).replace(str(folder), "TMP")


def _run(argv: list[str]) -> dict[str, Any]:
    """Wall and CPU seconds of one run, its exit status and the load average around it."""
    load = os.getloadavg()[0]
    res = run_child(argv, cwd=ROOT)
    if res.returncode != 0:
        print(res.stderr[-2000:], file=sys.stderr)
    return {
        "wall_s": round(res.wall_s, 2),
        "cpu_s": round(res.cpu_s, 2),
        "exit_code": res.returncode,
        "load_1min_before": round(load, 2),
        "load_1min_after": round(os.getloadavg()[0], 2),
    }


def bench_commands(
    full: bool = False, quick: bool = False, only: tuple[str, ...] = (), keep: Path | None = None
) -> dict[str, Any]:
    """Run the commands once each in a fresh folder; their times, exit codes and targets.

    The folder is temporary, or ``keep`` (which must be empty or new), whose outputs are kept.
    """
    out: dict[str, Any] = {}
    if keep is not None and keep.exists() and any(keep.iterdir()):
        raise SystemExit(f"error: {keep} is not empty; the commands run from scratch -- give a new folder")
    with contextlib.nullcontext(str(keep)) if keep is not None else tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for name, argv in commands(folder, full, quick).items():
            if only and name not in only and name != "collect":  # train needs the collected data
                continue
            print(f"{name}: {_describe(argv, folder)}", flush=True)
            out[name] = {"command": _describe(argv, folder), **_run(argv)}
            print(f"  {out[name]['wall_s']:.1f} s wall, {out[name]['cpu_s']:.1f} CPU-s", flush=True)
    targets = {
        name: {"limit_wall_s": limit, "wall_s": out[name]["wall_s"], "met": out[name]["wall_s"] <= limit}
        for name, limit in TARGETS.items()
        if name in out and not quick
    }
    return {
        "commands": out,
        "targets": targets,
        "all_succeeded": all(r["exit_code"] == 0 for r in out.values()),
    }


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="also the full reproduction (about 8 minutes)")
    parser.add_argument("--quick", action="store_true", help="tiny sizes: a smoke test, numbers mean nothing")
    parser.add_argument("--only", nargs="+", default=[], help="run only these commands (and collect)")
    parser.add_argument("--keep", type=Path, default=None, help="run in this new folder and keep the outputs")
    parser.add_argument("--out", type=Path, default=OUT, help=f"JSON output (default {OUT.name} beside this)")
    args = parser.parse_args(argv)
    from benchmarks.common import machine_info, write_json

    result = {
        "command": "python -m benchmarks.bench_commands"
        + (" --full" if args.full else "")
        + (" --quick" if args.quick else ""),
        "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": machine_info() | {"note": "each command once, from an empty folder"},
        **bench_commands(args.full, args.quick, tuple(args.only), args.keep),
    }
    if args.only and args.out.is_file():  # a partial rerun updates the other commands' entries in place
        import json

        previous = json.loads(args.out.read_text())
        result["command"] = (
            f"{previous.get('command', '?')}; then {result['command']} --only {' '.join(args.only)}"
        )
        result["commands"] = previous.get("commands", {}) | result["commands"]
        result["targets"] = previous.get("targets", {}) | result["targets"]
        result["all_succeeded"] = all(r["exit_code"] == 0 for r in result["commands"].values())
    write_json(args.out, result)
    for name, t in result["targets"].items():
        verdict = "met" if t["met"] else "NOT met"
        print(f"target {name}: {t['wall_s']:.1f} s <= {t['limit_wall_s']:g} s: {verdict}")
    return result


if __name__ == "__main__":
    main()
