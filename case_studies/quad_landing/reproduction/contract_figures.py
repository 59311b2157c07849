"""The three contracts in one figure: Table I, the landings, and their sets at the hover against ``G``.

Examples
--------
>>> from case_studies.quad_landing.reproduction.figures import figure_png
>>> figure_png(plot_contracts({}))[:4] == b"\\x89PNG"
True
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from case_studies.quad_landing.reproduction.campaign import CampaignSummary
from case_studies.quad_landing.reproduction.contracts import CONTRACTS, ContractSummary
from case_studies.quad_landing.reproduction.table1 import PAPER_TABLE1

__all__ = ["CONTRACT_COLORS", "plot_contracts"]

#: One colour per contract (and the paper's numbers in orange, as in the other figures).
CONTRACT_COLORS = {"paper_raw": "#9467bd", "paper_calibrated": "#8c564b", "default_calibrated": "#1f77b4"}
_AXES = ("x", "y", "z")


def _share(mc: CampaignSummary | None, outcome: str) -> float:
    """The share of a campaign's runs with ``outcome`` (0 if it was not flown)."""
    return 0.0 if mc is None or mc.runs == 0 else getattr(mc, outcome) / mc.runs


#: Plain numbers on log axes (2, 5, 10 rather than 2 x 10^0).
_PLAIN = FuncFormatter(lambda v, _: f"{v:g}")


def plot_contracts(
    contracts: Mapping[str, ContractSummary], baseline: CampaignSummary | None = None, floor: float = 1e-3
) -> Figure:
    """Table I per contract (left), landing outcomes with the baseline's (middle), hover half-widths (right).

    Rates of zero are drawn at the bottom of the log axis, whose tick reads 0 (the floor must lie
    below the smallest non-zero rate, 1 / n); a contract that was not flown has no bars.
    """
    fig = Figure(figsize=(13.5, 4.4))
    ax_t, ax_l, ax_h = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.1, 1.0, 1.1]})
    paper = sorted(PAPER_TABLE1.items())
    ax_t.plot([k for k, _ in paper], [p for _, p in paper], "s--", color="#ff7f0e", lw=1.6, label="paper")
    names = [n for n in CONTRACTS if n in contracts]
    for name in names:
        rows = contracts[name].table1.rows
        ks = [r.buffer_size for r in rows]
        lo = [max(r.interval[0], floor) for r in rows]
        hi = [max(r.interval[1], floor) for r in rows]
        ax_t.fill_between(ks, lo, hi, color=CONTRACT_COLORS[name], alpha=0.12)
        ax_t.plot(
            ks, [max(r.rate, floor) for r in rows], "o-", color=CONTRACT_COLORS[name], lw=1.6, label=name
        )
    ax_t.set_yscale("log")
    # the bottom tick is where rates of zero are drawn: labelled 0, not the floor's value
    ax_t.set_yticks([floor, 1e-2, 1e-1, 1.0])
    ax_t.yaxis.set_major_formatter(FuncFormatter(lambda v, _: "0" if v <= floor else f"{100 * v:g} %"))
    ax_t.set_ylim(floor * 0.8, 1.0)
    ax_t.set_xlabel("camera buffer size")
    ax_t.set_ylabel("Table I: truths outside the set")
    ax_t.set_title("Table I (bands: simultaneous 95 % intervals)", fontsize=10)
    ax_t.grid(alpha=0.3, which="both")
    ax_t.legend(fontsize=8)

    flown = [(n, contracts[n].monte_carlo) for n in names]
    if baseline is not None:
        flown.append(("baseline", baseline))
    x = np.arange(len(flown))
    bottom = np.zeros(len(flown))
    for outcome, color in (("safe", "#2ca02c"), ("unsafe", "#d62728"), ("aborted", "#bbbbbb")):
        share = np.array([_share(mc, outcome) for _, mc in flown])
        ax_l.bar(x, 100 * share, bottom=100 * bottom, color=color, label=outcome, width=0.6)
        bottom += share
    ax_l.set_xticks(x, [n.replace("_", "\n") for n, _ in flown], fontsize=8)
    ax_l.set_ylabel("Monte Carlo landings (%)")
    ax_l.set_ylim(0, 100)
    ax_l.set_title("landings at buffer size 1", fontsize=10)
    ax_l.legend(fontsize=8, loc="lower right")

    width = 0.8 / max(len(names), 1)
    limit = None
    for j, name in enumerate(names):
        hover = contracts[name].hover
        if hover is None or hover.median is None:
            continue
        limit = hover.limit
        pos = np.arange(3) + (j - (len(names) - 1) / 2) * width
        med, p90 = 100 * np.asarray(hover.median), 100 * np.asarray(hover.p90)
        ax_h.bar(pos, med, width=width, color=CONTRACT_COLORS[name], label=f"{name} (median; bar: 90 %)")
        ax_h.errorbar(pos, med, yerr=[np.zeros(3), p90 - med], fmt="none", ecolor="k", lw=0.8, capsize=2)
    if limit is not None:
        for i, v in enumerate(limit):
            ax_h.hlines(100 * v, i - 0.45, i + 0.45, colors="k", linestyles="--", lw=1.4)
        ax_h.plot([], [], "k--", label="largest half-width G allows")
    ax_h.set_xticks(range(3), [f"{a} (world)" for a in _AXES])
    ax_h.set_ylabel("half-width of the set (cm)")
    ax_h.set_yscale("log")
    ax_h.yaxis.set_major_formatter(_PLAIN)
    ax_h.yaxis.set_minor_formatter(_PLAIN)
    ax_h.set_title("sets at the hover (measurements after the first)", fontsize=10)
    ax_h.grid(alpha=0.3, axis="y", which="both")
    if limit is not None:
        ax_h.legend(fontsize=7)
    fig.tight_layout()
    return fig
