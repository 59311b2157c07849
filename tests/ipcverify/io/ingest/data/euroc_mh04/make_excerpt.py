"""Make this excerpt from rpg_trajectory_evaluation's public files (run once; the output is committed).

    python tests/ipcverify/io/ingest/data/euroc_mh04/make_excerpt.py CHECKOUT

CHECKOUT is a checkout of github.com/uzh-rpg/rpg_trajectory_evaluation. Every line written is
a line of the public files, unchanged:

* the first SECONDS of two estimate files of each method (vislam_rp runs 0 and 5, vislam_ba
  runs 0 and 3);
* of the ground truth (stamped_groundtruth.txt, the same file for both methods), only the two
  lines around every time at which the samples of those runs interpolate it (t0 and t0 + 0.5 s).
  Interpolating between those two lines is what the full file gives, so the samples are the same.
"""

from __future__ import annotations

import gzip
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RUNS = {"vislam_rp": ("stamped_traj_estimate", (0, 5)), "vislam_ba": ("stamped_ba_estimate", (0, 3))}
SECONDS = {"vislam_rp": 20.0, "vislam_ba": 30.0}
H, S = 0.5, 0.25


def main(checkout: Path) -> None:
    base = checkout / "results/euroc_vislam_mono/laptop"
    gt_lines = (base / "vislam_rp/laptop_vislam_rp_MH_04/stamped_groundtruth.txt").read_text().splitlines()
    header, body = gt_lines[0], gt_lines[1:]
    gt_t = np.array([float(line.split()[0]) for line in body])
    keep: set[int] = set()
    for method, (stem, runs) in RUNS.items():
        for k in runs:
            lines = (base / f"{method}/laptop_{method}_MH_04/{stem}{k}.txt").read_text().splitlines()
            t = np.array([float(line.split()[0]) for line in lines])
            cut = lines[: int(np.searchsorted(t - t[0], SECONDS[method], side="right"))]
            (HERE / f"{method}_{k}.txt").write_text("\n".join(cut) + "\n")
            e0 = t[0]
            rel = gt_t + (0.0 - e0)  # the arithmetic of ipcverify.io.ingest._samples
            span = float(t[len(cut) - 1]) - e0
            t0 = S * np.arange(int(span / S) + 2)
            t0 = t0[t0 + H < span]
            for q in np.concatenate([t0, t0 + H]):
                i = int(np.searchsorted(rel, q, side="right"))
                keep |= {i - 1, i}
    with gzip.open(HERE / "groundtruth.txt.gz", "wt", encoding="utf-8") as f:
        f.write("\n".join([header, *(body[i] for i in sorted(keep))]) + "\n")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
