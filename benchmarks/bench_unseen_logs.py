"""The documented pipeline, with its defaults, on public real logs that ipcverify was never developed on.

ipcverify was developed against one real log (``data/euroc_mh04_vislam.csv``: EuRoC MH_04, two
VI-SLAM variants). This benchmark runs what a new user types -- ``ingest trajectories``,
``split``, ``train`` (defaults), ``calibrate --epsilon 0.1 --delta 0.01`` (on data that name their
runs, its default claim is about runs: a new run's expected share of rows outside their sets),
``certify`` on the held-out part -- on five other public logs and on MH_04 itself, changing
nothing per log but the file names, the file format and how to split (by run where a log has
many, by blocks of time where it has one or two). Where ``calibrate`` is refused, the next step
does what its message says, once: name the column of the runs (``--group-column``), raise
``--epsilon`` to the smallest value the runs allow, or set the ``--domain-flag-rate`` it names; where
a certificate asks for a domain test fitted by groups, the next step fits it so. Per step it
records the claim (unit and epsilon), the certificate's status, the held-out test counted by runs
(the mean of the runs' shares of rows outside with its betting bounds, and the runs with any
violation; the rows as secondary), the share of queries outside the domain of validity, the sets'
size next to the errors, and what the calibration rows are worth (the model's
``calibration_runs``: design effect, effective rows).

The last contracts of KITTI 00 and of MH_04 are replayed through ``ipcverify monitor``: KITTI's
and MH_04's held-out blocks and flights (no alarm expected), and all 20 runs of EuRoC V1_02,
another room, through the MH_04 contract (one more row: that contract certified on V1_02). The
record keeps each run's share outside its sets and outside the domain, and the monitor's
e-values after each run.

The logs are not in this repository (their licences differ from ours); give their folders:

* ``--rpg DIR``: a checkout of https://github.com/uzh-rpg/rpg_trajectory_evaluation (MIT): the
  two VI-SLAM variants on EuRoC V1_02, 10 runs each, with ground truth
  (``results/euroc_vislam_mono/laptop/...``);
* ``--evo DIR``: the ``test/data`` folder of https://github.com/MichaelGrupp/evo (used only as
  data, never as code): KITTI 00 (ORB-SLAM and S-PTAM against the KITTI ground truth), TUM RGB-D
  fr2/desk (ORB-SLAM) and fr1/xyz (RGBD-SLAM), and one estimator on EuRoC V1_02 with EuRoC's
  ground-truth CSV.

``python -m benchmarks.bench_unseen_logs --rpg RPG --evo EVO`` (several minutes on 2 cores: six
networks are trained) writes ``benchmarks/unseen_logs_results.json`` and
``docs/img/unseen_logs.png``; docs/real_logs.md quotes them, and
``tests/benchmarks/test_bench_unseen_logs.py`` checks the page against the record.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import re
import shutil
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

__all__ = ["EPSILON", "DELTA", "LOGS", "MH04_LOG", "Log", "bench_unseen_logs", "main"]

ROOT = Path(__file__).resolve().parent.parent
OUT = Path(__file__).with_name("unseen_logs_results.json")
FIGURE = ROOT / "docs" / "img" / "unseen_logs.png"
#: The target every log is first calibrated to, and the confidence parameter.
EPSILON, DELTA = 0.1, 0.01
#: Calibration steps per log: the defaults, then at most three that follow a message.
MAX_STEPS = 4
_RPG = "{rpg}/results/euroc_vislam_mono/laptop"


@dataclass(frozen=True)
class Log:
    """One log: how to read it, how to split it, and whether its held-out part is replayed.

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
        The column the split kept whole (``--group-column`` when a message asks which column
        names the runs).
    table : str or None
        A ready table in this repository, used instead of ``ingest``.
    runs_by : tuple of str
        The columns whose values together name a run of the log.
    monitor : bool
        Replay the held-out part through the last contract with ``ipcverify monitor``.
    """

    name: str
    what: str
    ingest: tuple[str, ...]
    split: tuple[str, ...]
    group_column: str
    table: str | None = None
    runs_by: tuple[str, ...] = ("run",)
    monitor: bool = False

    def __post_init__(self) -> None:
        if not (self.name and (self.ingest or self.table) and self.group_column):
            raise ValueError("a log has a name, ingest arguments or a table, and a group column")


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


#: The log ipcverify was developed on, split by flight; its contract is also deployed on V1_02.
MH04_LOG = Log(
    "EuRoC MH_04, VI-SLAM",
    "MAV in the machine hall: the log ipcverify was developed on (data/euroc_mh04_vislam.csv), "
    "two VI-SLAM variants x 10 runs",
    (),
    ("--by", "method,run", "--name-groups", "flight"),
    "flight",
    table="data/euroc_mh04_vislam.csv",
    runs_by=("method", "run"),
    monitor=True,
)

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
        monitor=True,
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
    MH04_LOG,
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


def _must(argv: list[str]) -> None:
    """Run a step the benchmark's own setup needs; its failure is the benchmark's, not a finding."""
    code, err = _cli(argv)
    if code:
        raise RuntimeError(f"ipcverify {' '.join(argv[:1])} failed ({code}): {err}")


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


def _by_runs(group: dict[str, Any]) -> dict[str, Any] | None:
    """The held-out test by runs: the mean of their shares (betting bounds), the runs with any violation."""
    share, anywhere = group.get("share"), group.get("trajectory")
    if not (share and anywhere):
        return None
    return {
        "column": group["column"],
        "runs": share["n"],
        "mean_share": share["empirical_rate"],
        "lower": share["lower_bound"],
        "upper": share["upper_bound"],
        "with_violation": anywhere["violations"],
        "with_violation_upper": anywhere["upper_bound"],
    }


def _dependence(runs: dict[str, Any]) -> dict[str, Any] | None:
    """What the calibration's runs support and what its rows are worth (the model's ``calibration_runs``)."""
    if not runs:
        return None
    dep, plan = runs.get("dependence") or {}, runs.get("plan") or {}
    smallest = {c["guarantee"]: c["smallest"] for c in plan.get("claims", [])}
    keys = (
        "n_runs",
        "n_rows",
        "violation_rate",
        "effective_rows",
        "design_effect",
        "icc",
        "autocorrelation_time",
    )
    return {
        "column": runs["column"],
        "unit": runs["unit"],
        **{k: dep.get(k) for k in keys},
        "floor": plan.get("floor"),
        "smallest_expected_share": smallest.get("expected-share"),
        "statement": dep.get("statement"),
    }


def _certified(out: Path, model: Path, test: Path) -> dict[str, Any]:
    """``certify`` MODEL on TEST (counted by runs where the claim or the data name them): its numbers."""
    code, err = _cli(["certify", str(model), "--data", str(test), "--out", str(out)])
    if code not in (0, 1):
        return {"refused": err}
    c = json.loads((out / "certificate.json").read_text())
    t, dom, summary = c["test"], c["domain"] or {}, c["summary"]
    inside = dom["n"] - dom["outside"] if dom else None
    return {
        "status": c["status"],
        "exit": code,
        "verdict": summary["verdict"],
        "unit": "run" if summary["unit"] == "group" else summary["unit"],
        "unit_column": summary.get("unit_column"),
        "certified_epsilon": c["calibration"]["certified_epsilon"],
        "test": {
            "statistic": t["statistic"],
            "unit": t["unit"],
            "n": t["n"],
            "rate": t["empirical_rate"],
            "lower": t["lower_bound"],
            "upper": t["upper_bound"],
        },
        "by_runs": _by_runs(c.get("group_test") or {}),
        "test_rows": c["data"]["test"]["n"],
        "rows_outside": int(sum(c["coverage_by_bin"]["violations"])),
        "domain_flag_rate": dom.get("flag_rate"),
        "outside_fraction": dom.get("outside_fraction"),
        "shift_warning": dom.get("well_above_flag_rate"),
        "domain_statement": dom.get("statement"),
        "inside_violation_rate": (dom["violations_inside"] / inside) if inside else None,
        "row_level_column": dom.get("row_level_column"),
        "calibration_runs": _dependence(c.get("runs") or {}),
        "median_log_volume": c["volume"]["median_log"],
        "theorem1_vacuous": c["theorem1"]["vacuous"],
        "checks": [{k: ch[k] for k in ("check", "verdict", "level")} for ch in summary["checks"]],
    }


#: A refusal for too few runs names the smallest rate they allow (``too_few_groups``).
_SMALLEST = re.compile(r"raise --(epsilon|gamma) \(with \d+ groups the smallest is ([0-9.e+-]+)")
#: A refusal of the domain test names a false-alarm rate that works.
_DOMAIN = re.compile(r"domain test at flag rate \S+ needs .*?--domain-flag-rate ([0-9.e-]+) works\)")


def _advice(step: dict[str, Any], options: list[str], group_column: str) -> list[str] | None:
    """The calibrate options a step's own messages tell the user to use next (None: nothing to follow).

    A refusal that asks which column names the runs gets the column the split kept whole
    (``group_column``); one for too few runs, the smallest ``--epsilon`` it names; one of the domain
    test, the ``--domain-flag-rate`` it names. A certificate whose row-level domain test flags a shift
    that a test fitted by groups might not gets the ``--domain-group-column`` it names.
    """
    message = step.get("message", "")
    if step.get("refused_at") == "calibrate":
        new = list(options)
        if "several columns could name the runs" in message and "--group-column" not in new:
            new += ["--group-column", group_column]
        found = _SMALLEST.search(message)
        if found and float(found.group(2)) < 1:
            name = f"--{found.group(1)}"
            new = [*_without(new, name), name, found.group(2)]
        elif "requirements are not met" in message:
            return None  # the guarantee itself is out of reach, and no value is named
        if domain := _DOMAIN.search(message):
            new = [*_without(new, "--domain-flag-rate"), "--domain-flag-rate", domain.group(1)]
        return new if new != options else None
    told = re.search(r"\(calibrate (--domain-group-column [^)]+)\)", step.get("domain_statement") or "")
    if step.get("shift_warning") and told and "--domain-group-column" not in options:
        return [*_without(options, "--domain-flag-rate"), *told.group(1).split()]
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


def _calibrated(folder: Path, parts: Path, options: list[str], index: int) -> dict[str, Any]:
    """Step ``index``: ``calibrate`` with ``options``, then ``certify`` on the test part."""
    model = folder / f"calibrated{index}.pt"
    epsilon = float(options[options.index("--epsilon") + 1]) if "--epsilon" in options else EPSILON
    target = [] if "--epsilon" in options else ["--epsilon", str(EPSILON)]
    code, err = _cli(
        ["calibrate", str(folder / "model.pt"), str(parts / "calibration.csv"), *target]
        + ["--delta", str(DELTA), *options, "--out", str(model)]
    )
    head = {"options": options, "epsilon": epsilon}
    if code:
        return {**head, "refused_at": "calibrate", "message": _here(err, folder)}
    result = _certified(folder / f"certificate{index}", model, parts / "test.csv")
    if "refused" in result:
        return {**head, "refused_at": "certify", "message": _here(result["refused"], folder)}
    return {**head, "calibrate_hints": _here(err, folder), **result, **_sizes(result, parts / "test.csv")}


def _here(message: str, folder: Path) -> str:
    """``message`` with the temporary folder's path taken out of the file names it gives."""
    return message.replace(f"{folder}/", "")


