"""The reproduction's three contracts side by side, and which of the paper's claims each reproduces.

* ``paper_raw`` — the paper's IPC as trained (:mod:`.paper_ipc`), uncalibrated, measured and
  flown as the paper did: **no guarantee**;
* ``paper_calibrated`` — the same network, PAC-calibrated (``[paper] epsilon, delta``);
* ``default_calibrated`` — ipcverify's default recipe (``[ipc]``), PAC-calibrated.

Each gets Table I at every buffer size (the pilot test flights, exact intervals), the landing
at the landing buffer size (paper-style and Monte Carlo runs, safe / unsafe / aborted), the
certified bound beside the empirical rate where a certificate exists, and the size of its sets
at the hover against ``G`` (:func:`hover_half_widths`): what decides whether it can land.
:func:`contract_claims` reads the paper's claims off them.

Examples
--------
>>> CONTRACTS["paper_raw"].guarantee
'none: the network as trained, uncalibrated (the paper flew it so)'
>>> [c.name for c in CONTRACTS.values()]
['paper_raw', 'paper_calibrated', 'default_calibrated']
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from case_studies.quad_landing.landing.runs import LandingRun
from case_studies.quad_landing.reproduction.campaign import CampaignSummary
from case_studies.quad_landing.reproduction.certified import CertifiedBound, EmpiricalVsCertified
from case_studies.quad_landing.reproduction.claims import Claim, table1_claims
from case_studies.quad_landing.reproduction.run import CertificateRecord
from case_studies.quad_landing.reproduction.table1 import Table1
from ipcverify.calibration._protocol import CalibrationSummary
from ipcverify.errors import InvalidInputError
from ipcverify.sets import Box

__all__ = [
    "ContractInfo",
    "CONTRACTS",
    "LANDING_TARGETS",
    "HoverWidths",
    "ContractSummary",
    "hover_half_widths",
    "contract_claims",
]


@dataclass(frozen=True)
class ContractInfo:
    """A contract's name (``summary.json`` key), its label and the guarantee its sets carry."""

    name: str
    label: str
    recipe: str
    guarantee: str

    @property
    def calibrated(self) -> bool:
        """Whether the sets carry a calibration certificate."""
        return not self.guarantee.startswith("none")


#: The three contracts, in the order the report shows them.
CONTRACTS: dict[str, ContractInfo] = {
    c.name: c
    for c in (
        ContractInfo(
            "paper_raw",
            "the paper's IPC, as trained (no guarantee)",
            "paper",
            "none: the network as trained, uncalibrated (the paper flew it so)",
        ),
        ContractInfo(
            "paper_calibrated",
            "the paper's IPC, PAC-calibrated",
            "paper",
            "PAC calibration of the paper's network on held-out data",
        ),
        ContractInfo(
            "default_calibrated",
            "ipcverify's default, PAC-calibrated",
            "tight",
            "PAC calibration of ipcverify's default recipe on held-out data",
        ),
    )
}

#: The landing targets every contract is judged by (the issue's, after the paper's 10 of 10).
LANDING_TARGETS = {"paper_runs_safe": 0.9, "monte_carlo_safe": 0.95, "monte_carlo_aborted": 0.10}


@dataclass(frozen=True, kw_only=True)
class HoverWidths:
    """Half-widths (x, y, z in the world frame) of a contract's sets where the landing hovers.

    The landing's later measurements (after the first, which is taken in transit) are taken
    hovering above the pad; a set is accepted only if it fits ``G`` shrunk by the tracking
    tolerance, whose half-widths are :attr:`limit`.

    Attributes
    ----------
    n : int
        Hover measurements (with a detection and a set).
    median, p90 : tuple of float
        Median and 90th percentile of each axis's half-width (m).
    limit : tuple of float
        ``G_tau``'s half-widths (m): a set wider on any axis cannot be accepted.
    fits : float or None
        Share of the hover sets no wider than the limit on every axis.
    """

    n: int
    median: tuple[float, float, float] | None
    p90: tuple[float, float, float] | None
    limit: tuple[float, float, float]
    fits: float | None

    def to_dict(self) -> dict[str, Any]:
        """Plain data (``summary.json``: ``contracts.<name>.hover_half_widths``)."""
        return {
            "n": self.n,
            "median": None if self.median is None else list(self.median),
            "p90": None if self.p90 is None else list(self.p90),
            "limit": list(self.limit),
            "fits": self.fits,
        }


