"""The reproduction's results as frozen dataclasses, and how they are written to ``summary.json``.

:func:`~case_studies.quad_landing.reproduction.pipeline.reproduce` returns a
:class:`ReproductionSummary`; ``summary.json`` is its :meth:`~ReproductionSummary.to_dict`
written by :func:`ipcverify.data.write_json` (the one JSON encoder: ``inf`` as ``"inf"``,
NaN as ``null``). The layout of ``summary.json`` is a published format: keys are added,
never renamed or removed.

The landing experiments' records (:class:`~.experiments.IpcSummary`,
:class:`~.experiments.ContractResults`, :class:`~.experiments.LandingExperiment`,
:class:`~.experiments.ControlExperiment`) are in :mod:`.experiments`.

* :class:`ReproductionSummary` — all of it, Table I (:class:`~.table1.Table1`), the ablation
  (:class:`~.variants.VariantStudy`), the camera timing and the claims (:class:`~.claims.Claim`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from case_studies.quad_landing.reproduction.claims import Claim
from case_studies.quad_landing.reproduction.config import ReproduceConfig
from case_studies.quad_landing.reproduction.contracts import ContractSummary
from case_studies.quad_landing.reproduction.experiments import (
    PAPER_LANDING,
    ControlExperiment,
    IpcSummary,
    LandingExperiment,
)
from case_studies.quad_landing.reproduction.run import MachineInfo
from case_studies.quad_landing.reproduction.table1 import PAPER_TABLE1, Table1
from case_studies.quad_landing.reproduction.timing_stats import CameraTimingSummary, Table1Protocol
from case_studies.quad_landing.reproduction.variants import VariantStudy

__all__ = [
    "SUMMARY_FORMAT",
    "SUMMARY_VERSION",
    "ReproductionSummary",
]

#: ``summary.json``'s ``format`` and ``version``.
SUMMARY_FORMAT = "quad-landing-reproduction"
SUMMARY_VERSION = 1


@dataclass(frozen=True, kw_only=True)
class ReproductionSummary:
    """Everything the reproduction found; :meth:`to_dict` is ``summary.json``.

    Attributes
    ----------
    quick : bool
        Whether the ``[quick]`` sizes were used.
    settings : ReproduceConfig
        The reproduction's settings.
    seeds : mapping of str to int
        Seeds of the datasets and campaigns.
    ipcs : mapping of int to IpcSummary
        The learned IPCs by buffer size.
    table1 : Table1
        Table I.
    landing : LandingExperiment
        The landing at the landing buffer size (the paper's 1).
    landing_buffer1 : ControlExperiment or None
        The buffer-1 Monte Carlo counts (the same runs as ``landing`` at buffer size 1).
    landing_buffer3 : LandingExperiment or None
        The extra landing experiment (buffer size 3, IPC learned there), None if skipped.
    ablation : VariantStudy
        Table I of every camera variant (error sources alone and removed).
    camera_timing : CameraTimingSummary
        The timing parameters, image ages and errors per buffer size.
    table1_protocol : Table1Protocol
        How Table I was tested.
    claims : mapping of str to Claim
        The acceptance claims of ``default_calibrated`` (:func:`~.claims.evaluate_claims`).
    contracts : mapping of str to ContractSummary
        The three contracts side by side, ``paper_raw``, ``paper_calibrated`` and
        ``default_calibrated`` (:mod:`.contracts`): each with Table I, its landings and the
        paper's claims.
    machine : MachineInfo
        Where it ran.
    jobs, backend
        How it ran: worker processes and the campaigns' joblib backend.
    stage_seconds, runtime_seconds, cpu_seconds
        How long it took: per stage and in total (wall clock), and the CPU time of this process
        and its worker processes (what the run costs whatever else the machine is doing).
    """

    quick: bool
    settings: ReproduceConfig
    seeds: Mapping[str, int]
    ipcs: Mapping[int, IpcSummary]
    table1: Table1
    landing: LandingExperiment
    landing_buffer1: ControlExperiment | None
    landing_buffer3: LandingExperiment | None
    ablation: VariantStudy
    camera_timing: CameraTimingSummary
    table1_protocol: Table1Protocol
    claims: Mapping[str, Claim]
    machine: MachineInfo
    jobs: int
    backend: str
    stage_seconds: Mapping[str, float]
    runtime_seconds: float
    cpu_seconds: float
    contracts: Mapping[str, ContractSummary]

    def to_dict(self) -> dict[str, Any]:
        """The content of ``summary.json`` (every key it has always had)."""
        return {
            "format": SUMMARY_FORMAT,
            "version": SUMMARY_VERSION,
            "quick": self.quick,
            "settings": self.settings.as_dict(),
            "seeds": dict(self.seeds),
            "paper": {"table1": PAPER_TABLE1, "landing": PAPER_LANDING},
            "ipc": {f"k{k}": info.to_dict() for k, info in self.ipcs.items()},
            "table1": self.table1.to_dict(),
            "table1_rising": self.table1.rising().to_dict(),
            "landing": self.landing.to_dict(),
            "landing_buffer1": None if self.landing_buffer1 is None else self.landing_buffer1.to_dict(),
            "landing_buffer3": None if self.landing_buffer3 is None else self.landing_buffer3.to_dict(),
            "ablation": self.ablation.to_dict(),
            "camera_timing": self.camera_timing.to_dict(),
            "table1_protocol": self.table1_protocol.to_dict(),
            "machine": self.machine.to_dict(),
            "jobs": self.jobs,
            "backend": self.backend,
            "claims": {name: claim.to_dict() for name, claim in self.claims.items()},
            "contracts": {name: c.to_dict() for name, c in self.contracts.items()},
            "stage_seconds": dict(self.stage_seconds),
            "runtime_seconds": self.runtime_seconds,
            "cpu_seconds": self.cpu_seconds,
        }
