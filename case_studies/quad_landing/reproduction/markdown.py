"""The results of a reproduction as Markdown tables, read from its ``summary.json``.

The numbers in ``README.md`` and ``docs/reproduce_results.md`` are pasted from
``python -m case_studies.quad_landing summarize OUT`` after a real run, never typed:
:func:`results_markdown` formats Table I beside the paper's, the ablation, the image ages,
the landing experiments and the stage timings.

Examples
--------
>>> rows = {"1": {"n": 300, "violations": 3, "rate": 0.01, "interval": [0.001, 0.036]}}
>>> print(table1_markdown({"table1": rows}).splitlines()[2])
| this reproduction | 1.00 % (3/300; [0.10, 3.60] %) |
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = [
    "table1_markdown",
    "ablation_markdown",
    "landing_markdown",
    "claim_markdown",
    "unsafe_cell",
    "bound_words",
    "contracts_markdown",
    "results_markdown",
]

#: The paper's Table I (percent), for the row beside ours.
_PAPER = {"1": 0.19, "2": 0.93, "3": 2.05, "4": 4.07, "5": 11.05}


def _pct(v: float) -> str:
    return f"{100 * v:.2f} %"


def _cell(row: Mapping[str, Any]) -> str:
    """``rate (k/n; [lo, hi] %)`` of one Table I row."""
    lo, hi = row["interval"]
    return f"{_pct(row['rate'])} ({row['violations']}/{row['n']}; [{100 * lo:.2f}, {100 * hi:.2f}] %)"


def table1_markdown(summary: Mapping[str, Any]) -> str:
    """Table I with exact intervals, and the paper's row."""
    rows = summary["table1"]
    keys = sorted(rows, key=int)
    cells = [_cell(rows[k]) for k in keys]
    lines = ["| buffer size | " + " | ".join(keys) + " |", "|---|" + "---|" * len(keys)]
    lines.append("| this reproduction | " + " | ".join(cells) + " |")
    lines.append("| paper | " + " | ".join(f"{_PAPER[k]:.2f} %" if k in _PAPER else "—" for k in keys) + " |")
    return "\n".join(lines)


def ablation_markdown(summary: Mapping[str, Any]) -> str:
    """Every configuration's Table I (rate and count per buffer size) and median age at each."""
    rows = summary["ablation"]["rows"]
    keys = sorted(next(iter(rows.values()))["table1"], key=int)
    head = "| configuration | " + " | ".join(f"b = {k}" for k in keys) + " | median age (ms), b = 1 … 5 |"
    lines = [head, "|---|" + "---|" * (len(keys) + 1)]
    order = {"reference": 0, "alone": 1, "removed": 2}
    for r in sorted(rows.values(), key=lambda r: order.get(r["group"], 3)):
        t = r["table1"]
        cells = [f"{100 * t[k]['rate']:.1f} % ({t[k]['violations']}/{t[k]['n']})" for k in keys]
        ages = " / ".join(f"{r['median_age_ms'][k]:.0f}" for k in keys)
        lines.append(f"| {r['label']} | " + " | ".join(cells) + f" | {ages} |")
    lines.append("| paper | " + " | ".join(f"{_PAPER[k]:.2f} %" for k in keys) + " | |")
    return "\n".join(lines)


def _side(s: Mapping[str, Any]) -> str:
    iv = s.get("unsafe_interval")
    ci = "—" if not iv else f"[{100 * iv[0]:.1f}, {100 * iv[1]:.1f}] %"
    rate = "—" if s.get("unsafe_rate") is None else _pct(s["unsafe_rate"])
    q = "—" if s.get("mean_queries") is None else f"{s['mean_queries']:.2f}"
    return f"{s['runs']} | {s['safe']} | {unsafe_cell(s)} | {s['aborted']} | {rate} | {ci} | {q}"


def unsafe_cell(s: Mapping[str, Any]) -> str:
    """The unsafe count, with how many of those runs flew into the pad.

    Examples
    --------
    >>> unsafe_cell({"unsafe": 9, "unsafe_into_pad": 6}), unsafe_cell({"unsafe": 2})
    ('9 (6 into the pad)', '2')
    """
    pad = int(s.get("unsafe_into_pad", 0))
    return f"{s['unsafe']} ({pad} into the pad)" if pad else f"{s['unsafe']}"


def landing_markdown(landing: Mapping[str, Any]) -> str:
    """One landing experiment: paper-style and Monte Carlo runs of both contracts."""
    ipc, base = landing["ipc"], landing["baseline"]
    lines = [
        "| | runs | safe | unsafe | aborted | unsafe rate | 95 % CP | queries / run |",
        "|---|---|---|---|---|---|---|---|",
        f"| IPC, paper-style | {_side(ipc['paper_runs'])} |",
        f"| baseline, paper-style | {_side(base['paper_runs'])} |",
        f"| IPC, Monte Carlo | {_side(ipc)} |",
        f"| baseline, Monte Carlo | {_side(base)} |",
    ]
    return "\n".join(lines)


def claim_markdown(claim: Mapping[str, Any]) -> str:
    """One acceptance claim in words: whether it holds and whether the sample sizes support it.

    Examples
    --------
    >>> claim_markdown({"statement": "Table I, buffer 1: at most 1 %", "holds": True,
    ...                 "supported": False, "detail": "3/300"})
    'Table I, buffer 1: at most 1 % — **holds**, not established at these sizes (3/300)'
    """
    if not claim["holds"]:
        return f"{claim['statement']} — **does not hold** ({claim['detail']})"
    support = "established by the intervals" if claim["supported"] else "not established at these sizes"
    return f"{claim['statement']} — **holds**, {support} ({claim['detail']})"


