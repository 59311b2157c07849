"""The top of the certificate page: the verdict banner and the executive summary.

What a reviewer reads (and signs) first: the banner's colours (:func:`banner_colors`), the
claim, the target and the unit of the claim, one row per check (:func:`display_text` shows
their numbers with symbols), the record of versions and hashes, and the assumption behind
every statement. :func:`page_header` puts them together; :mod:`ipcverify.certification._report`
adds the sections below it. :func:`html_value` and :func:`html_table` format cells for both.
"""

from __future__ import annotations

import html
import math
from typing import Any

from ipcverify.certification._certificate import Certificate, CertificateStatus
from ipcverify.certification._summarize import capitalized
from ipcverify.certification._summary import WEAK_EPSILON, CertificateSummary

#: Banner background and text colour per status (a certified weak target: :data:`_WEAK`).
_COLORS = {
    CertificateStatus.CERTIFIED: ("#1b7f3b", "#ffffff"),
    CertificateStatus.UNTESTED: ("#1b5e7f", "#ffffff"),
    CertificateStatus.UNCHECKED: ("#1b5e7f", "#ffffff"),
    CertificateStatus.NOT_CALIBRATED: ("#9a6700", "#ffffff"),
    CertificateStatus.ROWS_ASSUMED: ("#9a6700", "#ffffff"),
    CertificateStatus.CONTRADICTED: ("#b42318", "#ffffff"),
}
_WEAK = ("#f5b400", "#1f2328")
_LEVEL_COLORS = {"pass": "#1b7f3b", "warn": "#9a6700", "fail": "#b42318", "info": "#57606a"}


def banner_colors(status: CertificateStatus, summary: CertificateSummary) -> tuple[str, str]:
    """Background and text colour of the verdict banner: amber for a certified weak target.

    Parameters
    ----------
    status : CertificateStatus
        The verdict.
    summary : CertificateSummary
        The executive summary (its target strength).

    Examples
    --------
    >>> s = CertificateSummary(status="CERTIFIED", status_detail="", claim="", epsilon=0.5,
    ...     certified_epsilon=0.45, delta=0.1, unit="row", checks=(), date_utc="2025-01-31T12:00:00Z",
    ...     ipcverify_version="0", model_sha256="0" * 64, model_sha256_of="network", labels=("y_0",))
    >>> banner_colors(CertificateStatus.CERTIFIED, s)
    ('#f5b400', '#1f2328')
    """
    if summary.certified and summary.strength == "weak":
        return _WEAK
    return _COLORS[status]


def html_value(v: Any) -> str:
    """A value as a table cell: thousands separators, 4 significant digits, an em dash for None.

    Examples
    --------
    >>> html_value(12345), html_value(0.123456), html_value(None), html_value(True)
    ('12,345', '0.1235', '&mdash;', 'yes')
    """
    if v is None:
        return "&mdash;"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}"
    if isinstance(v, float):
        if not math.isfinite(v):
            return html.escape(str(v))
        return f"{v:.4g}"
    return html.escape(str(v))


