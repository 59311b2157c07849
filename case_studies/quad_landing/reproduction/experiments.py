"""The landing experiments' records: one IPC, one contract's landings, both contracts at one buffer size.

* :class:`IpcSummary` — one learned IPC: its calibration and its test certificate.
* :class:`ContractResults` — one contract's landings: the Monte Carlo campaign and the
  paper-style runs (:class:`~.campaign.CampaignSummary` each, and the runs), with the
  certified bound for the IPC (:class:`~.certified.CertifiedBound`).
* :class:`LandingExperiment` — both contracts at one buffer size, the closed loop's own
  violations and the coverage check: ``landing`` is the paper's buffer size 1,
  ``landing_buffer3`` the extra experiment at buffer size 3 (None when skipped).
* :class:`ControlExperiment` — ``landing_buffer1``: the Monte Carlo counts at buffer size 1
  (since the landing runs at buffer size 1, the same runs as ``landing``).

The claims (:mod:`.claims`) are read from them, and the reproduction's summary
(:mod:`.results`) holds them; ``to_dict`` gives each one's part of ``summary.json``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from case_studies.quad_landing.landing.runs import LandingRun
from case_studies.quad_landing.reproduction.campaign import CampaignSummary
from case_studies.quad_landing.reproduction.certified import (
    CertifiedBound,
    ClosedLoopViolations,
    EmpiricalVsCertified,
)
from case_studies.quad_landing.reproduction.coverage import CoverageCheck
from case_studies.quad_landing.reproduction.learn import FlightLevelCheck
from case_studies.quad_landing.reproduction.record import Record
from case_studies.quad_landing.reproduction.run import CertificateRecord
from ipcverify.calibration._protocol import CalibrationSummary
from ipcverify.errors import InvalidInputError

__all__ = [
    "PAPER_LANDING",
    "IpcSummary",
    "ContractResults",
    "LandingExperiment",
    "ControlExperiment",
]

#: The paper's landing experiment: 10 pads; the IPC landed safely in all, the baseline failed 9.
PAPER_LANDING = {"runs": 10, "ipc_safe": 10, "baseline_unsafe": 9}


@dataclass(frozen=True, kw_only=True)
class IpcSummary(Record):
    """One learned IPC: buffer size, calibration, test certificate, size and flight-level check.

    ``calibration`` is the library's :class:`~ipcverify.calibration.CalibrationSummary`,
    ``certificate`` the test certificate (:func:`~.run.certify_ipc`), ``flight_level``
    :func:`~.learn.flight_level_check` (the same network calibrated with the calibration
    flights as the exchangeable units).
    """

    buffer_size: int
    calibration: CalibrationSummary
    certificate: CertificateRecord
    n_parameters: int
    flight_level: FlightLevelCheck | None = None


def _run_row(run: LandingRun) -> dict[str, Any]:
    """One Monte Carlo run in ``runs_detail`` (the trajectory and queries left out)."""
    return {
        "index": run.scenario.index,
        "outcome": run.outcome.value,
        "n_queries": run.n_queries,
        "offset": None if run.offset is None else np.asarray(run.offset).tolist(),
        "reason": run.reason,
    }


@dataclass(frozen=True, kw_only=True)
class ContractResults:
    """One contract's landings at the landing buffer size.

    Attributes
    ----------
    monte_carlo : CampaignSummary
        The Monte Carlo campaign, flown as ``runs``.
    paper : CampaignSummary
        The paper-style runs, flown as ``paper_runs``.
    certified, empirical_vs_certified : optional
        The certified bound on the unsafe rate and the campaign beside it (the IPC only).
    """

    monte_carlo: CampaignSummary
    runs: tuple[LandingRun, ...]
    paper: CampaignSummary
    paper_runs: tuple[LandingRun, ...]
    certified: CertifiedBound | None = None
    empirical_vs_certified: EmpiricalVsCertified | None = None

    def __post_init__(self) -> None:
        if (self.monte_carlo.runs, self.paper.runs) != (len(self.runs), len(self.paper_runs)):
            raise InvalidInputError("a contract's summaries must count the runs they come with")
        if (self.certified is None) != (self.empirical_vs_certified is None):
            raise InvalidInputError("give the certified bound and the empirical comparison together")

    def to_dict(self) -> dict[str, Any]:
        """``summary.json``'s ``landing.ipc`` / ``landing.baseline``."""
        out: dict[str, Any] = self.monte_carlo.to_dict()
        out["paper_runs"] = {
            **self.paper.to_dict(),
            "runs_detail": [r.to_dict(trajectory=True) for r in self.paper_runs],
        }
        out["runs_detail"] = [_run_row(r) for r in self.runs]
        if self.certified is not None and self.empirical_vs_certified is not None:
            out["certified_unsafe_bound"] = self.certified.union_bound
            out["certified"] = self.certified.to_dict()
            out["empirical_vs_certified"] = self.empirical_vs_certified.to_dict()
        return out


@dataclass(frozen=True, kw_only=True)
class LandingExperiment:
    """The landing at the landing buffer size: both contracts on the same scenarios.

    ``closed_loop`` is :func:`~.certified.closed_loop_violations`, ``coverage``
    :func:`~.coverage.coverage_check` (``summary.json`` leaves its raw distances out).
    """

    buffer_size: int
    tracking_tolerance: float
    max_measurements: int
    ipc: ContractResults
    baseline: ContractResults
    closed_loop: ClosedLoopViolations
    coverage: CoverageCheck

    def __post_init__(self) -> None:
        if self.ipc.certified is None:
            raise InvalidInputError("the IPC's landing results need its certified bound")

    @property
    def shift_detected(self) -> bool | None:
        """Whether the coverage check flagged a shift (None without closed-loop queries)."""
        return self.coverage.shift_detected

    def to_dict(self) -> dict[str, Any]:
        """``summary.json``'s ``landing``."""
        return {
            "buffer_size": self.buffer_size,
            "tracking_tolerance": self.tracking_tolerance,
            "max_measurements": self.max_measurements,
            "ipc": self.ipc.to_dict(),
            "baseline": self.baseline.to_dict(),
            "closed_loop": self.closed_loop.to_dict(),
            "coverage": self.coverage.to_dict(distances=False),
        }


@dataclass(frozen=True, kw_only=True)
class ControlExperiment(Record):
    """The Monte Carlo counts of the landing at ``buffer_size`` (1), IPC and baseline."""

    buffer_size: int
    ipc: CampaignSummary
    baseline: CampaignSummary
