"""What every step of one reproduction shares: its settings, output directory, workers and stages.

:class:`Run` is one reproduction's context (:func:`start_run` checks and creates its output
directory); :class:`Stages` its progress bars and stage timings. :data:`SEEDS` are the seeds
of its datasets and campaigns, :data:`REPORT_DELTA` the confidence parameter of its reported
intervals. :func:`certify_ipc` certifies a learned IPC on its held-out test set and writes the
certificate; :func:`machine_info` and :func:`cpu_seconds` say where and at what cost it ran.
"""

from __future__ import annotations

import os
import platform
import resource
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import torch
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from case_studies.quad_landing.reproduction.campaign import default_jobs
from case_studies.quad_landing.reproduction.config import ReproduceConfig
from case_studies.quad_landing.reproduction.record import Record
from case_studies.quad_landing.sim.config import SimConfig
from ipcverify.contract import IPCModel
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError

if TYPE_CHECKING:
    from ipcverify.certification._test_result import GroupTest, TestResult

__all__ = [
    "SEEDS",
    "REPORT_DELTA",
    "ABLATION_PREFIX",
    "Stages",
    "Run",
    "start_run",
    "CertificateRecord",
    "certify_ipc",
    "MachineInfo",
    "machine_info",
    "cpu_seconds",
]

#: Seeds of the datasets and campaigns (different seeds: disjoint paths, flights, pads).
SEEDS = {"train": 0, "calibration": 1, "test": 2, "pilot": 3, "paper": 10, "monte_carlo": 11}
#: Confidence parameter of the reported intervals (two-sided 95 %).
REPORT_DELTA = 0.05
#: Name prefix of the ablation's datasets and models.
ABLATION_PREFIX = "abl-"


class Stages:
    """Progress bars and timings of the pipeline's stages."""

    def __init__(self, show: bool, console: Console | None) -> None:
        self.progress = Progress(
            TextColumn("{task.description:<38}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=console or Console(stderr=True),
            disable=not show,
        )
        self.seconds: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str, total: int) -> Iterator[Callable[[int], None]]:
        task = self.progress.add_task(name, total=total)
        t0 = time.perf_counter()
        try:
            yield lambda k: self.progress.advance(task, k)
        finally:
            self.progress.update(task, completed=total)
            self.seconds[name] = round(time.perf_counter() - t0, 2)


@dataclass(frozen=True)
class Run:
    """What every step of one reproduction shares: settings, output directory, workers, stages."""

    cfg: ReproduceConfig
    sim: SimConfig
    out_dir: Path
    n_jobs: int | None
    backend: str
    stages: Stages

    @property
    def jobs(self) -> int:
        """Worker processes for collection, ablation and campaigns."""
        return 1 if self.backend == "sequential" else (self.n_jobs or default_jobs())

    @property
    def landing_buffer(self) -> int:
        """The buffer size of the landing runs (``[landing] buffer_size``: the paper's 1)."""
        return self.cfg.landing.buffer_size

    @property
    def extra_buffer(self) -> int | None:
        """The extra landing experiment's buffer size, or None when it is skipped."""
        sizes = self.cfg.sizes
        if not sizes.extra_landing_runs or sizes.extra_landing_buffer == self.landing_buffer:
            return None
        return sizes.extra_landing_buffer

    @property
    def ipc_buffers(self) -> list[int]:
        """Buffer sizes an IPC is learned at: 1 (Table I), the landing's, the extra one's."""
        extra = {self.extra_buffer} if self.extra_buffer is not None else set()
        return sorted({1, self.landing_buffer} | extra)


@dataclass(frozen=True)
class MachineInfo(Record):
    """Where a reproduction ran, and how busy the machine was (other work slows every stage down).

    ``summary.json``'s ``machine`` is :meth:`to_dict`.
    """

    cpu_count: int | None
    cores_available: int
    platform: str
    python: str
    torch: str
    load_average_start: tuple[float, float, float]
    load_average_end: tuple[float, float, float]


def machine_info(load_start: tuple[float, float, float]) -> MachineInfo:
    """This machine now, with the load average at the start of the run.

    Examples
    --------
    >>> machine_info((0.0, 0.0, 0.0)).to_dict()["load_average_start"]
    [0.0, 0.0, 0.0]
    """
    return MachineInfo(
        cpu_count=os.cpu_count(),
        cores_available=default_jobs(),
        platform=platform.platform(),
        python=platform.python_version(),
        torch=torch.__version__,
        load_average_start=load_start,
        load_average_end=os.getloadavg(),
    )


def cpu_seconds() -> float:
    """CPU time of this process and of its finished worker processes (the reusable pool is shut down)."""
    from joblib.externals.loky import get_reusable_executor

    get_reusable_executor().shutdown(wait=True)
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return round(own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime, 1)


def start_run(
    out: str | os.PathLike[str],
    cfg: ReproduceConfig,
    sim: SimConfig,
    n_jobs: int | None,
    backend: str,
    stages: Stages,
) -> Run:
    """Check and create the output directory (``data``, ``models``, ``certificates``, ``figures``)."""
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise InvalidInputError(f"--out {out_dir} exists and is not a directory; choose a directory")
    for sub in ("data", "models", "certificates", "figures"):
        (out_dir / sub).mkdir(parents=True, exist_ok=True)
    return Run(cfg, sim, out_dir, n_jobs, backend, stages)


@dataclass(frozen=True)
class CertificateRecord(Record):
    """A learned IPC's test certificate as the reproduction reports it, and where its files are.

    ``test`` and ``group_test`` are the library's results
    (:class:`ipcverify.certification.TestResult`, :class:`ipcverify.certification.GroupTest`).
    """

    status: str
    statement: str
    test: TestResult | None
    group_test: GroupTest | None
    files: str


def certify_ipc(model: IPCModel, test: PerceptionDataset, out_dir: Path) -> CertificateRecord:
    """Certify ``model`` on its held-out ``test`` set (also per flight).

    The certificate's files are written to ``out_dir``.
    """
    from ipcverify.certification import certify, write_certificate

    # the test samples come from a few dozen flights: also count violations per flight
    result = certify(model, test, group_column="flight")
    write_certificate(result, out_dir)
    cert = result.certificate
    return CertificateRecord(
        status=cert.status.name,
        statement=cert.statement,
        test=cert.test,
        group_test=cert.group_test,
        files=str(out_dir),
    )
