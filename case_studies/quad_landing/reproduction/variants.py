"""Table I for camera variants: the ablation of the error sources and the sensitivity study.

A *variant* is the simulator with a changed camera: an error source switched off or on
alone (``[camera_timing] disabled``), the previous fixed ``k``-frame lag, or one timing
parameter changed. Each variant follows the paper's protocol on its own: an IPC learned
and calibrated at buffer size 1 on exploration data measured with *that* camera, then
tested at every buffer size on pilot test flights (the same flights for all variants and
buffer sizes). The sizes are ``[ablation]`` of ``reproduce.toml``.

* :func:`ablation_variants` — every source alone (with the driver queue, without which the
  buffer size changes nothing) and every source removed, the queue alone, all sources,
  and the previous ``k``-frame lag;
* :func:`sensitivity_variants` — one parameter of ``[camera_timing]`` changed from
  ``defaults.toml`` each (the values that the sources leave open).

Examples
--------
>>> from case_studies.quad_landing.sim.config import load_config
>>> names = [v.name for v in ablation_variants(load_config())]
>>> names[:3], "no-blur" in names, "frames" in names
(['all', 'queue', 'queue+latency'], True, True)
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import joblib
import numpy as np
import pandas as pd

from case_studies.quad_landing.data.datasets import DatasetSpec
from case_studies.quad_landing.reproduction.collection import DatasetPlan, spec_path
from case_studies.quad_landing.reproduction.config import AblationSizes, IpcParams
from case_studies.quad_landing.reproduction.learn import cached_ipc, certified_epsilon
from case_studies.quad_landing.reproduction.table1 import Table1, table1
from case_studies.quad_landing.sim.camera import SOURCES
from case_studies.quad_landing.sim.config import SimConfig
from ipcverify.data import PerceptionDataset

__all__ = [
    "SOURCE_LABELS",
    "Variant",
    "VariantTable",
    "VariantStudy",
    "ablation_variants",
    "sensitivity_variants",
    "plan_variants",
    "variant_tables",
]

#: What each error source is, in words (the report's and the docs' labels).
SOURCE_LABELS: dict[str, str] = {
    "queue": "driver queue (buffer lag)",
    "latency": "base latency (ISP)",
    "jitter": "jitter",
    "stalls": "reader stalls",
    "clock": "clock phase and rate, motion-capture sampling",
    "blur": "motion blur",
    "shutter": "rolling shutter",
    "noise": "sensor noise",
}


@dataclass(frozen=True)
class Variant:
    """A camera variant: a name (file names), a label (reports), its group and its simulator."""

    name: str
    label: str
    group: str
    config: SimConfig


def ablation_variants(base: SimConfig) -> list[Variant]:
    """All sources; the queue alone; the queue with each other source; each source removed; k-frame lag."""
    timing = base.camera_timing
    out = [
        Variant("all", "all sources", "reference", base),
        Variant("queue", "driver queue alone", "alone", base.replace(camera_timing={"disabled": [
            s for s in SOURCES if s != "queue"]})),
    ]  # fmt: skip
    for s in SOURCES[1:]:
        disabled = list(timing.only("queue", s).disabled)
        out.append(Variant(f"queue+{s}", f"queue + {SOURCE_LABELS[s]}", "alone",
                           base.replace(camera_timing={"disabled": disabled})))  # fmt: skip
    for s in SOURCES:
        disabled = list(timing.without(s).disabled)
        out.append(Variant(f"no-{s}", f"without {SOURCE_LABELS[s]}", "removed",
                           base.replace(camera_timing={"disabled": disabled})))  # fmt: skip
    out.append(Variant("frames", "previous model: fixed lag of b frames", "reference",
                       base.replace(camera_timing={"model": "frames"})))  # fmt: skip
    return out


def _scaled(values: Sequence[float], factor: float) -> list[float]:
    return [float(v) * factor for v in values]


def sensitivity_variants(base: SimConfig) -> list[Variant]:
    """``defaults.toml`` and one ``[camera_timing]`` value changed at a time (see ``docs/case_study.md``)."""
    t = base.camera_timing
    changes: list[tuple[str, str, dict[str, Any]]] = [
        ("cpu-x0.5", "Pi reader twice as fast (cpu_scale x 0.5)", {"cpu_scale": t.cpu_scale * 0.5}),
        ("cpu-x2", "Pi reader twice as slow (cpu_scale x 2)", {"cpu_scale": t.cpu_scale * 2.0}),
        ("parallel-1.5", "OpenCV threads give 1.5x on the Pi's cores", {"parallel_speedup": 1.5}),
        ("overhead-5ms", "5 ms loop overhead (IPC + controller in the loop)", {"overhead": 0.005}),
        ("os-jitter-3ms", "OS jitter mean 3 ms", {"os_jitter": 3 * t.os_jitter}),
        ("stalls-x4", "four times as many stalls", {"stall_rate": 4 * t.stall_rate}),
        ("stalls-long", "stalls twice as long", {"stall_duration": _scaled(t.stall_duration, 2.0)}),
        ("drop-newest", "queue drops the newest frame (videobuf2)", {"policy": "drop_newest"}),
        ("drop-oldest", "queue overwrites the oldest frame (ring)", {"policy": "drop_oldest"}),
        ("readout-16ms", "16 ms readout (Pi camera v1 at VGA)", {"readout": 0.016}),
        ("exposure-2ms", "2 ms exposure", {"exposure": 0.002}),
        ("exposure-16ms", "16 ms exposure", {"exposure": 0.016}),
        ("isp-10ms", "10 ms ISP latency", {"isp_latency": 0.010}),
        ("mocap-latency-0", "motion capture without latency", {"mocap_latency": 0.0}),
        ("mocap-latency-20ms", "20 ms motion-capture latency", {"mocap_latency": 0.020}),
        ("mocap-200hz", "motion capture at 200 Hz", {"mocap_rate": 200.0}),
    ]
    out = [Variant("all", "defaults.toml", "reference", base)]
    out += [
        Variant(name, label, "sensitivity", base.replace(camera_timing=kw)) for name, label, kw in changes
    ]
    return out


def plan_variants(
    plan: DatasetPlan,
    variants: Sequence[Variant],
    *,
    prefix: str,
    sizes: AblationSizes,
    buffers: Sequence[int],
    seeds: Mapping[str, int],
    out_dir: Path,
) -> None:
    """Add each variant's training, calibration (buffer 1) and pilot test sets to ``plan``."""
    for v in variants:
        base = f"{prefix}{v.name}"
        for kind, part, n, b in (
            ("mixed", "train", sizes.n_train, 1),
            ("mixed", "calibration", sizes.n_calibration, 1),
            *(("pilot", "pilot", sizes.n_pilot, b) for b in buffers),
        ):
            name = f"{base}_{part}_k{b}"
            plan.add(kind, seeds[part], DatasetSpec(name, v.config, b, n, spec_path(out_dir, name)))


