"""The worked example of docs/ingest.md: simulated flights in ROS bags, to a certified contract.

Run ``python -m docgen.ingest_example --out ingest-example`` (about 3 minutes on 2 cores).
It writes 100 ROS 1 bags of 20 s flights (``flights/flight_NNN.bag``), each with

* ``/vicon/drone/pose`` (``geometry_msgs/PoseStamped``, 120 Hz): motion-capture truth, stamped
  by the motion-capture computer, whose clock runs ``MOCAP_AHEAD`` = 3.2 s ahead of the robot's;
* ``/vio/odometry`` (``nav_msgs/Odometry``, 30 Hz): a simulated visual-inertial estimate in its
  own world frame (it starts at the origin, facing along x), stamped by the robot's clock.
  Its error grows with speed and rotation rate: a per-flight scale error of the velocity, noise
  on every increment, and a yaw drift;

then runs, and prints, the commands of docs/ingest.md (ingest 30 flights for training, 50 for
calibration and 20 for testing; train; calibrate by flight; certify), and draws
``docs/img/ingest_truth_vs_estimate.png``: the truth against the estimate over one flight.
``--flights`` and ``--seconds`` make it smaller; ``--ingest-only`` stops after ingesting.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from scipy.spatial.transform import Rotation

from benchmarks.bench_ingest import PoseStream, write_pose_bag
from ipcverify.data._files import atomic_write

__all__ = ["MOCAP_AHEAD", "simulate_flight", "write_flights", "commands", "plot_flight", "main"]

ROOT = Path(__file__).resolve().parent.parent
FIGURE = ROOT / "docs" / "img" / "ingest_truth_vs_estimate.png"
MOCAP_AHEAD = 3.2
RATE_TRUTH, RATE_EST = 120.0, 30.0
TRUTH, ESTIMATE = "/vicon/drone/pose", "/vio/odometry"


def _flight_path(t: np.ndarray, size: tuple[float, float, float, float]) -> tuple[np.ndarray, Rotation]:
    """A figure-eight (half-widths a, b, rate w, heading yaw0); the body tilts as it accelerates."""
    a, b, w, yaw0 = size
    p = np.column_stack([a * np.sin(w * t), b * np.sin(2 * w * t), 1.2 + 0.2 * np.sin(0.5 * w * t)])
    acc = np.column_stack([-a * w**2 * np.sin(w * t), -4 * b * w**2 * np.sin(2 * w * t)])
    yaw = yaw0 + 0.3 * np.sin(0.7 * w * t)
    tilt = np.column_stack([yaw, np.arctan(acc[:, 0] / 9.81), -np.arctan(acc[:, 1] / 9.81)])
    return p, Rotation.from_euler("ZYX", tilt)


def simulate_flight(seed: int, seconds: float) -> tuple[PoseStream, PoseStream]:
    """The truth and estimate streams of one flight (the module docstring describes them)."""
    rng = np.random.default_rng(seed)
    size = (
        rng.uniform(1.0, 3.0),
        rng.uniform(0.6, 1.5),
        2 * np.pi / rng.uniform(5.0, 14.0),
        rng.uniform(-np.pi, np.pi),
    )
    start = 1_700_000_000.0 + 100.0 * seed  # the robot's clock at take-off
    t_truth = np.arange(0.0, seconds, 1 / RATE_TRUTH)
    t_est = 0.011 + np.arange(0.0, seconds - 0.02, 1 / RATE_EST)
    p_true, r_true = _flight_path(t_truth, size)
    p_at_est, r_at_est = _flight_path(t_est, size)
    step = np.diff(p_at_est, axis=0, prepend=p_at_est[:1])
    turn = np.r_[0.0, (r_at_est[:-1].inv() * r_at_est[1:]).magnitude()]
    noise = (0.03 * np.linalg.norm(step, axis=1) + 0.02 * turn + 2e-4)[:, None]
    step_est = (1.0 + rng.normal(0.0, 0.02)) * step + rng.normal(0.0, 1.0, step.shape) * noise
    # a yaw drift turns the estimated world: positions and attitude alike, so that it leaves the
    # body-frame displacement alone, as in a real visual-inertial estimator
    drift = Rotation.from_euler("z", np.cumsum(rng.normal(0.0, 0.002, len(t_est)))[:, None])
    frame = Rotation.from_euler("z", size[3]).inv()  # the estimator's own world: it starts facing along x
    p_est = frame.apply(np.cumsum(drift.apply(step_est), axis=0))
    r_est = frame * drift * r_at_est
    return (
        PoseStream(
            TRUTH, "geometry_msgs/msg/PoseStamped", start + MOCAP_AHEAD + t_truth, start + t_truth + 0.004,
            p_true, r_true.as_quat(),
        ),
        PoseStream(
            ESTIMATE, "nav_msgs/msg/Odometry", start + t_est, start + t_est + 0.02, p_est, r_est.as_quat()
        ),
    )  # fmt: skip


def write_flights(out: Path, flights: int, seconds: float) -> list[Path]:
    """Write the flights as ROS 1 bags under ``out/flights``."""
    (out / "flights").mkdir(parents=True, exist_ok=True)
    return [
        write_pose_bag("ros1", out / "flights" / f"flight_{k:03d}", simulate_flight(k, seconds))
        for k in range(flights)
    ]


def commands(out: Path, bags: list[Path], ingest_only: bool) -> list[list[str]]:
    """The commands of docs/ingest.md, for these bags."""
    n = len(bags)
    parts = {
        "train": bags[: int(0.3 * n)],
        "calibration": bags[int(0.3 * n) : int(0.8 * n)],
        "test": bags[int(0.8 * n) :],
    }
    ingest = ["ingest", "bag", "--truth", TRUTH, "--estimate", ESTIMATE, "--t-offset", f"{-MOCAP_AHEAD}"]
    cmds = [["ingest", "topics", str(bags[0])]]
    cmds += [[*ingest, *map(str, b), "--out", str(out / f"{name}.parquet")] for name, b in parts.items()]
    if not ingest_only:
        cmds += [
            ["train", str(out / "train.parquet"), "--out", str(out / "model.pt")],
            [
                "calibrate", str(out / "model.pt"), str(out / "calibration.parquet"), "--epsilon", "0.1",
                "--delta", "0.01", "--group-column", "run", "--domain-flag-rate", "0.05",
                "--out", str(out / "calibrated.pt"),
            ],
            [
                "certify", str(out / "calibrated.pt"), "--data", str(out / "test.parquet"),
                "--group-column", "run", "--out", str(out / "certificate"),
            ],
        ]  # fmt: skip
    return cmds


def plot_flight(table: Path, run: str, figure: Path) -> None:
    """The truth's and the estimate's displacement over one flight, axis by axis."""
    df = pd.read_parquet(table)
    one = df[df["run"] == run]
    fig = Figure(figsize=(9.0, 7.5), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True, height_ratios=(1, 1, 1, 0.8))
    for i, (ax, name) in enumerate(zip(axes[:3], ("forward", "left", "up"), strict=True)):
        ax.plot(one["t"], one[f"y_{i}"], color="black", lw=1.6, label="truth y (motion capture)")
        ax.plot(one["t"], one[f"yhat_{i}"], color="tab:orange", lw=1.0, label="estimate ŷ (VIO)")
        ax.set_ylabel(f"{name} (m)")
        ax.grid(alpha=0.3)
    err = np.linalg.norm(
        one[["y_0", "y_1", "y_2"]].to_numpy() - one[["yhat_0", "yhat_1", "yhat_2"]].to_numpy(), axis=1
    )
    axes[3].plot(one["t"], 100 * err, color="tab:red", lw=1.0)
    axes[3].set_ylabel("|y - ŷ| (cm)")
    axes[3].grid(alpha=0.3)
    axes[0].legend(loc="upper right", ncols=2, fontsize=8)
    axes[0].set_title(f"{run}: body-frame displacement over the next 0.5 s, one sample every 0.25 s")
    axes[-1].set_xlabel("t (s since the estimate's first stamp)")
    atomic_write(figure, lambda f: fig.savefig(f, format="png", dpi=110))


def main(argv: list[str] | None = None) -> None:
    """Write the flights, run the commands (printing each), draw the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("ingest-example"))
    parser.add_argument("--flights", type=int, default=100)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--figure", type=Path, default=FIGURE)
    parser.add_argument("--ingest-only", action="store_true")
    args = parser.parse_args(argv)
    bags = write_flights(args.out, args.flights, args.seconds)
    for cmd in commands(args.out, bags, args.ingest_only):
        print("$ ipcverify " + shlex.join(cmd), flush=True)
        subprocess.run([sys.executable, "-m", "ipcverify", *cmd], check=True)
    plot_flight(args.out / "train.parquet", bags[0].stem, args.figure)


if __name__ == "__main__":
    main()