def hover_half_widths(runs: Sequence[LandingRun], target: Box) -> HoverWidths:
    """The half-widths of the sets of every measurement after a run's first, against ``target``.

    Parameters
    ----------
    runs : sequence of LandingRun
        A contract's landing runs.
    target : Box
        ``G_tau``, the box a set must fit (:func:`.state_machine.decision_target`).

    Examples
    --------
    >>> from case_studies.quad_landing.landing.state_machine import decision_target
    >>> w = hover_half_widths([], decision_target(0.005, Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])))
    >>> w.n, [round(v, 3) for v in w.limit]
    (0, [0.045, 0.045, 0.02])
    """
    limit = tuple(float(v) for v in (target.upper - target.lower) / 2.0)
    widths = [
        np.asarray(q.half_widths, dtype=np.float64)
        for r in runs
        for q in r.queries[1:]
        if q.detected and q.half_widths is not None
    ]
    if not widths:
        return HoverWidths(n=0, median=None, p90=None, limit=limit, fits=None)  # type: ignore[arg-type]
    w = np.vstack(widths)
    lim = np.asarray(limit)
    return HoverWidths(
        n=len(w),
        median=tuple(float(v) for v in np.median(w, axis=0)),  # type: ignore[arg-type]
        p90=tuple(float(v) for v in np.quantile(w, 0.9, axis=0)),  # type: ignore[arg-type]
        limit=limit,  # type: ignore[arg-type]
        fits=float(np.mean(np.all(w <= lim, axis=1))),
    )


@dataclass(frozen=True, kw_only=True)
class ContractSummary:
    """One contract's Table I, landings and certificate, as ``summary.json``'s ``contracts.<name>``.

    Attributes
    ----------
    info : ContractInfo
        Name, label, recipe, guarantee.
    n_parameters : int
        The network's trainable parameters ``p``.
    table1 : Table1
        Table I on the pilot test flights.
    monte_carlo, paper : CampaignSummary or None
        The landing's Monte Carlo and paper-style runs (None if the contract was not flown).
    hover : HoverWidths or None
        Its sets where the landing hovers.
    certified, empirical_vs_certified : optional
        The certified bound on unsafe landings beside the empirical rate (calibrated only).
    selection : mapping or None
        How the paper's unstated settings were chosen (:class:`ipcverify.training.HingeSelection`).
    calibration : CalibrationSummary or None
        The calibration summary (calibrated only).
    certificate : CertificateRecord or None
        :func:`~.run.certify_ipc` on the held-out test set (calibrated only).
    claims : mapping of str to Claim
        :func:`contract_claims`.
    not_flown : str or None
        Why the contract was not flown (e.g. ``[paper] fly_uncalibrated = false``).
    """

    info: ContractInfo
    n_parameters: int
    table1: Table1
    monte_carlo: CampaignSummary | None
    paper: CampaignSummary | None
    hover: HoverWidths | None
    certified: CertifiedBound | None = None
    empirical_vs_certified: EmpiricalVsCertified | None = None
    selection: Mapping[str, Any] | None = None
    calibration: CalibrationSummary | None = None
    certificate: CertificateRecord | None = None
    claims: Mapping[str, Claim] = field(default_factory=dict)
    not_flown: str | None = None

    def __post_init__(self) -> None:
        if (self.monte_carlo is None) != (self.paper is None):
            raise InvalidInputError("give both landing campaigns of a contract, or neither")
        if self.monte_carlo is None and not self.not_flown:
            raise InvalidInputError("a contract that was not flown needs the reason (not_flown)")
        if not self.info.calibrated and self.certified is not None:
            raise InvalidInputError(
                f"{self.info.name} carries no guarantee: it cannot have a certified bound"
            )

    def to_dict(self) -> dict[str, Any]:
        """``table1`` (rate per buffer size), ``landing`` (Monte Carlo counts) and the rest."""
        return {
            "label": self.info.label,
            "recipe": self.info.recipe,
            "guarantee": self.info.guarantee,
            "calibrated": self.info.calibrated,
            "n_parameters": self.n_parameters,
            "table1": {str(r.buffer_size): r.rate for r in self.table1.rows},
            "table1_detail": self.table1.to_dict(),
            "table1_rising": self.table1.rising().to_dict(),
            "landing": None if self.monte_carlo is None else self.monte_carlo.to_dict(),
            "landing_paper_runs": None if self.paper is None else self.paper.to_dict(),
            "not_flown": self.not_flown,
            "hover_half_widths": None if self.hover is None else self.hover.to_dict(),
            "certified": None if self.certified is None else self.certified.to_dict(),
            "empirical_vs_certified": (
                None if self.empirical_vs_certified is None else self.empirical_vs_certified.to_dict()
            ),
            "selection": None if self.selection is None else dict(self.selection),
            "calibration": None if self.calibration is None else self.calibration.to_dict(),
            "certificate": None if self.certificate is None else self.certificate.to_dict(),
            "claims": {k: c.to_dict() for k, c in self.claims.items()},
        }


