"""The three contracts' summaries and claims (``reproduction/contracts.py``), on small made-up runs."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.landing.runs import QueryRecord
from case_studies.quad_landing.reproduction.campaign import CampaignSummary
from case_studies.quad_landing.reproduction.contracts import (
    CONTRACTS,
    ContractSummary,
    contract_claims,
    hover_half_widths,
)
from case_studies.quad_landing.reproduction.table1 import Table1, Table1Row
from ipcverify.errors import InvalidInputError
from ipcverify.sets._box import Box

G_TAU = Box([-0.045, -0.045, 0.0], [0.045, 0.045, 0.04])


def _table(rates: list[int], n: int = 200) -> Table1:
    rows = tuple(
        Table1Row(
            buffer_size=b,
            n=n,
            violations=k,
            rate=k / n,
            upper=min(1.0, (k + 3) / n),
            interval=(max(0.0, (k - 3) / n), min(1.0, (k + 3) / n)),
            confidence=0.95,
            paper_rate=None,
            paths=None,
            paths_with_violations=None,
        )  # fmt: skip
        for b, k in enumerate(rates, start=1)
    )
    return Table1(rows)


def _campaign(safe: int, unsafe: int, aborted: int) -> CampaignSummary:
    return CampaignSummary(
        runs=safe + unsafe + aborted, safe=safe, unsafe=unsafe, aborted=aborted, confidence=0.95
    )


class _Run:
    """The part of a LandingRun that hover_half_widths reads."""

    def __init__(self, widths: list[tuple[float, float, float] | None]) -> None:
        self.queries = [
            QueryRecord(
                time=float(i),
                position=np.zeros(3),
                velocity=np.zeros(3),
                detected=w is not None,
                half_widths=None if w is None else np.asarray(w),
            )  # fmt: skip
            for i, w in enumerate(widths)
        ]


def test_hover_widths_skip_the_first_measurement_and_missed_detections():
    runs = [_Run([(0.5, 0.5, 0.5), (0.01, 0.02, 0.015), None]), _Run([(0.5, 0.5, 0.5), (0.03, 0.01, 0.03)])]
    w = hover_half_widths(runs, G_TAU)  # type: ignore[arg-type]
    assert w.n == 2 and w.limit == pytest.approx((0.045, 0.045, 0.02))
    assert w.median == pytest.approx((0.02, 0.015, 0.0225)) and w.fits == 0.5  # 3 cm > 2 cm does not fit


def test_claims_hold_only_where_the_counts_meet_the_targets():
    claims = contract_claims(_table([0, 1, 2, 6, 20]), _campaign(290, 0, 10), _campaign(9, 0, 1))
    assert claims["table1_buffer1_at_most_1pct"].holds and claims["table1_rates_rising"].holds
    assert claims["paper_runs_safe"].holds  # 9 of 10 is the target
    assert (
        claims["monte_carlo_safe"].holds and claims["monte_carlo_aborted"].holds
    )  # 96.7 % safe, 3.3 % aborted
    claims = contract_claims(_table([3, 1, 2, 6, 20]), _campaign(260, 0, 40), _campaign(8, 0, 2))
    assert not claims["table1_buffer1_at_most_1pct"].holds and not claims["table1_rates_rising"].holds
    assert not claims["paper_runs_safe"].holds and not claims["monte_carlo_safe"].holds
    assert not claims["monte_carlo_aborted"].holds  # 40 of 300 > 10 %
    unflown = contract_claims(_table([0, 1, 2, 3, 4]), None, None)
    assert unflown["paper_runs_safe"].detail == "not flown" and not unflown["monte_carlo_safe"].holds


def test_a_contract_without_a_guarantee_cannot_carry_a_certified_bound():
    from case_studies.quad_landing.reproduction.certified import certified_bound

    raw = CONTRACTS["paper_raw"]
    assert not raw.calibrated and CONTRACTS["paper_calibrated"].calibrated
    bound = certified_bound(0.002, 0.001, max_queries=8, queries_per_run=[2, 2])
    with pytest.raises(InvalidInputError, match="no guarantee"):
        ContractSummary(info=raw, n_parameters=1, table1=_table([0] * 5), monte_carlo=_campaign(1, 0, 0),
                        paper=_campaign(1, 0, 0), hover=None, certified=bound)  # fmt: skip
    with pytest.raises(InvalidInputError, match="not flown"):
        ContractSummary(
            info=raw, n_parameters=1, table1=_table([0] * 5), monte_carlo=None, paper=None, hover=None
        )
    c = ContractSummary(info=raw, n_parameters=1, table1=_table([0, 0, 1, 2, 3]), monte_carlo=None,
                        paper=None, hover=None, not_flown="not asked")  # fmt: skip
    d = c.to_dict()
    assert d["guarantee"].startswith("none") and d["landing"] is None and d["table1"]["3"] == 0.005