def _sizes(result: dict[str, Any], test: Path) -> dict[str, Any]:
    """The sets' size next to the errors: the radius of the median set's ball over the errors' q90."""
    errors = _errors(test, EPSILON)
    radius = _radius(result["median_log_volume"], dim=3)
    return {"errors": errors, "set_radius": radius, "radius_over_error": radius / errors["quantile"]}


def _follow(folder: Path, parts: Path, group_column: str) -> list[dict[str, Any]]:
    """Calibrate and certify with the defaults, then as each step's messages say (at most MAX_STEPS)."""
    steps: list[dict[str, Any]] = []
    options: list[str] | None = []
    while options is not None and len(steps) < MAX_STEPS:
        steps.append(_calibrated(folder, parts, options, len(steps)))
        options = _advice(steps[-1], options, group_column)
    return steps


def contract_of(folder: Path, record: dict[str, Any]) -> Path | None:
    """The model file of a log's last certified step (None: no step got a certificate)."""
    done = [i for i, step in enumerate(record.get("steps", [])) if "status" in step]
    return folder / f"calibrated{done[-1]}.pt" if done else None


def _read(log: Log, roots: dict[str, Path], data: Path) -> tuple[int, str]:
    """The log as a table at ``data``: ``ingest trajectories``, or a copy of its ready table."""
    if log.table is not None:
        shutil.copyfile(ROOT / log.table, data)
        return 0, ""
    ingest = [a.format(**{k: str(v) for k, v in roots.items()}) for a in log.ingest]
    return _cli(["ingest", "trajectories", *ingest, "--out", str(data)])


