"""Benchmark: time to collect the quad-landing dataset (5000 samples by default).

Target: <= 30 s on 2 cores. Run from the repository root::

    python benchmarks/bench_collect.py                   # jobs = 1 and 2, k = 1
    python benchmarks/bench_collect.py --jobs 2 --json timing.json

Prints one line per run (wall time, CPU time of this process, detection stats) and,
with ``--json``, writes the same numbers to a file. The load average is printed too:
other processes on the machine make the timings longer.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

from case_studies.quad_landing.data.collect import collect


def run(n: int, buffer_size: int, seed: int, jobs: int) -> dict:
    t0, c0 = time.perf_counter(), time.process_time()
    data, stats = collect(n, buffer_size=buffer_size, seed=seed, jobs=jobs)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    assert len(data) == n
    return {
        "n": n,
        "buffer_size": buffer_size,
        "seed": seed,
        "jobs": jobs,
        "wall_s": round(wall, 2),
        "cpu_s_main_process": round(cpu, 2),
        "samples_per_s": round(n / wall, 1),
        **{k: v for k, v in stats.as_dict().items() if k not in ("wall_time",)},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=5000)
    parser.add_argument("--buffer-size", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--json", default=None, help="also write the results here")
    args = parser.parse_args()
    header = {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "load_average_before": [round(v, 2) for v in os.getloadavg()],
    }
    print(json.dumps(header))
    results = []
    for jobs in args.jobs:
        r = run(args.n, args.buffer_size, args.seed, jobs)
        results.append(r)
        print(
            f"n={r['n']} k={r['buffer_size']} jobs={jobs}: {r['wall_s']:.1f} s wall "
            f"({r['samples_per_s']:.0f} samples/s), detection rate "
            f"{100 * r['detection_rate']:.2f} % ({r['missed']} missed: "
            f"{r['missed_out_of_view']} out of view, {r['missed_in_view']} in view), "
            f"{r['paths']} paths, {r['flight_time']:.0f} s flown"
        )
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"machine": header, "runs": results}, fh, indent=2)
            fh.write("\n")


if __name__ == "__main__":
    main()