def html_table(rows: list[tuple[str, Any]]) -> str:
    """A two-column table, one ``(label, value)`` row each (labels escaped, values by :func:`html_value`).

    Examples
    --------
    >>> html_table([("n", 1000)])
    '<table><tr><th>n</th><td>1,000</td></tr></table>'
    """
    body = "".join(f"<tr><th>{html.escape(k)}</th><td>{html_value(v)}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


_CSS = """
body{font-family:-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;max-width:980px;margin:1.2em auto;
padding:0 1em;color:#1f2328;line-height:1.45}
h1{font-size:1.5em;margin:0 0 .3em}h2{font-size:1.2em;border-bottom:1px solid #d0d7de;padding-bottom:.2em;
margin-top:1.6em}
.status{padding:.55em .8em;border-radius:6px;font-weight:600;margin:.4em 0}
.statement{font-size:1.04em;background:#f6f8fa;border-left:4px solid #4c72b0;padding:.6em 1em;margin:.8em 0}
table{border-collapse:collapse;margin:.5em 0}
th,td{border:1px solid #d0d7de;padding:.25em .6em;text-align:left;font-size:.92em;vertical-align:top}
th{background:#f6f8fa;font-weight:600}
.vacuous{color:#b42318;font-weight:600}.ok{color:#1b7f3b;font-weight:600}
.verdict{font-weight:600;white-space:nowrap}.hash{font-family:monospace;font-size:.85em;word-break:break-all}
img{max-width:100%;display:block;margin:.6em 0}.small{font-size:.85em;color:#57606a}
code{background:#f6f8fa;padding:0 .25em;border-radius:3px}
.sign td{height:2.2em;min-width:14em}
"""


def _target_table(s: CertificateSummary) -> str:
    rows: list[tuple[str, str]] = []
    if s.epsilon is None:
        rows.append(("target violation rate &epsilon;", "none: the model is not calibrated"))
    else:
        strength = (
            f"<b>weak target</b> (&epsilon; &ge; {WEAK_EPSILON:g})"
            if s.strength == "weak"
            else f"strong target (&epsilon; &lt; {WEAK_EPSILON:g})"
        )
        rows.append(
            (
                "target violation rate &epsilon;",
                f"{s.epsilon:g}: {strength}; certified rate {html_value(s.certified_epsilon)}",
            )
        )
    delta = (
        "&mdash;"
        if s.delta is None
        else f"{s.delta:g} (the claim holds with probability &ge; {1 - s.delta:.6g})"
    )
    rows += [
        ("confidence parameter &delta;", delta),
        ("unit of the claim", html.escape(s.unit_text())),
        (
            "perceived quantity y",
            f"{html.escape(', '.join(s.labels))}, in {html.escape(s.units_text)}",
        ),
    ]
    return "<table>" + "".join(f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in rows) + "</table>"


_SYMBOLS = (("<=", "≤"), (">=", "≥"), ("epsilon =", "ε ="), ("delta =", "δ ="), ("alpha =", "α ="))


def display_text(text: str) -> str:
    """Plain-text numbers as the page shows them: ``<=`` as ≤, ``epsilon =`` as ε =, ...

    Parameters
    ----------
    text : str
        A check's detail as the summary writes it, in ASCII; ``<=``, ``>=``, ``epsilon =``,
        ``delta =`` and ``alpha =`` are replaced where they follow a space or an opening
        parenthesis and precede a space.

    Examples
    --------
    >>> display_text("lower bound 0.2 <= allowed 0.3 (target epsilon = 0.5)")
    'lower bound 0.2 ≤ allowed 0.3 (target ε = 0.5)'
    """
    for plain, symbol in _SYMBOLS:
        text = text.replace(f" {plain} ", f" {symbol} ").replace(f"({plain} ", f"({symbol} ")
    return text


def _checks_table(s: CertificateSummary) -> str:
    rows = "".join(
        f'<tr class="check-{c.level}"><td>{html.escape(capitalized(c.name))}</td>'
        f'<td class="verdict" style="color:{_LEVEL_COLORS[c.level]}">{html.escape(c.verdict)}</td>'
        f"<td>{html.escape(display_text(c.detail))}</td></tr>"
        for c in s.checks
    )
    return f'<table class="checks"><tr><th>check</th><th>verdict</th><th>the numbers</th></tr>{rows}</table>'


def _record_table(s: CertificateSummary) -> str:
    rows = [
        ("date (UTC, ISO 8601)", html.escape(s.date_utc)),
        ("ipcverify version", html.escape(s.ipcverify_version)),
        (f"{s.model_sha256_of} SHA-256", f'<span class="hash">{s.model_sha256}</span>'),
    ]
    rows += [
        (f"{k} SHA-256", f'<span class="hash">{html.escape(v)}</span>') for k, v in s.data_sha256.items()
    ]
    if not s.data_sha256:
        rows.append(("data SHA-256", "no data given"))
    return (
        '<table class="record">' + "".join(f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in rows) + "</table>"
    )


def _assumption(s: CertificateSummary) -> str:
    if s.unit == "group":
        units = (
            f"the calibration groups of <code>{html.escape(str(s.unit_column))}</code> (flights, runs), the "
            "test groups and the groups met in deployment are exchangeable (rows within a group may be "
            "correlated)"
        )
    else:
        units = (
            "the calibration rows, the test rows and the rows met in deployment are exchangeable (for "
            "example, drawn i.i.d. from the same distribution)"
        )
    return (
        f'<p class="small">Assumption behind every statement on this page: {units}, and none of them was '
        "used for training. Nothing here holds under distribution shift; the domain-of-validity test flags "
        "queries unlike the calibration data.</p>"
    )


def page_header(cert: Certificate, s: CertificateSummary) -> list[str]:
    """The banner and the executive summary: what a reviewer reads (and signs) first."""
    bg, fg = banner_colors(cert.status, s)
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        "<title>ipcverify certificate</title>",
        f"<style>{_CSS}</style></head><body>",
        "<h1>Inverse perception contract: certificate</h1>",
        f'<p class="status" id="verdict" style="background:{bg};color:{fg}">'
        f"{html.escape(s.verdict_text('ε'))}</p>",
        '<section id="summary"><h2>Summary</h2>',
        f'<p class="statement"><b>What is guaranteed.</b> {html.escape(s.claim)}</p>',
        _target_table(s),
        _checks_table(s),
    ]
    if cert.test_bound_note:
        parts.append(f"<p>{html.escape(cert.test_bound_note)}</p>")
    parts += [_assumption(s), _record_table(s), "</section>"]
    return parts