@dataclass(frozen=True)
class VariantTable:
    """One variant's Table I with the median image age and error per buffer size.

    Attributes
    ----------
    name, label, group : str
        The variant.
    table : Table1
        Its buffer-1 IPC at buffer sizes 1..5 on pilot test flights.
    median_age_ms, median_error_mm : mapping of int to float
        Per buffer size: the median age of the test images (image older than the state) and
        the median ``|yhat_C - y_C|``.
    certified_epsilon : float
        What the variant's calibration certifies.
    """

    name: str
    label: str
    group: str
    table: Table1
    median_age_ms: Mapping[int, float]
    median_error_mm: Mapping[int, float]
    certified_epsilon: float

    def to_dict(self) -> dict[str, Any]:
        """``summary.json``'s ``ablation.rows.<name>``."""
        return {
            "label": self.label,
            "group": self.group,
            "table1": self.table.to_dict(),
            "rising": self.table.rising().to_dict(),
            "median_age_ms": {str(b): v for b, v in self.median_age_ms.items()},
            "median_error_mm": {str(b): v for b, v in self.median_error_mm.items()},
            "certified_epsilon": self.certified_epsilon,
        }


@dataclass(frozen=True)
class VariantStudy:
    """Tables I of several variants (the ablation or the sensitivity study)."""

    sizes: AblationSizes
    rows: tuple[VariantTable, ...]

    def row(self, name: str) -> VariantTable:
        """The variant called ``name``."""
        for r in self.rows:
            if r.name == name:
                return r
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        """``summary.json``'s ``ablation``: the sizes and one entry per variant."""
        return {
            "sizes": self.sizes.to_table(),
            "protocol": (
                "each variant learns and calibrates its own IPC at buffer size 1 on exploration data "
                "measured with its camera, then is tested at every buffer size on the same pilot flights"
            ),
            "rows": {r.name: r.to_dict() for r in self.rows},
        }