def run_log(log: Log, roots: dict[str, Path], folder: Path) -> dict[str, Any]:
    """Read, split, train (defaults), calibrate and certify one log in ``folder``.

    ``steps`` holds the calibration with the defaults, then each one the previous step's own
    messages asked for, as a user would follow them (:func:`_advice`). With ``log.monitor``, the
    held-out part is replayed through the last certified contract (``monitor``).
    """
    data = folder / "log.csv"
    code, err = _read(log, roots, data)
    if code:
        return {"name": log.name, "what": log.what, "refused_at": "ingest", "message": err}
    manifest = data.with_name("log.manifest.json")
    df = pd.read_csv(data)
    parts = folder / "parts"
    code, err = _cli(["split", str(data), "--out", str(parts), *log.split])
    out: dict[str, Any] = {
        "name": log.name,
        "what": log.what,
        "rows": len(df),
        "runs": int(df.groupby(list(log.runs_by)).ngroups),
        "seconds_per_run": round(float(df.groupby(list(log.runs_by))["t"].max().max()), 1),
        "up": json.loads(manifest.read_text())["options"]["up"] if manifest.exists() else None,
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
    out["steps"] = _follow(folder, parts, log.group_column)
    contract = contract_of(folder, out)
    if log.monitor and contract is not None:
        out["monitor"] = replay(contract, parts / "test.csv", folder / "monitor", log.group_column)
    return out


def replay(contract: Path, log: Path, out: Path, column: str) -> dict[str, Any]:
    """``ipcverify monitor CONTRACT LOG``: its outcome, and each run's shares and e-values after it.

    The monitor of a run-level contract takes one observation per run of ``column`` (the
    contract's): the run's share of rows outside their sets, tested against the claim, and, when
    the domain test was fitted by runs, its share of queries outside the domain, tested against
    the domain test's false-alarm rate. The per-run numbers come from the library's
    ``monitor_log`` (the code the command runs), checked against the command's alarms.
    """
    from ipcverify.contract import monitor_log
    from ipcverify.contract._prediction import predict_sets
    from ipcverify.data import PerceptionInputs
    from ipcverify.io import load_model
    from ipcverify.io._modelio import load_data_for_model

    code, err = _cli(["monitor", str(contract), str(log), "--out", str(out)])
    if code not in (0, 1):
        return {"refused": err}
    m = json.loads((out / "monitor.json").read_text())
    keys = ("rows", "unit", "observations", "epsilon", "delta", "null", "alarm", "alarm_index")
    keys += ("domain_rate", "domain_alarm", "domain_alarm_index", "in_domain_fraction", "statement")
    record: dict[str, Any] = {k: m[k] for k in keys}
    record["exit"] = code
    model = load_model(contract)
    data = load_data_for_model(log, model)
    res = monitor_log(model, data)
    if (res.alarm_index, res.domain_alarm_index) != (m["alarm_index"], m["domain_alarm_index"]):
        raise RuntimeError(f"monitor_log and ipcverify monitor disagree on {log}")
    pred = predict_sets(model, PerceptionInputs(data.x, data.yhat, data.source))
    runs = pd.Series(np.asarray(data.column(column)).astype(str))
    outside = pd.Series(~pred.in_domain).groupby(runs).mean()
    sizes = runs.value_counts()
    domain_path = res.result.domain_log_e_value

    def rounded(values: Any) -> list[float]:
        return [round(float(v), 6) for v in values]

    return {
        **record,
        "runs": list(res.labels),
        "run_rows": [int(sizes[label]) for label in res.labels],
        "shares": rounded(res.violated),
        "outside_shares": rounded(outside[list(res.labels)]),
        "log_e": rounded(res.result.log_e_value),
        "domain_log_e": None if domain_path is None else rounded(domain_path),
        "alarm_level": -math.log(m["delta"]),
    }


def cross_room(rpg: Path, folder: Path, contract: Path) -> dict[str, Any]:
    """The MH_04 contract (calibrated by flights) certified on all of V1_02 and replayed through the monitor.

    V1_02's runs are named in a column ``run``; the contract's claim is about ``flight``s, and
    ``certify`` and ``monitor`` refuse a log without that column (recorded in ``refusals``), so
    ``split --fractions 0,0,1 --by run --name-groups flight`` names them, keeping every row in
    its order. MH_04's own held-out flights, replayed in :func:`run_log`, are the control.
    """
    raw = folder / "v102.csv"
    _must(["ingest", "trajectories", *[a.format(rpg=str(rpg)) for a in _vislam_v102()], "--out", str(raw)])
    refusals = {
        "certify": _cli(["certify", str(contract), "--data", str(raw), "--out", str(folder / "c")]),
        "monitor": _cli(["monitor", str(contract), str(raw), "--out", str(folder / "m")]),
        "monitor --group-column run": _cli(
            ["monitor", str(contract), str(raw), "--group-column", "run", "--out", str(folder / "m")]
        ),
    }
    parts = folder / "v102"
    _must(["split", str(raw), "--out", str(parts), "--by", "run", "--name-groups", MH04_LOG.group_column]
          + ["--fractions", "0,0,1"])  # fmt: skip
    test = parts / "test.csv"
    table = pd.read_csv(test)
    step = _certified(folder / "certificate_v102", contract, test)
    if "refused" in step:
        raise RuntimeError(f"certify refused the MH_04 contract on V1_02: {step['refused']}")
    return {
        "name": "MH_04 contract in V1_02",
        "what": "the last MH_04 contract (calibrated by flights), certified on all 20 runs of V1_02",
        "rows": len(table),
        "runs": int(table[MH04_LOG.group_column].nunique()),
        "refusals": {k: {"exit": code, "message": _here(err, folder)} for k, (code, err) in refusals.items()},
        "steps": [
            {
                "options": ["(the MH_04 contract)"],
                "epsilon": step["certified_epsilon"],
                **step,
                **_sizes(step, test),
            }
        ],
        "monitor": replay(contract, test, folder / "monitor_v102", MH04_LOG.group_column),
    }


def _range(values: Sequence[float], fmt: Any = None) -> str:
    """``a to b`` (or ``a``) of the smallest and largest value, formatted with ``fmt``."""
    fmt = fmt or _pct
    lo, hi = fmt(min(values)), fmt(max(values))
    return lo if lo == hi else f"{lo} to {hi}"


def _needed(message: str) -> int:
    """The runs a refused target needs, from its message."""
    found = re.search(r"at least (\d+) groups are needed", message)
    if found is None:
        raise ValueError(f"no count of runs in {message!r}")
    return int(found.group(1))


def findings(results: dict[str, Any]) -> str:
    """The page's "What the logs show", every number from the record."""
    logs = {log["name"]: log for log in results["logs"]}
    eps, delta = results["epsilon"], results["delta"]
    last = {name: log["steps"][-1] for name, log in logs.items()}
    few = [st for log in logs.values() for st in log["steps"] if "too few" in st.get("message", "")]
    ambiguous = [
        (log["name"].split(",")[0], log["group_column_name"])
        for log in logs.values()
        if "several columns" in log["steps"][0].get("message", "")
    ]
    cal_runs = [log["parts"]["calibration"]["groups"] for log in logs.values()]
    floors = [st["calibration_runs"]["floor"] for st in last.values()]
    by_runs = [st["by_runs"] for st in last.values()]
    sizes = {name: st["radius_over_error"] for name, st in last.items()}
    weak_verdicts = {st["verdict"].split(" (")[0] for st in last.values()}
    weak = f", and say so (`{weak_verdicts.pop()}`)" if len(weak_verdicts) == 1 else ""
    contradicted = [name for name, st in last.items() if st["status"] == "CONTRADICTED"]
    shifted = [(name, st) for name, st in last.items() if st["shift_warning"]]
    beyond = [
        (name, st)
        for name, st in last.items()
        if (st["outside_fraction"] or 0) > 1.5 * st["domain_flag_rate"]
    ]
    kitti, mh04, v102 = logs["KITTI 00"], logs[MH04_LOG.name], logs["EuRoC V1_02, VI-SLAM"]
    dep = {name: last[name]["calibration_runs"] for name in (v102["name"], mh04["name"])}
    unmeasured = [name for name, st in last.items() if st["calibration_runs"]["design_effect"] is None]
    k_mon, m_mon = kitti["monitor"], mh04["monitor"]
    short = k_mon["shares"].index(max(k_mon["shares"]))
    cross, c_mon = results["cross_room"], results["cross_room"]["monitor"]
    c = cross["steps"][0]
    alarm = c_mon["domain_alarm_index"]
    refusals = cross["refusals"]
    mh_steps = mh04["steps"]
    methods = [label.split(":")[0] for label in c_mon["runs"]]
    order = ", then ".join(f"{methods.count(m)} runs of `{m}`" for m in dict.fromkeys(methods))

    def rows_outside(d: dict[str, Any]) -> int:
        return round(d["violation_rate"] * d["n_rows"])

    def worth(name: str) -> str:
        d = dep[name]
        return f"{d['n_rows']:,} rows are worth about {d['effective_rows']:,.0f}"

    return f"""* **At ε = {eps:g}, every log is refused: its runs are too few.** Every log names its runs
  (runs, flights, or the split's blocks of time), so `calibrate`'s default claim is about a new
  run: the expected share of its rows outside their sets. At δ = {delta:g} an expected share of
  {eps:g} needs {_needed(few[0]["message"])} runs; the logs leave {_range(cal_runs, str)} for
  calibration, and from `G` runs no claim about a new run goes below `1 − δ^(1/G)`
  ({_range(floors, lambda x: f"{x:.3f}")} here). Each refusal names the smallest ε the runs allow,
  and the next step uses it: {", ".join(sorted({f"{st['epsilon']:g}" for st in last.values()}))}.
  On {" and ".join(name for name, _ in ambiguous)}, the split leaves two columns that could name
  runs, and `calibrate` first asks which; the next step names the one the split kept whole
  ({", ".join(f"`{col}`" for _, col in ambiguous)}).
* **Followed, every log is certified at that ε, and {len(contradicted) or "no"} held-out test
  contradicts its claim.** The held-out runs' mean shares of rows outside are
  {_range([r["mean_share"] for r in by_runs])}; their 99 % lower bounds are
  {_range([r["lower"] for r in by_runs])}, and the upper bounds, {_range([r["upper"] for r in by_runs])}
  from {_range([r["runs"] for r in by_runs], str)} test runs, confirm little.
  {sum(st["rows_outside"] for st in last.values())} of {sum(st["test_rows"] for st in last.values()):,}
  held-out rows fall outside (rows of a run are correlated, so the row count is descriptive).
  These claims are weak{weak}: a few runs allow only a claim that
  {_range([st["certified_epsilon"] for st in last.values()])} of a new run's rows may fall outside,
  on average. To certify ε near the floor, the calibration runs must leave almost no row outside:
  the scale is near the largest calibration score, and the sets' radius is
  {", ".join(f"{v:.2f} ({name})" for name, v in sizes.items())} times the errors' 90th
  percentile.
* **What the rows are worth.** `calibrate` records how much a run's rows tell (the model's
  `calibration_runs`). On V1_02 and MH_04, {worth(v102["name"])} and {worth(mh04["name"])}
  independent ones (design effect {dep[v102["name"]]["design_effect"]:.3f} and
  {dep[mh04["name"]]["design_effect"]:.3f}), but that is measured at the calibrated scale, where only
  {rows_outside(dep[v102["name"]])} and {rows_outside(dep[mh04["name"]])} of those rows are
  outside: it says little. On the other logs ({"; ".join(unmeasured)}) no calibration row is outside at the
  calibrated scale and the design effect is not measured; the scores' autocorrelation time,
  {last["KITTI 00"]["calibration_runs"]["autocorrelation_time"]:.1f} rows in KITTI's
  {k_mon["run_rows"][0]}-row blocks, says how far from independent the rows are.
* **On KITTI, a short block weighs as much as a whole one.** KITTI's held-out mean share,
  {_pct(last["KITTI 00"]["by_runs"]["mean_share"])}, comes from one block of
  {k_mon["run_rows"][short]} rows (the end of a run, which `split --block {kitti["split"].split()[1]}`
  leaves shorter than the others' {k_mon["run_rows"][0]}),
  {round(k_mon["shares"][short] * k_mon["run_rows"][short])} of them outside (a share of
  {_pct(k_mon["shares"][short])}); the other {len(k_mon["shares"]) - 1} blocks have none. The claim
  counts runs as equals, whatever their length.
* **A domain test fitted on a few blocks does not cover the next ones, and a few runs cannot
  show it.** On {" and ".join(name for name, _ in beyond)}, the held-out queries outside the
  domain are {" and ".join(_pct(st["outside_fraction"]) for _, st in beyond)} (the test fitted by
  {beyond[0][1]["calibration_runs"]["n_runs"]} blocks, at flag rate {beyond[0][1]["domain_flag_rate"]:g},
  the smallest they allow): a few seconds of a hand-held camera do not span the next few. Counted
  by their {" and ".join(str(st["by_runs"]["runs"]) for _, st in beyond)} held-out runs, as a claim
  about runs must be, that is {
        "a shift warning on " + str(len(shifted)) + " of them" if shifted else "no shift warning"
    }: the warning needs the runs' shares outside to be above the flag rate
  with confidence, and so few runs cannot give it.
* **The monitor is silent on held-out runs.** Replaying KITTI's {k_mon["observations"]} held-out
  segments and MH_04's {m_mon["observations"]} held-out flights through their own contracts raises
  no alarm (exit status {max(k_mon["exit"], m_mon["exit"])}), one observation per run: neither test's
  log e-value rises above {
        max(
            max(k_mon["log_e"]), max(k_mon["domain_log_e"]), max(m_mon["log_e"]), max(m_mon["domain_log_e"])
        ):.2f} (the alarm level is {k_mon["alarm_level"]:.2f}).
* **In another room, the out-of-domain test alarms after {alarm + 1} runs; the violation test
  never does.** The MH_04 contract is the last step of its row: the default split
  (`{mh04["split"]}`: {mh04["parts"]["calibration"]["groups"]} calibration flights), `train`'s
  defaults, then `{" ".join(mh_steps[-1]["options"])}` as the refusals said (δ = {delta:g}), with
  the domain test fitted by flight at flag rate {c_mon["domain_rate"]:g}, the smallest those flights allow
  (`calibrate` says so in a hint). Replaying all {c_mon["observations"]} runs of V1_02 in their
  order ({order}), each run has
  {_range(c_mon["outside_shares"])} of its queries outside MH_04's domain, against a rate of
  {c_mon["domain_rate"]:g}: the out-of-domain test alarms after {alarm + 1} runs. The runs leave
  {_range(c_mon["shares"])} of their rows outside their sets (mean
  {_pct(c["by_runs"]["mean_share"])}), against a null of {c_mon["epsilon"]:g}: there is nothing
  for the violation test to refute. The contract's sets, {c["radius_over_error"]:.2f} times V1_02's
  error quantile, are large enough for the other room; what changed is where the queries are,
  and that is what the domain test reports. `monitor` exits with status {c_mon["exit"]}: an alarm
  of either test exits 1.
* **`certify` on V1_02 passes the weak claim and warns of the shift.** It says `{c["status"]}`
  (99 % upper bound {_pct(c["by_runs"]["upper"])} on the mean share, against
  {c["certified_epsilon"]:g}; {c["by_runs"]["with_violation"]} of {c["by_runs"]["runs"]} runs have a
  violation somewhere), with {_pct(c["outside_fraction"])} of the queries outside the domain
  (against a flag rate of {
        c["domain_flag_rate"]:g}) and a shift warning; inside the domain rows are outside their
  sets at {
        _pct(c["inside_violation_rate"])
    }. Both commands count V1_02's runs only when told which column names them:
  `certify` says "{refusals["certify"]["message"].removeprefix("error: ")}", and `monitor`
  "{refusals["monitor"]["message"].removeprefix("error: ")}". With `--group-column run`, `monitor` counts
  V1_02's runs by that column and raises the same domain alarm (observation
  {refusals["monitor --group-column run"]["message"].split("observation ")[1].split(" ")[0]}). The
  replay above names them like the contract's instead, with `split --by run --name-groups flight
  --fractions 0,0,1`, keeping every row in its order."""


def bench_unseen_logs(rpg: Path, evo: Path, logs: Sequence[Log] = LOGS) -> dict[str, Any]:
    """Every log of ``logs`` in its own temporary folder, and the cross-room row after MH_04's."""
    roots = {"rpg": rpg, "evo": evo}
    out: dict[str, Any] = {
        "date_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "epsilon": EPSILON,
        "delta": DELTA,
        "logs": [],
    }
    for log in logs:
        with tempfile.TemporaryDirectory() as tmp:
            record = run_log(log, roots, Path(tmp))
            out["logs"].append(record)
            print(json.dumps(record, default=str)[:300], flush=True)
            contract = contract_of(Path(tmp), record)
            if log == MH04_LOG and contract is not None:
                out["cross_room"] = cross_room(rpg, Path(tmp), contract)
    return out


def _steps(results: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """``(label, step)`` for every calibration step of every log and the cross-room row, in order."""
    rows = []
    for log in [*results["logs"], results["cross_room"]]:
        for i, step in enumerate(log.get("steps", [])):
            label = log["name"] if i == 0 else "  + " + " ".join(step["options"])
            rows.append((label, step))
    return rows


def refusal(message: str) -> str:
    """A refusal in a few words, from its message: what was refused and the value it names."""
    cols = re.search(r"several columns could name the runs \((.*?)\); say", message)
    if cols:
        return "which column names the runs? " + re.sub(r" \(\d+ groups\)", "", cols.group(1))
    few = re.search(r"(\d+) groups of column '(\w+)' are too few .* at epsilon=(\S+), delta", message)
    named = _SMALLEST.search(message)
    if few and named:
        g, column, eps = few.groups()
        return f"{g} {column}s are too few for ε = {eps}; the smallest they allow is {named.group(2)}"
    return message.removeprefix("error: ")[:80] + "..."


_COLOR = {"CERTIFIED": "tab:blue", "CONTRADICTED": "tab:red", "ROWS_ASSUMED": "tab:orange"}


def figure(results: dict[str, Any], path: Path = FIGURE) -> None:
    """Per step: the claim and the held-out runs' mean share; the share outside; the monitor's e-values."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = _steps(results)
    fig = plt.figure(figsize=(12.5, 0.36 * len(rows) + 5.2))
    grid = fig.add_gridspec(2, 2, width_ratios=[3, 1.2], height_ratios=[0.36 * len(rows) + 0.9, 3.2])
    ax, bx, mx = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1]), fig.add_subplot(grid[1, :])
    bx.sharey(ax)
    ys = range(len(rows) - 1, -1, -1)
    for yi, (_, step) in zip(ys, rows, strict=True):
        if "status" not in step:
            ax.text(0.01, yi, "refused: " + refusal(step["message"]), va="center", fontsize=8, color="0.25")
            continue
        color, runs = _COLOR.get(step["status"], "k"), step["by_runs"]
        m, lo, up = runs["mean_share"], runs["lower"], runs["upper"]
        ax.errorbar([m], [yi], xerr=[[m - lo], [up - m]], fmt="o", color=color, capsize=3, ms=5)
        ax.plot([step["certified_epsilon"]], [yi], marker="|", ms=16, mew=2.5, color="k")
        outside = 100 * (step["outside_fraction"] or 0.0)
        bx.barh([yi], [outside], color="tab:orange" if step["shift_warning"] else "0.6", height=0.6)
        bx.text(
            outside + 2,
            yi,
            f"{outside:.1f} % (flag rate {step['domain_flag_rate']:g})",
            va="center",
            fontsize=8,
        )
    ax.plot(
        [], [], "o-", color="tab:blue", label="held-out runs: mean share of rows outside, 99 % betting bounds"
    )
    ax.plot([], [], "|", ms=12, mew=2.5, color="k", label="the claim: ε (a new run's expected share outside)")
    ax.set_yticks(list(ys), [label for label, _ in rows], fontsize=8)
    for tick, (label, _) in zip(ax.get_yticklabels(), rows, strict=True):
        tick.set_fontweight("normal" if label.startswith("  + ") else "bold")
    for yi, (label, _) in zip(ys, rows, strict=True):
        if not label.startswith("  + ") and yi < len(rows) - 1:
            for a in (ax, bx):
                a.axhline(yi + 0.5, color="0.8", lw=0.8)
    ax.set_ylim(-0.6, len(rows) - 0.4)
    ax.set_xlim(-0.02, 1)
    ax.set_xlabel("share of a run's rows outside their sets", fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=8, frameon=False)
    ax.grid(axis="x", color="0.9")
    bx.set_xlim(0, 110)
    bx.tick_params(axis="y", labelleft=False)
    bx.set_xlabel(
        "held-out queries outside the domain (%)\norange: the certificate warns of a shift", fontsize=9
    )
    _monitor_panel(mx, results)
    fig.suptitle(
        "calibrate --epsilon 0.1 on real logs, then the ε its refusal names (claims about runs, by default)",
        fontsize=11,
    )
    save_figure(fig, path)


def _replays(results: dict[str, Any]) -> list[tuple[str, str, dict[str, Any]]]:
    """``(what was replayed, whose contract, monitor record)``: the held-out parts, then V1_02."""
    out = []
    for log in results["logs"]:
        if "monitor" in log:
            owner = log["name"].split(",")[0]
            out.append((f"{owner}'s held-out {log['group_column_name']}s", owner, log["monitor"]))
    cross = results["cross_room"]
    return [*out, (f"all {cross['runs']} runs of EuRoC V1_02", MH04_LOG.name.split(",")[0], cross["monitor"])]


def _monitor_panel(ax: Any, results: dict[str, Any]) -> None:
    """The monitor's log e-values after each run, both tests, and its alarm level."""
    colors = ("tab:green", "tab:purple", "tab:red")
    for (what, owner, mon), color in zip(_replays(results), colors, strict=False):
        what = what if what.startswith(owner) else f"{what} through {owner}'s contract"
        n = np.arange(1, len(mon["log_e"]) + 1)
        ax.plot(
            n,
            mon["log_e"],
            "-o",
            ms=3,
            color=color,
            label=f"{what}: violations (null ε = {mon['epsilon']:g})",
        )
        if mon["domain_log_e"] is not None:
            ax.plot(n, mon["domain_log_e"], "--s", ms=3, color=color,
                    label=f"{what}: outside the domain (null {mon['domain_rate']:g})")  # fmt: skip
        if mon["domain_alarm"]:
            i = mon["domain_alarm_index"]
            ax.annotate(f"domain alarm after {i + 1} runs", (i + 1, mon["domain_log_e"][i]),
                        xytext=(i + 2.5, mon["domain_log_e"][i] - 2.5), fontsize=9,
                        arrowprops={"arrowstyle": "->"})  # fmt: skip
    silent = [what for what, _, mon in _replays(results) if not (mon["alarm"] or mon["domain_alarm"])]
    if silent:
        ax.text(10.5, 0.35, "no alarm: " + ", ".join(silent), fontsize=8.5, color="0.25")
    level = _replays(results)[0][2]["alarm_level"]
    ax.axhline(level, color="k", lw=1, ls=":")
    ax.text(0.6, level + 0.25, f"alarm level ln(1/δ) = {level:.2f}", fontsize=8)
    ax.set_xlabel("runs replayed (one observation per run, in the log's order)", fontsize=9)
    ax.set_ylabel("log e-value", fontsize=9)
    ax.set_xlim(0.5, 20.5)
    ax.set_ylim(-1, None)
    ax.set_xticks(range(1, 21))
    ax.legend(loc="upper left", fontsize=7.5, ncol=1, frameon=False)
    ax.set_title("ipcverify monitor, replaying held-out runs and another room", fontsize=10)


def _claim(step: dict[str, Any]) -> str:
    return f"{step['unit']} (`{step['unit_column']}`), ε = {step['certified_epsilon']:g}"


def _worth(step: dict[str, Any]) -> str:
    """What the calibration rows are worth: effective rows of all, and the design effect."""
    d = step["calibration_runs"]
    if d is None:
        return ""
    if d["design_effect"] is None:
        return f"{d['n_rows']:,} rows, none outside: not measured (τ = {d['autocorrelation_time']:.1f} rows)"
    return (
        f"{d['effective_rows']:,.0f} of {d['n_rows']:,} (design effect {d['design_effect']:.3f}, "
        f"τ = {d['autocorrelation_time']:.1f} rows)"
    )


def _cells(step: dict[str, Any]) -> str:
    """One step's cells: options, claim, verdict, the test by runs, rows, outside share, size, rows' worth."""
    options = " ".join(step["options"]) or "defaults"
    if "status" not in step:
        return f"`{options}` | refused: {refusal(step['message'])} | | | | | | | |"
    r = step["by_runs"]
    share = f"{_pct(r['mean_share'])} ({_pct(r['lower'])} to {_pct(r['upper'])})"
    anywhere = f"{r['with_violation']} of {r['runs']}"
    rows = f"{step['rows_outside']}/{step['test_rows']:,}"
    shift = ", shift warning" if step["shift_warning"] else ""
    outside = f"{_pct(step['outside_fraction'] or 0.0)} (flag rate {step['domain_flag_rate']:g}{shift})"
    return (
        f"`{options}` | {_claim(step)} | {step['status']} | {share} | {anywhere} | {rows} | {outside} | "
        f"{step['radius_over_error']:.2f} | {_worth(step)} |"
    )


def markdown_table(results: dict[str, Any]) -> str:
    """The table docs/real_logs.md shows: every log and every step, from the record."""
    lines = _head(
        "log", "rows (runs)", "split: train / calibration / test groups", "calibrate", "claim", "certificate",
        "held-out runs: mean share outside (99 % bounds)", "runs with a violation", "rows outside",
        "outside the domain", "set radius / error q90", "calibration rows worth (design effect)",
    )  # fmt: skip
    for log in [*results["logs"], results["cross_room"]]:
        parts = log.get("parts")
        split = (
            f"`{log['split']}`: "
            + " / ".join(str(parts[k]["groups"]) for k in ("train", "calibration", "test"))
            if parts
            else "the MH_04 contract; all of V1_02 tested"
        )
        head = f"| {log['name']} | {log['rows']:,} ({log['runs']}) | {split} | "
        for i, step in enumerate(log.get("steps", [])):
            lines.append((head if i == 0 else "| | | | ") + _cells(step))
    return "\n".join(lines)


def _head(*columns: str) -> list[str]:
    """A markdown table's header and separator lines."""
    return ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def replay_table(results: dict[str, Any]) -> str:
    """The monitor's replays, from the record: what was replayed, its nulls, and which test alarmed."""
    lines = _head(
        "replayed", "through the contract of", "runs", "violation test: null ε, alarm",
        "runs' shares outside their sets", "domain test: null flag rate, alarm",
        "runs' shares outside the domain", "exit status",
    )  # fmt: skip
    for what, owner, mon in _replays(results):

        def alarm(index: int | None) -> str:
            return "none" if index is None else f"**after {index + 1} runs**"

        lines.append(
            f"| {what} | {owner} | {mon['observations']} | "
            f"{mon['epsilon']:g}, {alarm(mon['alarm_index'])} | "
            f"{_pct(min(mon['shares']))} to {_pct(max(mon['shares']))} | "
            f"{mon['domain_rate']:g}, {alarm(mon['domain_alarm_index'])} | "
            f"{_pct(min(mon['outside_shares']))} to {_pct(max(mon['outside_shares']))} | {mon['exit']} |"
        )
    return "\n".join(lines)


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
