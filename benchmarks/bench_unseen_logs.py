"""The documented pipeline, with its defaults, on public real logs that ipcverify was never developed on.

ipcverify was developed against one real log (``data/euroc_mh04_vislam.csv``: EuRoC MH_04, two
VI-SLAM variants). This benchmark runs what a new user types -- ``ingest trajectories``,
``split``, ``train`` (defaults), ``calibrate`` (epsilon 0.1, delta 0.01, row level),
``certify`` on the held-out part -- on other public logs, changing nothing per log but the
file names, the file format and how to split (by run where a log has many, by blocks of time
where it has one or two). It records, per log, what a reviewer would ask: does the held-out test
agree with the certificate, how many queries fall outside the domain of validity, how large the
sets are next to the errors, and what was refused. One more row deploys a contract built on
MH_04 in another room (V1_02), where the certificate must not pass.

The logs are not in this repository (their licences differ from ours); give their folders:

* ``--rpg DIR``: a checkout of https://github.com/uzh-rpg/rpg_trajectory_evaluation (MIT): the
  two VI-SLAM variants on EuRoC V1_02, 10 runs each, with ground truth
  (``results/euroc_vislam_mono/laptop/...``);
* ``--evo DIR``: the ``test/data`` folder of https://github.com/MichaelGrupp/evo (used only as
  data, never as code): KITTI 00 (ORB-SLAM and S-PTAM against the KITTI ground truth), TUM RGB-D
  fr2/desk (ORB-SLAM) and fr1/xyz (RGBD-SLAM), and one estimator on EuRoC V1_02 with EuRoC's
  ground-truth CSV.

``python -m benchmarks.bench_unseen_logs --rpg RPG --evo EVO`` (a few minutes on 2 cores)
writes ``benchmarks/unseen_logs_results.json`` and ``docs/img/unseen_logs.png``; docs/real_logs.md
quotes them, and ``tests/benchmarks/test_bench_unseen_logs.py`` checks the page against the
record.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import re
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmarks.common import save_figure, write_json
from ipcverify.calibration import min_calibration_size, pac_rows_allowing
from ipcverify.guard import DEFAULT_ALPHA

__all__ = ["EPSILON", "DELTA", "LOGS", "Log", "bench_unseen_logs", "main"]

ROOT = Path(__file__).resolve().parent.parent
OUT = Path(__file__).with_name("unseen_logs_results.json")
FIGURE = ROOT / "docs" / "img" / "unseen_logs.png"
MH04 = ROOT / "data" / "euroc_mh04_vislam.csv"
#: The one target every log is calibrated to (row level), and the confidence parameter.
EPSILON, DELTA = 0.1, 0.01
_RPG = "{rpg}/results/euroc_vislam_mono/laptop"


@dataclass(frozen=True)
class Log:
    """One public log: how to ingest it and how to split it.

    Attributes
    ----------
    name : str
        Short name (a row of the table).
    what : str
        The platform, the sequence and the estimator(s).
    ingest : tuple of str
        Arguments of ``ipcverify ingest trajectories`` (``{rpg}`` and ``{evo}`` are the folders).
    split : tuple of str
        Arguments of ``ipcverify split`` besides the file and ``--out``.
    group_column : str
        The column ``certify --group-column`` counts the test by (what the split kept whole).
    """

    name: str
    what: str
    ingest: tuple[str, ...]
    split: tuple[str, ...]
    group_column: str

    def __post_init__(self) -> None:
        if not (self.name and self.ingest and self.group_column):
            raise ValueError("a log has a name, ingest arguments and a group column")


def _vislam_v102() -> tuple[str, ...]:
    """The 20 VI-SLAM runs on V1_02, one ``ingest`` call (docs/ingest.md's loop, one room over)."""
    args: list[str] = ["--format", "tum", "--max-gap", "3"]
    for m, stem in (("rp", "stamped_traj_estimate"), ("ba", "stamped_ba_estimate")):
        folder = f"{_RPG}/vislam_{m}/laptop_vislam_{m}_V1_02"
        for k in range(10):
            args += ["--truth", f"{folder}/stamped_groundtruth.txt"]
            args += ["--estimate", f"{folder}/{stem}{k}.txt", "--run", f"vislam_{m}:{k}"]
    return tuple(args)


def _in_blocks(seconds: int) -> tuple[tuple[str, ...], str]:
    """The split of a log of one or two long runs: blocks of ``seconds``, named ``segment``."""
    return ("--block", str(seconds), "--name-groups", "segment"), "segment"


LOGS: tuple[Log, ...] = (
    Log(
        "EuRoC V1_02, VI-SLAM",
        "MAV in the Vicon room (not the machine hall of MH_04), two VI-SLAM variants x 10 runs",
        _vislam_v102(),
        ("--by", "run"),
        "run",
    ),
    Log(
        "KITTI 00",
        "car, 3.7 km drive; ORB-SLAM and S-PTAM on the same recording",
        (
            "--format",
            "kitti",
            "--times",
            "{evo}/KITTI_00_gt_times.txt",
            "--truth",
            "{evo}/KITTI_00_gt.txt",
            "--estimate",
            "{evo}/KITTI_00_ORB.txt",
            "--estimate",
            "{evo}/KITTI_00_SPTAM.txt",
        ),
        *_in_blocks(10),
    ),
    Log(
        "TUM fr2/desk",
        "hand-held RGB-D camera over a desk; ORB-SLAM",
        # ORB-SLAM's world is its first camera frame (y down): --up -y, as ingest's hint says
        ("--truth", "{evo}/fr2_desk_groundtruth.txt", "--estimate", "{evo}/fr2_desk_ORB.txt", "--up", "-y"),
        *_in_blocks(5),
    ),
    Log(
        "TUM fr1/xyz",
        "hand-held RGB-D camera, 30 s; RGBD-SLAM",
        ("--truth", "{evo}/freiburg1_xyz-groundtruth.txt", "--estimate", "{evo}/freiburg1_xyz-rgbdslam.txt"),
        *_in_blocks(2),
    ),
    Log(
        "EuRoC V1_02, one estimator",
        "MAV in the Vicon room; one run of another estimator, EuRoC's ground-truth CSV",
        ("--truth-format", "euroc", "--truth", "{evo}/V102_groundtruth.csv", "--estimate", "{evo}/V102.txt"),
        *_in_blocks(5),
    ),
)


def _cli(argv: Sequence[str]) -> tuple[int, str]:
    """Run ``ipcverify ARGV`` in this interpreter: its exit status and what it printed to stderr."""
    from ipcverify.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main(list(argv))
            code = 0
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, " ".join(err.getvalue().split())


def _errors(path: Path, epsilon: float) -> dict[str, float]:
    """The error norms ``||y - yhat||`` of a data file: median and the (1 - epsilon) quantile."""
    df = pd.read_csv(path)
    n = sum(c.startswith("y_") for c in df.columns)
    e = np.linalg.norm(
        df[[f"y_{i}" for i in range(n)]].to_numpy() - df[[f"yhat_{i}" for i in range(n)]].to_numpy(), axis=1
    )
    return {"median": float(np.median(e)), "quantile": float(np.quantile(e, 1 - epsilon))}


def _radius(median_log_volume: float, dim: int) -> float:
    """The radius of the ball with the median set's volume."""
    unit_ball = math.pi ** (dim / 2) / math.gamma(dim / 2 + 1)
    return float(math.exp((median_log_volume - math.log(unit_ball)) / dim))


def _certified(folder: Path, model: Path, test: Path, group_column: str | None) -> dict[str, Any]:
    """``certify`` MODEL on TEST: the numbers of its certificate a reviewer reads first."""
    cert = folder / "certificate"
    args = ["certify", str(model), "--data", str(test), "--out", str(cert)]
    code, err = _cli([*args, "--group-column", group_column] if group_column else args)
    if code not in (0, 1):
        return {"refused": err}
    exit_status = code
    c = json.loads((cert / "certificate.json").read_text())
    t, dom = c["test"], c["domain"] or {}
    inside = dom["n"] - dom["outside"] if dom else None
    group = c.get("group_test") or {}
    return {
        "status": c["status"],
        "exit": exit_status,
        "verdict": c["summary"]["verdict"],
        "certified_epsilon": c["calibration"]["certified_epsilon"],
        "test_n": t["n"],
        "test_violations": t["violations"],
        "test_rate": t["empirical_rate"],
        "test_upper": t["upper_bound"],
        "test_lower": t["lower_bound"],
        "outside_fraction": dom.get("outside_fraction"),
        "shift_warning": dom.get("well_above_alpha"),
        "domain_statement": dom.get("statement"),
        "inside_violation_rate": (dom["violations_inside"] / inside) if inside else None,
        "group_test": (
            {
                "groups": group["n_groups"],
                "sample_violations": group["sample"]["violations"],
                "sample_upper": group["sample"]["upper_bound"],
                "groups_with_any_violation": group["trajectory"]["violations"],
            }
            if group
            else None
        ),
        "row_level_column": dom.get("row_level_column"),
        "median_log_volume": c["volume"]["median_log"],
        "theorem1_vacuous": c["theorem1"]["vacuous"],
        "checks": [{k: ch[k] for k in ("check", "verdict", "level")} for ch in c["summary"]["checks"]],
    }


def _advice(step: dict[str, Any], options: list[str]) -> list[str] | None:
    """The calibrate options a step's own messages tell the user to add next (None: nothing to follow)."""
    message = step.get("message", "")
    if step.get("refused_at") == "calibrate":
        found = re.search(r"domain test at alpha=\S+ needs .*?--domain-alpha ([0-9.e-]+) works\)", message)
        if found is None or "requirements are not met" in message:
            return None  # also too few for the guarantee itself: no domain setting helps
        return [*_without(options, "--domain-alpha"), "--domain-alpha", found.group(1)]
    told = re.search(r"\(calibrate (--domain-group-column [^)]+)\)", step.get("domain_statement") or "")
    if step.get("shift_warning") and told and "--domain-group-column" not in options:
        return [*_without(options, "--domain-alpha"), *told.group(1).split()]
    return None


def _without(options: list[str], name: str) -> list[str]:
    """``options`` without ``name`` and its value."""
    out, skip = [], False
    for o in options:
        if skip:
            skip = False
        elif o == name:
            skip = True
        else:
            out.append(o)
    return out


def _calibrated(folder: Path, parts: Path, options: list[str], group_column: str) -> dict[str, Any]:
    """``calibrate`` with ``options``, then ``certify`` on the test part: the certificate's numbers."""
    model = folder / "calibrated.pt"
    model.unlink(missing_ok=True)
    code, err = _cli(
        ["calibrate", str(folder / "model.pt"), str(parts / "calibration.csv"), "--epsilon", str(EPSILON)]
        + ["--delta", str(DELTA), *options, "--out", str(model)]
    )
    if code:
        return {"options": options, "refused_at": "calibrate", "message": err}
    result = _certified(folder, model, parts / "test.csv", group_column)
    if "refused" in result:
        return {"options": options, "refused_at": "certify", "message": result["refused"]}
    errors = _errors(parts / "test.csv", EPSILON)
    radius = _radius(result["median_log_volume"], dim=3)
    return {"options": options, **result, "errors": errors, "set_radius": radius,
            "radius_over_error": radius / errors["quantile"]}  # fmt: skip


def run_log(log: Log, roots: dict[str, Path], folder: Path) -> dict[str, Any]:
    """Ingest, split, train (defaults), calibrate and certify one log in ``folder``.

    ``steps`` holds the calibration with the defaults, then each one the previous step's own
    messages asked for (a ``--domain-alpha`` a refusal named, ``--domain-group-column`` a
    row-level domain test on runs called for), as a user would follow them.
    """
    data = folder / "log.csv"
    ingest = [a.format(**{k: str(v) for k, v in roots.items()}) for a in log.ingest]
    code, err = _cli(["ingest", "trajectories", *ingest, "--out", str(data)])
    if code:
        return {"name": log.name, "what": log.what, "refused_at": "ingest", "message": err}
    manifest = json.loads(data.with_name("log.manifest.json").read_text())
    parts = folder / "parts"
    code, err = _cli(["split", str(data), "--out", str(parts), *log.split])
    out: dict[str, Any] = {
        "name": log.name,
        "what": log.what,
        "rows": manifest["rows"],
        "runs": len(manifest["runs"]),
        "seconds_per_run": round(float(pd.read_csv(data).groupby("run")["t"].max().max()), 1),
        "up": manifest["options"]["up"],
        "split": " ".join(log.split),
        "group_column_name": log.group_column,
    }
    if code:
        return {**out, "refused_at": "split", "message": err}
    record = json.loads((parts / "split.json").read_text())["parts"]
    out["parts"] = {k: {"rows": v["rows"], "groups": v["groups"]} for k, v in record.items()}
    t0 = time.perf_counter()
    code, err = _cli(["train", str(parts / "train.csv"), "--out", str(folder / "model.pt")])
    out["train_seconds"] = time.perf_counter() - t0
    if code:
        return {**out, "refused_at": "train", "message": err}
    return {**out, "steps": _follow(folder, parts, log.group_column)}


def _follow(folder: Path, parts: Path, group_column: str) -> list[dict[str, Any]]:
    """Calibrate and certify with the defaults, then as each step's messages say (at most 4 steps)."""
    steps: list[dict[str, Any]] = []
    options: list[str] | None = []
    while options is not None and len(steps) < 4:
        steps.append(_calibrated(folder, parts, options, group_column))
        options = _advice(steps[-1], options)
    return steps


def _must(argv: list[str]) -> None:
    """Run a step the benchmark's own setup needs; its failure is the benchmark's, not a finding."""
    code, err = _cli(argv)
    if code:
        raise RuntimeError(f"ipcverify {' '.join(argv[:1])} failed ({code}): {err}")


def cross_room(rpg: Path, folder: Path) -> dict[str, Any]:
    """A contract trained and calibrated on MH_04 (machine hall), certified on V1_02 (Vicon room).

    Calibrated with the defaults, then as the certificate's messages say; the contract with the
    defaults is also replayed through the online monitor on V1_02 and, as a control, on MH_04's
    own held-out runs, row by row in the logs' order.
    """
    parts = folder / "mh04"
    _must(["split", str(MH04), "--out", str(parts), "--by", "method,run", "--name-groups", "flight"])
    _must(["train", str(parts / "train.csv"), "--out", str(folder / "model.pt")])
    v102 = folder / "v102"
    v102.mkdir()
    _must(
        [
            "ingest",
            "trajectories",
            *[a.format(rpg=str(rpg)) for a in _vislam_v102()],
            "--out",
            str(v102 / "test.csv"),
        ]
    )
    (v102 / "calibration.csv").symlink_to(parts / "calibration.csv")
    steps = _follow(folder, v102, "run")
    defaults = folder / "defaults.pt"
    _must(["calibrate", str(folder / "model.pt"), str(parts / "calibration.csv"), "--epsilon", str(EPSILON),
           "--delta", str(DELTA), "--out", str(defaults)])  # fmt: skip
    monitor = {}
    for name, log in (("v102", v102 / "test.csv"), ("mh04_test", parts / "test.csv")):
        code, _ = _cli(["monitor", str(defaults), str(log), "--out", str(folder / name)])
        m = json.loads((folder / name / "monitor.json").read_text())
        monitor[name] = {k: m[k] for k in ("rows", "alarm", "alarm_index", "in_domain_fraction")}
        monitor[name]["exit"] = code
    return {
        "name": "MH_04 contract in V1_02",
        "what": "trained and calibrated on MH_04 (data/euroc_mh04_vislam.csv, split by method,run), "
        "certified on all of V1_02",
        "rows": len(pd.read_csv(v102 / "test.csv")),
        "steps": steps,
        "monitor": monitor,
    }


def _figure_rows(results: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """``(label, step)`` for every calibration step of every log, the defaults first."""
    rows = []
    for log in [*results["logs"], results["cross_room"]]:
        for i, step in enumerate(log.get("steps", [])):
            label = log["name"] if i == 0 else "  + " + " ".join(step["options"])
            rows.append((label, step))
    return rows


def figure(results: dict[str, Any], path: Path = FIGURE) -> None:
    """Each step's held-out violation rate (1 - delta interval) against epsilon, and the share outside."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = _figure_rows(results)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11.5, 0.42 * len(rows) + 1.9), sharey=True,
                                 gridspec_kw={"width_ratios": [3, 2]})  # fmt: skip
    for yi, (_, step) in zip(range(len(rows) - 1, -1, -1), rows, strict=True):
        if "test_rate" not in step:
            ax.text(0.002, yi, "refused: " + step["message"].removeprefix("error: ")[:70] + "...",
                    va="center", fontsize=7, color="0.35")  # fmt: skip
            continue
        color = "tab:red" if step["status"] == "CONTRADICTED" else "tab:blue"
        r, lo, up = step["test_rate"], step["test_lower"], step["test_upper"]
        ax.errorbar([r], [yi], xerr=[[r - lo], [up - r]], fmt="o", color=color, capsize=3)
        outside = 100 * (step["outside_fraction"] or 0.0)
        bx.barh([yi], [outside], color=color)
        bx.text(outside + 1, yi, f"{outside:.1f} %", va="center", fontsize=8)
    ax.axvline(EPSILON, color="k", ls="--", lw=1, label=f"target epsilon = {EPSILON}")
    ax.set_yticks(range(len(rows) - 1, -1, -1), [label for label, _ in rows], fontsize=8)
    ax.set_xlim(0, 0.3)
    ax.set_xlabel(f"held-out violation rate (rows outside their set); bars: one-sided {1 - DELTA:.0%} bounds")
    ax.legend(loc="lower right", fontsize=8)
    bx.set_xlim(0, 110)
    bx.set_xlabel("held-out queries outside the domain (%)")
    title = "The defaults on real logs ipcverify was not developed on, then the steps its messages ask for"
    fig.suptitle(f"{title}\n(red: the certificate is contradicted by the held-out data)", fontsize=10)
    save_figure(fig, path)


def _cells(step: dict[str, Any]) -> str:
    """One step's cells: options, verdict, held-out count and bound, outside share, set size."""
    options = " ".join(step["options"]) or "defaults"
    if "test_rate" not in step:
        reason = step["message"].removeprefix("error: ")
        return f"`{options}` | refused: {reason} | | | |"
    k, n = step["test_violations"], step["test_n"]
    outside = 100 * (step["outside_fraction"] or 0.0)
    shift = " (shift warning)" if step["shift_warning"] else ""
    count = f"{k}/{n} = {100 * k / n:.1f} % (≤ {100 * step['test_upper']:.1f} %)"
    size = f"{step['radius_over_error']:.2f}"
    return f"`{options}` | {step['status']} | {count} | {outside:.1f} %{shift} | {size} |"


def markdown_table(results: dict[str, Any]) -> str:
    """The table docs/real_logs.md shows: every log and every step, from the record."""
    lines = [
        "| log | rows (runs) | split: train / calibration / test groups | calibrate | certificate | "
        "held-out violations (99 % bound) | outside the domain | set radius / error q90 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for log in [*results["logs"], results["cross_room"]]:
        parts = log.get("parts")
        split = (
            f"`{log['split']}`: "
            + " / ".join(str(parts[k]["groups"]) for k in ("train", "calibration", "test"))
            if parts
            else "MH_04 by `method,run`; all of V1_02 tested"
        )
        runs = f" ({log['runs']})" if "runs" in log else ""
        head = f"| {log['name']} | {log['rows']:,}{runs} | {split} | "
        for i, step in enumerate(log.get("steps", [])):
            lines.append((head if i == 0 else "| | | | ") + _cells(step))
    return "\n".join(lines)


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def findings(results: dict[str, Any]) -> str:
    """The page's "What the logs show", every number from the record."""
    logs = {log["name"]: log for log in results["logs"]}
    v102, kitti = logs["EuRoC V1_02, VI-SLAM"], logs["KITTI 00"]
    small = [logs[n] for n in ("TUM fr2/desk", "TUM fr1/xyz", "EuRoC V1_02, one estimator")]
    cross = results["cross_room"]
    done = [st for log in small for st in log["steps"] if "test_rate" in st]
    ratios = sorted({round(st["radius_over_error"], 1) for st in done})
    cal_rows = sorted(log["parts"]["calibration"]["rows"] for log in small)
    certified_rows = sorted(
        log["parts"]["calibration"]["rows"] for log in small if any("test_rate" in st for st in log["steps"])
    )
    eps, delta = results["epsilon"], results["delta"]
    pac_min, one_out = min_calibration_size(eps, delta), pac_rows_allowing(1, eps, delta)
    domain_min = min_calibration_size(DEFAULT_ALPHA, 0.5, "marginal")
    k0, k1 = kitti["steps"][0], kitti["steps"][-1]
    c0, c1 = cross["steps"][0], cross["steps"][-1]
    mon = cross["monitor"]

    def group(log: dict[str, Any]) -> str:
        g = log["steps"][-1]["group_test"]
        return (
            f"the random rows of {g['sample_violations']} of {g['groups']} {log['group_column_name']}s "
            f"fall outside (bound {_pct(g['sample_upper'])})"
        )

    def held(log: dict[str, Any]) -> str:
        st = log["steps"][-1]
        return f"{_pct(st['test_rate'])} (99 % bounds {_pct(st['test_lower'])} to {_pct(st['test_upper'])})"

    return f"""* **Where there is enough data, the defaults certify and the held-out test does not contradict
  them.** On the {v102["runs"]} runs of V1_02 (a room the contract's developers never saw) and on
  KITTI 00 (a car, {kitti["seconds_per_run"]:.0f} s driven by two estimators), {held(v102)} and
  {held(kitti)} of the held-out rows fall outside their sets, against a target of
  {_pct(results["epsilon"])}, with sets of about the errors' size. These are row-level claims on
  {v102["parts"]["calibration"]["groups"]} and {kitti["parts"]["calibration"]["groups"]} calibration
  runs or blocks: every one of these certificates marks **independent rows: assumed, in doubt**
  in its summary. Counted per run or block instead (one random row each, valid whatever the
  correlation within), {group(v102)} and {group(kitti)}: too few units to bound anything useful.
* **A row-level domain test on rows that come in runs flags new runs.** On KITTI, split in
  {kitti["split"].split()[1]} s blocks, the default domain test (fitted row by row) put
  {_pct(k0["outside_fraction"])} of the held-out queries outside: a block's rows are near-copies
  of each other, so the row-level threshold is too short for a new block, and the certificate
  reports a shift or that artefact, with the command that tells them apart. Fitted by block as it
  says (`{" ".join(k1["options"])}`), {_pct(k1["outside_fraction"])} are outside.
* **Small logs are refused, or certified with wide sets.** The two TUM RGB-D logs
  ({small[0]["rows"]} and {small[1]["rows"]} rows) and the single-run V1_02 log ({small[2]["rows"]}
  rows) leave {cal_rows[0]} to {cal_rows[-1]} calibration rows. The default domain test needs
  {domain_min}, and the refusal names the `--domain-alpha` the rows allow. With {small[1]["rows"]} rows
  the guarantee itself is out of reach (ε = {eps:g} at δ = {delta:g} needs {pac_min} calibration rows),
  and `calibrate` says so instead of certifying. Where it certifies, the PAC scale is the largest
  of the {certified_rows[0]} or {certified_rows[-1]} calibration scores ({one_out} would be needed to let
  one lie outside; `calibrate` says so): sets {ratios[0]:g} to {ratios[-1]:g} times the error quantile.
* **In another room, the certificate is contradicted, and the guard says why.** The MH_04
  contract violates on {_pct(c0["test_rate"])} of the V1_02 rows (`{c0["status"]}`, exit status
  {c0["exit"]}),
  and {_pct(c0["outside_fraction"])} of the queries lie outside its domain ({_pct(c1["outside_fraction"])}
  with the test fitted by flight, as the certificate says). The queries inside the domain violate
  at {_pct(c0["inside_violation_rate"])}: the domain test flags the shift as a whole, but it does
  not make the remaining queries safe. That is what the certificate's test and the
  [monitor](guard.md) are for: `ipcverify monitor` replaying V1_02 row by row raises its alarm at
  row {mon["v102"]["alarm_index"]:,} of {mon["v102"]["rows"]:,} (exit status {mon["v102"]["exit"]}), and
  replaying MH_04's own {mon["mh04_test"]["rows"]:,} held-out rows it stays silent."""


def bench_unseen_logs(rpg: Path, evo: Path, logs: Sequence[Log] = LOGS) -> dict[str, Any]:
    """Every log of ``logs`` and the cross-room row, each in its own temporary folder."""
    roots = {"rpg": rpg, "evo": evo}
    out: dict[str, Any] = {
        "date_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "epsilon": EPSILON,
        "delta": DELTA,
        "logs": [],
    }
    for log in logs:
        with tempfile.TemporaryDirectory() as tmp:
            out["logs"].append(run_log(log, roots, Path(tmp)))
            print(json.dumps(out["logs"][-1], default=str)[:200], flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        out["cross_room"] = cross_room(rpg, Path(tmp))
    return out


def main(argv: Sequence[str] | None = None) -> None:
    """``python -m benchmarks.bench_unseen_logs --rpg DIR --evo DIR``."""
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--rpg", type=Path, required=True, help="checkout of uzh-rpg/rpg_trajectory_evaluation")
    p.add_argument("--evo", type=Path, required=True, help="the test/data folder of MichaelGrupp/evo")
    p.add_argument("--out", type=Path, default=OUT)
    a = p.parse_args(argv)
    t0 = time.perf_counter()
    results = bench_unseen_logs(a.rpg, a.evo)
    results["runtime_seconds"] = time.perf_counter() - t0
    write_json(a.out, results)
    figure(results)
    print(f"wrote {a.out} and {FIGURE}")


if __name__ == "__main__":
    main()
