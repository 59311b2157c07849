"""The sensitivity study: Table I when one camera-timing parameter is changed.

No parameter of ``[camera_timing]`` is fitted to Table I; the sources leave several of them
open (the Pi's speed, the stalls, the queue's policy, the camera module). This study shows how
Table I moves when each is changed alone (:func:`.variants.sensitivity_variants`), with the
protocol and sizes of the ablation (``[ablation]`` of ``reproduce.toml``). It is a command of
its own, ``python -m case_studies.quad_landing sensitivity --out DIR``, which writes
``DIR/sensitivity.json`` and ``DIR/sensitivity.md`` (the table in ``docs/case_study.md``);
its datasets and models are cached in ``DIR`` like a reproduction's.

Examples
--------
>>> from case_studies.quad_landing.reproduction.table1 import Table1, Table1Row
>>> row = Table1Row(buffer_size=1, n=100, violations=1, rate=0.01, upper=0.05, interval=(0.0, 0.06),
...                 confidence=0.95, paper_rate=0.0019, paths=None, paths_with_violations=None)
>>> from case_studies.quad_landing.reproduction.variants import VariantTable
>>> t = VariantTable("all", "defaults.toml", "reference", Table1((row,)), {1: 20.0}, {1: 5.0}, 0.01)
>>> print(study_markdown([t]).splitlines()[2])
| defaults.toml | 1.0 % (1/100) | 20 |
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from case_studies.quad_landing.reproduction.collection import DatasetPlan, collect_plan
from case_studies.quad_landing.reproduction.config import ReproduceConfig, load_reproduce_config
from case_studies.quad_landing.reproduction.table1 import PAPER_TABLE1
from case_studies.quad_landing.reproduction.variants import (
    VariantStudy,
    VariantTable,
    plan_variants,
    sensitivity_variants,
    variant_tables,
)
from case_studies.quad_landing.sim.config import SimConfig, load_config
from ipcverify.data._files import atomic_write, json_data, write_json
from ipcverify.errors import InvalidInputError

__all__ = ["run_sensitivity", "study_markdown"]

#: Name prefix of the study's datasets and models.
PREFIX = "sens-"
#: The reproduction's seeds of the training, calibration and pilot flights.
SEEDS = {"train": 0, "calibration": 1, "pilot": 3}


def study_markdown(rows: Sequence[VariantTable]) -> str:
    """The rows as a Markdown table: rate (violations/n) per buffer size, median age at buffer 1."""
    buffers = list(rows[0].table.buffers)
    head = "| configuration | " + " | ".join(f"b = {b}" for b in buffers) + " | median age b = 1 (ms) |"
    lines = [head, "|---|" + "---|" * (len(buffers) + 1)]
    for r in rows:
        cells = [f"{100 * r.table.row(b).rate:.1f} % ({r.table.row(b).violations}/{r.table.row(b).n})"
                 for b in buffers]  # fmt: skip
        lines.append(f"| {r.label} | " + " | ".join(cells) + f" | {r.median_age_ms[buffers[0]]:.0f} |")
    paper = " | ".join(f"{100 * PAPER_TABLE1[b]:.2f} %" if b in PAPER_TABLE1 else "—" for b in buffers)
    lines.append(f"| paper | {paper} | — |")
    return "\n".join(lines)


def run_sensitivity(
    out: str | os.PathLike[str],
    *,
    quick: bool = False,
    config: ReproduceConfig | None = None,
    sim_config: SimConfig | None = None,
    only: Sequence[str] | None = None,
    n_jobs: int = 2,
) -> tuple[VariantStudy, dict[str, Any]]:
    """Table I of every sensitivity variant; writes ``OUT/sensitivity.json`` and ``OUT/sensitivity.md``.

    Parameters
    ----------
    out : path-like
        Output directory (created); datasets and models are cached in it.
    quick : bool
        The ``[quick.ablation]`` sizes.
    config, sim_config : optional
        The reproduction's settings and the simulator (defaults: the shipped files).
    only : sequence of str, optional
        Names of the variants to run (``all`` is always run, as the reference).
    n_jobs : int
        Worker processes.

    Returns
    -------
    study : VariantStudy
    timing : dict
        Seconds per stage.
    """
    cfg = config or load_reproduce_config(quick=quick)
    sim = sim_config or load_config()
    variants = sensitivity_variants(sim)
    if only:
        unknown = sorted(set(only) - {v.name for v in variants})
        if unknown:
            raise InvalidInputError(
                f"unknown sensitivity variants {unknown}; known: {', '.join(v.name for v in variants)}"
            )
        variants = [v for v in variants if v.name == "all" or v.name in only]
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise InvalidInputError(f"--out {out_dir} exists and is not a directory; choose a directory")
    for sub in ("data", "models"):
        (out_dir / sub).mkdir(parents=True, exist_ok=True)
    plan = DatasetPlan()
    buffers = cfg.sizes.buffers
    plan_variants(
        plan, variants, prefix=PREFIX, sizes=cfg.ablation, buffers=buffers, seeds=SEEDS, out_dir=out_dir
    )
    t0 = time.perf_counter()
    data, frames = collect_plan(plan, approach=cfg.approach, pilot=cfg.pilot, config=sim, jobs=n_jobs)
    t1 = time.perf_counter()
    study = variant_tables(variants, prefix=PREFIX, datasets=data, frames=frames, ipc=cfg.ipc,
                           sizes=cfg.ablation, buffers=buffers, out_dir=out_dir, jobs=n_jobs,
                           delta=0.05)  # fmt: skip
    timing = {"collect": round(t1 - t0, 1), "learn_and_test": round(time.perf_counter() - t1, 1)}
    write_json(out_dir / "sensitivity.json", json_data({**study.to_dict(), "seconds": timing}), indent=1)
    text = study_markdown(study.rows) + "\n"
    atomic_write(out_dir / "sensitivity.md", lambda fh: fh.write(text), "w")
    return study, timing