def bound_words(bound: Mapping[str, Any]) -> str:
    """The certified bound on unsafe landings, in words.

    Examples
    --------
    >>> b = {"union_bound": 0.0798, "max_queries": 8, "epsilon": 0.009976, "refined_bound": 0.0791}
    >>> bound_words(b).split(";")[0]
    'P(unsafe) ≤ 7.98 % (M = 8 measurements × ε = 0.009976'
    """
    return (
        f"P(unsafe) ≤ {100 * bound['union_bound']:.2f} % (M = {bound['max_queries']} measurements × "
        f"ε = {bound['epsilon']:.4g}; refined with the measured number of measurements: "
        f"{100 * bound['refined_bound']:.2f} %)"
    )


def contracts_markdown(summary: Mapping[str, Any]) -> str:
    """The three contracts side by side: Table I, landings, hover half-widths, and the paper's claims.

    Examples
    --------
    >>> c = {"table1": {"1": 0.0}, "landing": {"runs": 30, "safe": 30, "unsafe": 0, "aborted": 0},
    ...      "landing_paper_runs": {"runs": 10, "safe": 10, "unsafe": 0, "aborted": 0},
    ...      "hover_half_widths": None, "claims": {}}
    >>> contracts_markdown({"contracts": {"paper_raw": c}}).splitlines()[2]
    '| paper_raw | 0.00 % | 10 / 0 / 0 | 30 / 0 / 0 of 30 | — |'
    """
    contracts = summary.get("contracts") or {}
    if not contracts:
        return ""
    buffers = sorted(next(iter(contracts.values()))["table1"], key=int)
    head = (
        "| contract | " + " | ".join(f"Table I, b = {b}" for b in buffers)
        + " | paper-style safe / unsafe / aborted | Monte Carlo safe / unsafe / aborted "
        + "| hover half-widths x / y / z, median (cm) |"
    )  # fmt: skip
    lines = [head, "|---|" + "---|" * (len(buffers) + 3)]
    for name, c in contracts.items():
        t1 = " | ".join(_pct(c["table1"][b]) for b in buffers)
        pr, mc = c.get("landing_paper_runs"), c.get("landing")
        paper = "not flown" if pr is None else f"{pr['safe']} / {pr['unsafe']} / {pr['aborted']}"
        monte = (
            "not flown" if mc is None else f"{mc['safe']} / {mc['unsafe']} / {mc['aborted']} of {mc['runs']}"
        )
        hover = c.get("hover_half_widths") or {}
        med = hover.get("median")
        widths = "—" if med is None else " / ".join(f"{100 * v:.1f}" for v in med)
        lines.append(f"| {name} | {t1} | {paper} | {monte} | {widths} |")
    detail = [
        "",
        "| Table I with exact intervals | " + " | ".join(f"b = {b}" for b in buffers) + " |",
        "|---|" + "---|" * len(buffers),
    ]
    for name, c in contracts.items():
        rows = c.get("table1_detail") or {}
        if rows:
            detail.append(f"| {name} | " + " | ".join(_cell(rows[b]) for b in buffers) + " |")
    if len(detail) > 3:
        detail.append(
            "| paper | " + " | ".join(f"{_PAPER[b]:.2f} %" if b in _PAPER else "—" for b in buffers) + " |"
        )
        lines += detail
    claims = [
        f"- {name}: " + "; ".join(
            f"{cl['statement']}: {'holds' if cl['holds'] else 'does not hold'} ({cl['detail']})"
            for cl in c["claims"].values()
        )
        for name, c in contracts.items()
    ]  # fmt: skip
    return "\n".join(lines) + (
        "\n\n" + "\n".join(claims) if any(c["claims"] for c in contracts.values()) else ""
    )


def results_markdown(summary: Mapping[str, Any]) -> str:
    """Everything the docs quote: the contracts, Table I, ages, ablation, landings, bound, timings."""
    parts = []
    if summary.get("contracts"):
        parts += ["### The three contracts", contracts_markdown(summary)]
    parts += ["### Table I (default_calibrated)", table1_markdown(summary)]
    per = summary["camera_timing"]["per_buffer"]
    ages = " | ".join(
        f"{v['age_ms']['median']:.1f} ({v['age_ms']['p05']:.0f}–{v['age_ms']['p95']:.0f})"
        for _, v in sorted(per.items(), key=lambda kv: int(kv[0]))
    )
    errors = " | ".join(
        f"{v['error_mm']['median']:.1f}" for _, v in sorted(per.items(), key=lambda kv: int(kv[0]))
    )
    parts += [
        "### Image age and error on the test flights",
        "\n".join(
            [
                "| buffer size | " + " | ".join(sorted(per, key=int)) + " |",
                "|---|" + "---|" * len(per),
                f"| median age (5–95 %), ms | {ages} |",
                f"| median error, mm | {errors} |",
            ]
        ),
        "### Ablation",
        ablation_markdown(summary),
        f"### Landing at buffer size {summary['landing']['buffer_size']}",
        landing_markdown(summary["landing"]),
    ]
    if summary.get("landing_buffer3"):
        parts += [
            f"### Landing at buffer size {summary['landing_buffer3']['buffer_size']}",
            landing_markdown(summary["landing_buffer3"]),
        ]
    b = summary["landing"]["ipc"]["certified"]
    parts += [
        "### Certified bound",
        bound_words(b),
        "### Claims",
        "\n".join(f"- {claim_markdown(c)}" for c in summary["claims"].values()),
        "### Timings",
        "\n".join(f"- {k}: {v:.1f} s" for k, v in summary["stage_seconds"].items()),
        f"- total {summary['runtime_seconds']} s wall, {summary.get('cpu_seconds')} CPU-s; load average "
        f"{summary['machine'].get('load_average_start')} -> {summary['machine'].get('load_average_end')}",
    ]
    return "\n\n".join(parts)
