"""The issue's acceptance claims, each with what the numbers show and what they establish.

Every :class:`Claim` has a ``statement`` in words (what the report prints), ``holds`` (the
point statement on the observed counts), ``supported`` (what the sample sizes can establish
at the report's confidence, Clopper--Pearson) and ``detail`` (the numbers behind it).
:func:`evaluate_claims` reads them off Table I and the landing experiment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from case_studies.quad_landing.reproduction.table1 import Table1

if TYPE_CHECKING:
    from case_studies.quad_landing.reproduction.experiments import LandingExperiment

__all__ = ["Claim", "evaluate_claims", "table1_claims"]


@dataclass(frozen=True)
class Claim:
    """One acceptance claim: ``holds`` on the point counts, ``supported`` by the statistics.

    Examples
    --------
    >>> Claim(holds=True, supported=False, detail="30/30 safe", statement="IPC: all safe").to_dict()
    {'holds': True, 'supported': False, 'detail': '30/30 safe', 'statement': 'IPC: all safe'}
    """

    holds: bool
    supported: bool
    detail: str
    statement: str = ""

    def to_dict(self) -> dict[str, bool | str]:
        """``summary.json``'s ``claims.<name>``."""
        return {"holds": self.holds, "supported": self.supported, "detail": self.detail,
                "statement": self.statement}  # fmt: skip


def _rate_claim(table: Table1, b: int, low: float, high: float, statement: str) -> Claim:
    """``low <= rate(b) <= high`` on the point; supported if the row's CP interval lies inside."""
    if b not in table.buffers:
        return Claim(holds=False, supported=False, detail=f"Table I has no row for buffer size {b}",
                     statement=statement)  # fmt: skip
    r = table.row(b)
    lo, hi = r.interval
    return Claim(
        holds=low <= r.rate <= high,
        supported=low <= lo and hi <= high,
        detail=(
            f"{r.violations}/{r.n} = {r.rate:.2%}, two-sided CP interval [{lo:.2%}, {hi:.2%}] "
            f"(simultaneous {r.confidence:.0%} over the rows)"
        ),
        statement=statement,
    )


def table1_claims(table: Table1) -> dict[str, Claim]:
    """Table I's claims: buffer 1 at most 1 %, rising, buffer 2 at most 10 %, buffer 5 in [2, 30] %."""
    b1 = table.row(1)
    rising = table.rising()
    return {
        "table1_buffer1_at_most_1pct": Claim(
            holds=b1.rate <= 0.01,
            supported=b1.upper <= 0.01,
            detail=f"rate {b1.rate:.4%}, one-sided CP upper bound {b1.upper:.4%} (n = {b1.n})",
            statement="Table I, buffer 1: at most 1 %",
        ),
        "table1_rates_rising": Claim(
            holds=rising.strict,
            supported=rising.separated,
            detail="point rates strictly increasing; 'supported' = simultaneous CP intervals do not overlap",
            statement="Table I rises with the buffer size",
        ),
        "table1_buffer2_at_most_10pct": _rate_claim(table, 2, 0.0, 0.10, "Table I, buffer 2: at most 10 %"),
        "table1_buffer5_between_2_and_30pct": _rate_claim(
            table, 5, 0.02, 0.30, "Table I, buffer 5: between 2 % and 30 %"
        ),
    }