def _share_claim(
    k: int, n: int, at_least: float | None, at_most: float | None, what: str, statement: str
) -> Claim:
    if n == 0:
        return Claim(holds=False, supported=False, detail="no runs", statement=statement)
    rate = k / n
    holds = (at_least is None or rate >= at_least) and (at_most is None or rate <= at_most)
    return Claim(holds=holds, supported=holds, detail=f"{k}/{n} {what} ({rate:.1%})", statement=statement)


def contract_claims(
    table: Table1,
    monte_carlo: CampaignSummary | None,
    paper: CampaignSummary | None,
    empirical_vs_certified: EmpiricalVsCertified | None = None,
) -> dict[str, Claim]:
    """The paper's claims for one contract: Table I's, the landing targets, the certified bound.

    ``supported`` of the landing claims is the point statement (the targets are shares of
    runs, not rates to be estimated); Table I's carry their intervals (:mod:`.claims`).

    Examples
    --------
    >>> from case_studies.quad_landing.reproduction.table1 import Table1Row
    >>> row = Table1Row(buffer_size=1, n=300, violations=0, rate=0.0, upper=0.01, interval=(0.0, 0.012),
    ...                 confidence=0.95, paper_rate=0.0019, paths=None, paths_with_violations=None)
    >>> claims = contract_claims(Table1((row,)), None, None)
    >>> claims["table1_buffer1_at_most_1pct"].holds, claims["paper_runs_safe"].detail
    (True, 'not flown')
    """
    out = dict(table1_claims(table))
    t = LANDING_TARGETS
    if paper is None or monte_carlo is None:
        for key, statement in (
            ("paper_runs_safe", f"at least {t['paper_runs_safe']:.0%} of the paper-style runs safe"),
            ("monte_carlo_safe", f"at least {t['monte_carlo_safe']:.0%} of the Monte Carlo runs safe"),
            (
                "monte_carlo_aborted",
                f"at most {t['monte_carlo_aborted']:.0%} of the Monte Carlo runs aborted",
            ),
        ):
            out[key] = Claim(holds=False, supported=False, detail="not flown", statement=statement)
        return out
    out["paper_runs_safe"] = _share_claim(
        paper.safe, paper.runs, t["paper_runs_safe"], None, "safe",
        f"at least {t['paper_runs_safe']:.0%} of the paper-style runs safe (paper: 10 of 10)",
    )  # fmt: skip
    out["monte_carlo_safe"] = _share_claim(
        monte_carlo.safe, monte_carlo.runs, t["monte_carlo_safe"], None, "safe",
        f"at least {t['monte_carlo_safe']:.0%} of the Monte Carlo runs safe",
    )  # fmt: skip
    out["monte_carlo_aborted"] = _share_claim(
        monte_carlo.aborted, monte_carlo.runs, None, t["monte_carlo_aborted"], "aborted",
        f"at most {t['monte_carlo_aborted']:.0%} of the Monte Carlo runs aborted",
    )  # fmt: skip
    if empirical_vs_certified is not None:
        ev = empirical_vs_certified
        out["certified_bound_at_least_empirical"] = Claim(
            holds=bool(ev.bound_at_least_rate),
            supported=bool(ev.consistent),
            detail=(
                f"certified {ev.certified_union:.4g} (refined {ev.certified_refined:.4g}) "
                f"vs {ev.unsafe}/{ev.runs} unsafe"
            ),
            statement="the certified bound on unsafe landings is at least the observed rate",
        )
    return out