def _median_age_error(frame: pd.DataFrame) -> tuple[float, float]:
    err = frame[["yhat_0", "yhat_1", "yhat_2"]].to_numpy() - frame[["y_0", "y_1", "y_2"]].to_numpy()
    return 1e3 * float(frame["age"].median()), 1e3 * float(np.median(np.linalg.norm(err, axis=1)))


def _learn_and_test(
    v: Variant,
    train: PerceptionDataset,
    cal: PerceptionDataset,
    tests: dict[int, PerceptionDataset],
    params: IpcParams,
    model_path: Path,
    delta: float,
) -> tuple[Table1, float, list[tuple[type[Warning], str]]]:
    """One variant's IPC and Table I, in a worker process; its warnings are returned, not printed."""
    import torch

    torch.set_num_threads(1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        model, _ = cached_ipc(model_path, train, cal, params)
        table = table1(model, tests, delta)
    return table, certified_epsilon(model), [(w.category, f"ablation {v.name}: {w.message}") for w in caught]


def variant_tables(
    variants: Sequence[Variant],
    *,
    prefix: str,
    datasets: Mapping[str, PerceptionDataset],
    frames: Mapping[str, pd.DataFrame],
    ipc: IpcParams,
    sizes: AblationSizes,
    buffers: Sequence[int],
    out_dir: Path,
    jobs: int,
    delta: float,
) -> VariantStudy:
    """Learn each variant's buffer-1 IPC (cached in ``OUT/models``) and its Table I, ``jobs`` at a time."""
    params = dataclasses.replace(ipc, epsilon=sizes.epsilon, delta=sizes.delta)
    calls = []
    for v in variants:
        base = f"{prefix}{v.name}"
        tests = {b: datasets[f"{base}_pilot_k{b}"] for b in buffers}
        calls.append(joblib.delayed(_learn_and_test)(
            v, datasets[f"{base}_train_k1"], datasets[f"{base}_calibration_k1"], tests, params,
            out_dir / "models" / f"{base}.pt", delta,
        ))  # fmt: skip
    results = joblib.Parallel(n_jobs=max(1, min(jobs, len(calls))))(calls)
    rows = []
    for v, (table, eps, caught) in zip(variants, results, strict=True):
        for category, message in caught:  # shown here, where the CLI prints each on one line
            warnings.warn(message, category, stacklevel=2)
        base = f"{prefix}{v.name}"
        stats = {b: _median_age_error(frames[f"{base}_pilot_k{b}"]) for b in buffers}
        rows.append(VariantTable(
            name=v.name, label=v.label, group=v.group, table=table,
            median_age_ms={b: s[0] for b, s in stats.items()},
            median_error_mm={b: s[1] for b, s in stats.items()},
            certified_epsilon=eps,
        ))  # fmt: skip
    return VariantStudy(sizes, tuple(rows))