def _ipc_claims(landing: LandingExperiment) -> dict[str, Claim]:
    mc, paper = landing.ipc.monte_carlo, landing.ipc.paper
    n, lo_safe = mc.runs, mc.safe_lower
    established = lo_safe is not None and lo_safe >= 0.99
    note = "" if established else f" ({n} runs cannot establish >= 99 % unless (nearly) all are safe)"
    up = mc.unsafe_upper
    return {
        "ipc_safe_99pct_monte_carlo": Claim(
            holds=mc.safe >= 0.99 * n,
            supported=established,
            detail=(
                f"{mc.safe}/{n} safe, {mc.unsafe} unsafe, {mc.aborted} aborted; one-sided 95 % "
                f"lower bound of the safe rate {_num(lo_safe, '.4f')}" + note
            ),
            statement=f"Landing at buffer {landing.buffer_size}, IPC: at least 99 % of Monte Carlo runs safe",
        ),
        "ipc_unsafe_at_most_1pct_monte_carlo": Claim(
            holds=mc.unsafe <= 0.01 * n,
            supported=up is not None and up <= 0.01,
            detail=f"{mc.unsafe}/{n} unsafe; one-sided 95 % CP upper bound {_num(up, '.4f')}",
            statement=f"Landing at buffer {landing.buffer_size}, IPC: at most 1 % of Monte Carlo runs unsafe",
        ),
        "ipc_safe_all_paper_runs": Claim(
            holds=paper.safe == paper.runs,
            supported=paper.safe == paper.runs,
            detail=f"{paper.safe}/{paper.runs} safe ({paper.unsafe} unsafe, {paper.aborted} aborted)",
            statement=f"Landing at buffer {landing.buffer_size}, IPC: every paper-style run safe",
        ),
    }


def _baseline_claim(landing: LandingExperiment) -> Claim:
    base, paper = landing.baseline.monte_carlo, landing.baseline.paper
    lower = base.unsafe_lower
    lo, hi = base.unsafe_interval or (math.nan, math.nan)
    return Claim(
        holds=base.unsafe > 0.5 * base.runs,
        supported=lower is not None and lower > 0.5,
        detail=(
            f"{base.unsafe}/{base.runs} unsafe, one-sided 95 % lower bound {_num(lower, '.3f')}, "
            f"two-sided interval [{lo:.3f}, {hi:.3f}]; paper runs: {paper.unsafe}/"
            f"{paper.runs} unsafe (paper: 9/10)"
        ),
        statement=f"Landing at buffer {landing.buffer_size}, baseline: unsafe in most Monte Carlo runs",
    )


def _certified_claim(landing: LandingExperiment) -> Claim:
    bound, ev = landing.ipc.certified, landing.ipc.empirical_vs_certified
    assert bound is not None and ev is not None  # LandingExperiment requires them
    rate = math.nan if ev.unsafe_rate is None else ev.unsafe_rate
    return Claim(
        holds=bool(ev.bound_at_least_rate),
        supported=bool(ev.consistent),
        detail=(
            f"certified {bound.union_bound:.4g} (refined {ev.certified_refined:.4g}) vs empirical "
            f"{rate:.4g} ({ev.unsafe}/{ev.runs}); 'supported' = the CP lower bound of the unsafe rate "
            "does not exceed the refined bound"
        ),
        statement="The certified bound on unsafe landings is at least the observed rate",
    )


def _num(value: float | None, spec: str) -> str:
    return "n/a" if value is None else format(value, spec)


def evaluate_claims(table: Table1, landing: LandingExperiment) -> dict[str, Claim]:
    """The acceptance claims of the reproduction, in the order of ``summary.json``.

    Parameters
    ----------
    table : Table1
        Table I (needs the buffer-1 row).
    landing : LandingExperiment
        The landing at the landing buffer size, with the IPC's certified bound.

    Returns
    -------
    dict of str to Claim
        ``table1_buffer1_at_most_1pct``, ``table1_rates_rising``, ``table1_buffer2_at_most_10pct``,
        ``table1_buffer5_between_2_and_30pct``, ``ipc_safe_99pct_monte_carlo``,
        ``ipc_unsafe_at_most_1pct_monte_carlo``, ``ipc_safe_all_paper_runs``,
        ``baseline_unsafe_in_most_runs``, ``certified_bound_at_least_empirical``.
    """
    return {
        **table1_claims(table),
        **_ipc_claims(landing),
        "baseline_unsafe_in_most_runs": _baseline_claim(landing),
        "certified_bound_at_least_empirical": _certified_claim(landing),
    }
