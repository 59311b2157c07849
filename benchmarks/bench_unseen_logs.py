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

``python -m benchmarks.bench_unseen_logs --rpg RPG --evo EVO`` (about 2 minutes on 2 cores)
writes ``benchmarks/unseen_logs_results.json`` and ``docs/img/unseen_logs.png``; docs/benchmarks.md
quotes them, and ``tests/benchmarks/test_bench_unseen_logs.py`` checks the page against the
record.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
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
            "--format", "kitti", "--times", "{evo}/KITTI_00_gt_times.txt", "--truth", "{evo}/KITTI_00_gt.txt",
            "--estimate", "{evo}/KITTI_00_ORB.txt", "--estimate", "{evo}/KITTI_00_SPTAM.txt",
        ),
        ("--block", "10", "--name-groups", "segment"),
        "segment",
    ),  # fmt: skip
    Log(
        "TUM fr2/desk",
        "hand-held RGB-D camera over a desk; ORB-SLAM",
        ("--truth", "{evo}/fr2_desk_groundtruth.txt", "--estimate", "{evo}/fr2_desk_ORB.txt"),
        ("--block", "5", "--name-groups", "segment"),
        "segment",
    ),
    Log(
        "TUM fr1/xyz",
        "hand-held RGB-D camera, 30 s; RGBD-SLAM",
        ("--truth", "{evo}/freiburg1_xyz-groundtruth.txt", "--estimate", "{evo}/freiburg1_xyz-rgbdslam.txt"),
        ("--block", "2", "--name-groups", "segment"),
        "segment",
    ),
    Log(
        "EuRoC V1_02, one estimator",
        "MAV in the Vicon room; one run of another estimator, EuRoC's ground-truth CSV",
        ("--truth-format", "euroc", "--truth", "{evo}/V102_groundtruth.csv", "--estimate", "{evo}/V102.txt"),
        ("--block", "5", "--name-groups", "segment"),
        "segment",
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
    c = json.loads((cert / "certificate.json").read_text())
    t, dom = c["test"], c["domain"] or {}
    inside = dom["n"] - dom["outside"] if dom else None
    group = c.get("group_test") or {}
    return {
        "status": c["status"],
        "verdict": c["summary"]["verdict"],
        "certified_epsilon": c["calibration"]["certified_epsilon"],
        "test_n": t["n"],
        "test_violations": t["violations"],
        "test_rate": t["empirical_rate"],
        "test_upper": t["upper_bound"],
        "test_lower": t["lower_bound"],
        "outside_fraction": dom.get("outside_fraction"),
        "inside_violation_rate": (dom["violations_inside"] / inside) if inside else None,
        "group_test": {k: group.get(k) for k in ("n", "violations", "upper_bound")} if group else None,
        "median_log_volume": c["volume"]["median_log"],
        "theorem1_vacuous": c["theorem1"]["vacuous"],
    }


def run_log(log: Log, roots: dict[str, Path], folder: Path) -> dict[str, Any]:
    """Ingest, split, train, calibrate and certify one log in ``folder``; what each step gave."""
    data = folder / "log.csv"
    ingest = [a.format(**{k: str(v) for k, v in roots.items()}) for a in log.ingest]
    code, err = _cli(["ingest", "trajectories", *ingest, "--out", str(data)])
    if code:
        return {"name": log.name, "what": log.what, "refused_at": "ingest", "message": err}
    manifest = json.loads(data.with_name("log.manifest.json").read_text())
    rows = len(pd.read_csv(data))
    parts = folder / "parts"
    code, err = _cli(["split", str(data), "--out", str(parts), *log.split])
    if code:
        return {"name": log.name, "what": log.what, "rows": rows, "refused_at": "split", "message": err}
    record = json.loads((parts / "split.json").read_text())["parts"]
    out: dict[str, Any] = {
        "name": log.name,
        "what": log.what,
        "rows": rows,
        "runs": len(manifest["runs"]) if isinstance(manifest.get("runs"), list | dict) else None,
        "split": " ".join(log.split),
        "parts": {k: {"rows": v["rows"], "groups": v["groups"]} for k, v in record.items()},
    }
    t0 = time.perf_counter()
    code, err = _cli(["train", str(parts / "train.csv"), "--out", str(folder / "model.pt")])
    out["train_seconds"] = time.perf_counter() - t0
    if code:
        return {**out, "refused_at": "train", "message": err}
    code, err = _cli(
        ["calibrate", str(folder / "model.pt"), str(parts / "calibration.csv"), "--epsilon", str(EPSILON)]
        + ["--delta", str(DELTA), "--out", str(folder / "calibrated.pt")]
    )
    if code:
        return {**out, "refused_at": "calibrate", "message": err}
    result = _certified(folder, folder / "calibrated.pt", parts / "test.csv", log.group_column)
    if "refused" in result:
        return {**out, "refused_at": "certify", "message": result["refused"]}
    errors = _errors(parts / "test.csv", EPSILON)
    radius = _radius(result["median_log_volume"], dim=3)
    return {**out, **result, "errors": errors, "set_radius": radius, "radius_over_error": radius / errors["quantile"]}


def cross_room(rpg: Path, folder: Path) -> dict[str, Any]:
    """A contract trained and calibrated on MH_04 (machine hall), certified on V1_02 (Vicon room)."""
    parts = folder / "mh04"
    _cli(["split", str(MH04), "--out", str(parts), "--by", "method,run"])
    _cli(["train", str(parts / "train.csv"), "--out", str(folder / "mh04.pt")])
    _cli(
        ["calibrate", str(folder / "mh04.pt"), str(parts / "calibration.csv"), "--epsilon", str(EPSILON)]
        + ["--delta", str(DELTA), "--out", str(folder / "mh04_calibrated.pt")]
    )
    v102 = folder / "v102.csv"
    ingest = [a.format(rpg=str(rpg)) for a in _vislam_v102()]
    _cli(["ingest", "trajectories", *ingest, "--out", str(v102)])
    result = _certified(folder, folder / "mh04_calibrated.pt", v102, "run")
    errors = _errors(v102, EPSILON)
    radius = _radius(result["median_log_volume"], dim=3)
    return {
        "name": "MH_04 contract in V1_02",
        "what": "trained and calibrated on MH_04 (data/euroc_mh04_vislam.csv, split by method,run), "
        "certified on all of V1_02",
        "rows": len(pd.read_csv(v102)),
        **result,
        "errors": errors,
        "set_radius": radius,
        "radius_over_error": radius / errors["quantile"],
    }


def figure(results: dict[str, Any], path: Path = FIGURE) -> None:
    """Each log's held-out violation rate with its 1 - delta interval, against epsilon; and the share outside."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in [*results["logs"], results["cross_room"]] if "test_rate" in r]
    names = [r["name"] for r in rows]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 0.55 * len(rows) + 1.6), sharey=True)
    y = np.arange(len(rows))[::-1]
    rate = np.array([r["test_rate"] for r in rows])
    lo = np.array([r["test_lower"] for r in rows])
    up = np.array([r["test_upper"] for r in rows])
    colors = ["tab:red" if r["status"] == "CONTRADICTED" else "tab:blue" for r in rows]
    ax.errorbar(rate, y, xerr=[rate - lo, up - rate], fmt="none", ecolor=colors, capsize=3)
    ax.scatter(rate, y, c=colors, zorder=3)
    ax.axvline(EPSILON, color="k", ls="--", lw=1, label=f"target epsilon = {EPSILON}")
    ax.set_yticks(y, names)
    ax.set_xlabel(f"held-out violation rate (rows outside their set), {1 - DELTA:.0%} interval")
    ax.legend(loc="lower right", fontsize=8)
    outside = [100 * (r["outside_fraction"] or 0.0) for r in rows]
    bx.barh(y, outside, color=colors)
    bx.set_xlabel("held-out queries outside the domain of validity (%)")
    for yi, o in zip(y, outside, strict=True):
        bx.text(o + 1, yi, f"{o:.1f} %", va="center", fontsize=8)
    bx.set_xlim(0, 110)
    fig.suptitle("Defaults on real logs ipcverify was never developed on (red: the certificate is contradicted)")
    save_figure(fig, path)


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
            print(json.dumps(out["logs"][-1], default=str)[:300])
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
