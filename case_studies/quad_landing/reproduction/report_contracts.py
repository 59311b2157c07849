"""The report's first section: which of the three contracts reproduces which claim of the paper.

Reads ``summary.json``'s ``contracts`` (:mod:`.contracts`): a table of the paper's claims
against ``paper_raw``, ``paper_calibrated`` and ``default_calibrated``, a sentence per contract
saying in words what it reproduces, Table I and the landings side by side, and the sets'
half-widths at the hover against ``G`` (what decides whether a contract can land).

Examples
--------
>>> contracts_section({}, {})
''
>>> page = contracts_section({"contracts": {"paper_raw": {"label": "raw", "guarantee": "none", "claims": {
...     "table1_buffer1_at_most_1pct": {"holds": True, "supported": False, "detail": "0/300",
...                                     "statement": "Table I, buffer 1: at most 1 %"}}}}}, {})
>>> "reproduces Table I, buffer 1: at most 1 %" in page
True
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from case_studies.quad_landing.reproduction.html_parts import esc, figure, pct, table, yes

__all__ = ["CLAIM_ORDER", "contracts_section", "reproduces_sentence", "why_not_held"]

#: The paper's claims, in the order of the report's first table.
CLAIM_ORDER = (
    "table1_buffer1_at_most_1pct",
    "table1_rates_rising",
    "paper_runs_safe",
    "monte_carlo_safe",
    "monte_carlo_aborted",
    "certified_bound_at_least_empirical",
)


def _rates(contract: Mapping[str, Any]) -> tuple[list[str], dict[str, float], int | None]:
    t1 = contract.get("table1") or {}
    detail = contract.get("table1_detail") or {}
    n = next(iter(detail.values()))["n"] if detail else None
    return sorted(t1, key=int), t1, n


def why_not_held(key: str, contract: Mapping[str, Any], quick: bool) -> str:
    """One line, read off the contract's own numbers: why the claim ``key`` does not hold.

    Examples
    --------
    >>> c = {"table1": {"1": 0.0, "2": 0.0, "3": 0.01}, "table1_detail": {"1": {"n": 200}}}
    >>> print(why_not_held("table1_rates_rising", c, quick=True))
    buffer sizes 1 and 2 tie at 0.00 % (--quick: 200 measurements per buffer size cannot tell them apart)
    """
    buffers, t1, n = _rates(contract)
    quick_n = f" (--quick: {n} measurements per buffer size cannot tell them apart)" if quick else ""
    if key == "table1_rates_rising":
        steps = []
        for a, b in zip(buffers, buffers[1:], strict=False):
            if t1[b] == t1[a]:
                steps.append(f"buffer sizes {a} and {b} tie at {100 * t1[a]:.2f} %")
            elif t1[b] < t1[a]:
                steps.append(
                    f"it falls from {100 * t1[a]:.2f} % at buffer size {a} to {100 * t1[b]:.2f} % at {b}"
                )
        return "; ".join(steps) + quick_n
    if key.startswith("table1_buffer"):
        b = key.removeprefix("table1_buffer")[0]
        low = t1.get(b, 1.0) < 0.02 and "between_2" in key
        why = (
            "its sets also cover the lag of more buffers"
            if low
            else "more truths outside than the claim allows"
        )
        return f"{100 * t1.get(b, float('nan')):.2f} % at buffer size {b}: {why}" + (quick_n if quick else "")
    mc, hover = contract.get("landing"), contract.get("hover_half_widths") or {}
    if mc is None:
        return str(contract.get("not_flown") or "not flown")
    parts = []
    if mc.get("aborted"):
        parts.append(f"{mc['aborted']} of {mc['runs']} Monte Carlo runs aborted at the measurement cap")
    if mc.get("unsafe"):
        parts.append(f"{mc['unsafe']} of {mc['runs']} unsafe")
    med, limit = hover.get("median"), hover.get("limit")
    if med is not None and limit is not None and any(m > v for m, v in zip(med, limit, strict=True)):
        parts.append(
            "its sets at the hover are "
            + " / ".join(f"{100 * m:.1f}" for m in med)
            + " cm (x / y / z, median) "
            "where G allows " + " / ".join(f"{100 * v:.1f}" for v in limit) + " cm"
        )
    if quick:
        parts.append(f"--quick flies {mc['runs']} Monte Carlo runs")
    return "; ".join(parts) or "see the numbers"


def _cell(claim: Mapping[str, Any] | None, reason: str | None) -> str:
    if claim is None:
        return '<span class="muted">— (no certificate)</span>'
    why = "" if claim["holds"] or not reason else f"<br><span class='muted'>why: {esc(reason)}</span>"
    return f"{yes(claim['holds'])} <span class='muted'>{esc(claim['detail'])}</span>{why}"


def reproduces_sentence(name: str, contract: Mapping[str, Any]) -> str:
    """One sentence: what ``contract`` reproduces of the paper's claims, and what it does not.

    Examples
    --------
    >>> c = {"label": "x", "guarantee": "none", "claims": {"a": {"holds": False, "supported": False,
    ...      "detail": "0/10 safe", "statement": "all safe"}}}
    >>> reproduces_sentence("paper_raw", c)[-63:]
    'none of the claims; it does not reproduce all safe (0/10 safe).'
    """
    claims = contract.get("claims") or {}
    held = [c["statement"] for c in claims.values() if c["holds"]]
    missed = [f"{c['statement']} ({c['detail']})" for c in claims.values() if not c["holds"]]
    text = f"{name} ({contract.get('label', '')}; guarantee: {contract.get('guarantee', '')}) reproduces "
    text += "; ".join(held) if held else "none of the claims"
    if missed:
        text += "; it does not reproduce " + "; ".join(missed)
    return text + "."


def _hover_row(name: str, contract: Mapping[str, Any]) -> list[str] | None:
    hover = contract.get("hover_half_widths")
    if not hover or hover.get("median") is None:
        return None
    med, p90, limit = hover["median"], hover["p90"], hover["limit"]
    cells = [f"{100 * m:.1f} / {100 * p:.1f}" for m, p in zip(med, p90, strict=True)]
    return [esc(name), *cells, " / ".join(f"{100 * v:.1f}" for v in limit), pct(hover.get("fits"), 0)]


def contracts_section(summary: Mapping[str, Any], figs: Mapping[str, bytes]) -> str:
    """The HTML of the contracts section (empty if the summary has no ``contracts``)."""
    contracts = summary.get("contracts") or {}
    if not contracts:
        return ""
    names = list(contracts)
    statements: dict[str, str] = {}
    for c in contracts.values():
        for key, claim in (c.get("claims") or {}).items():
            statements.setdefault(key, claim.get("statement") or key)
    keys = [k for k in CLAIM_ORDER if k in statements] + [k for k in statements if k not in CLAIM_ORDER]
    quick = bool(summary.get("quick"))
    rows = [
        [
            esc(statements[k]),
            *[
                _cell((contracts[n].get("claims") or {}).get(k), why_not_held(k, contracts[n], quick))
                for n in names
            ],
        ]
        for k in keys
    ]
    words = "".join(f"<li>{esc(reproduces_sentence(n, contracts[n]))}</li>" for n in names)
    t1_rows = []
    for n in names:
        t1 = contracts[n].get("table1") or {}
        t1_rows.append([esc(n), *[pct(t1.get(b)) for b in sorted(t1, key=int)]])
    buffers = sorted((contracts[names[0]].get("table1") or {}), key=int)
    paper_t1 = (summary.get("paper") or {}).get("table1") or {}
    t1_rows.append(["paper", *[pct(paper_t1.get(b, paper_t1.get(int(b))), 2) for b in buffers]])
    land_rows = []
    for n in names:
        mc, pr = contracts[n].get("landing"), contracts[n].get("landing_paper_runs")
        if mc is None or pr is None:
            land_rows.append([esc(n), esc(contracts[n].get("not_flown") or "not flown"), "", "", "", ""])
            continue
        land_rows.append([
            esc(n), f"{pr['safe']} / {pr['unsafe']} / {pr['aborted']}",
            esc(mc["runs"]), esc(mc["safe"]), esc(mc["unsafe"]), esc(mc["aborted"]),
        ])  # fmt: skip
    hover_rows = [r for n in names if (r := _hover_row(n, contracts[n])) is not None]
    return (
        "<h2>The paper's claims, contract by contract</h2>"
        "<p>Three contracts are measured and flown side by side: the paper's IPC as trained, without a "
        "calibration and so with <b>no guarantee</b> (the paper's protocol); the same network "
        "PAC-calibrated; and ipcverify's default recipe, PAC-calibrated. A claim <i>holds</i> on the "
        "observed counts; Table I's intervals and the certificates are in the sections below.</p>"
        + table(
            ["claim of the paper", *names],
            rows,
            "Table C1. Which contract reproduces which claim of the paper.",
            text=tuple(range(len(names) + 1)),
        )  # fmt: skip
        + f"<ul>{words}</ul>"
        + table(
            ["contract", *[f"buffer {b}" for b in buffers]],
            t1_rows,
            "Table C2. Table I per contract (the pilot test flights; intervals in summary.json).",
        )
        + table(
            [
                "contract",
                "paper-style safe / unsafe / aborted",
                "Monte Carlo runs",
                "safe",
                "unsafe",
                "aborted",
            ],
            land_rows,
            "Table C3. Landings at buffer size 1 per contract.",
            text=(0, 1),
        )  # fmt: skip
        + (
            table(
                ["contract", "x (cm)", "y (cm)", "z (cm)", "largest G allows (cm)", "hover sets that fit"],
                hover_rows,
                "Table C4. Half-widths of the sets at the hover (world frame; median / 90th percentile), "
                "measurements after a run's first.",
            )  # fmt: skip
            if hover_rows
            else ""
        )
        + figure(
            figs,
            "contracts",
            "Figure C1. The three contracts: Table I, the landings, and the sets at the hover "
            "against the half-widths G allows.",
        )  # fmt: skip
    )
