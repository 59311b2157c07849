"""The certificate as one self-contained HTML page (plots embedded as base64 PNG).

The page references no external resource (no scripts, styles, fonts or images
from the network), so it can be archived, printed and opened offline. From the top:

* the verdict banner -- green for a certified strong target, **amber for a weak one**
  (``epsilon >= 0.1``, :data:`ipcverify.certification.WEAK_EPSILON`), red when the test data
  contradicts the calibration;
* the executive summary (:class:`~ipcverify.certification.CertificateSummary`): the claim in one
  sentence, epsilon, delta and the unit of the claim, the units and labels of ``y``, one row
  per check with its verdict, the date (UTC), the ipcverify version and the SHA-256 of the
  model and the data;
* the calibration, the domain of validity, the test set (with the per-flight table and the
  plots of :mod:`ipcverify.certification._report_plots`), Theorem 1, and the identity of every file, with
  lines for a reviewer's signature.
"""

from __future__ import annotations

import base64
import html
import math
from typing import Any

from matplotlib.figure import Figure

from ipcverify.calibration._protocol import CalibrationSummary
from ipcverify.certification._certificate import (
    Certificate,
    CertificateStatus,
    CertifyEvidence,
    CertifyResult,
    Consistency,
)
from ipcverify.certification._report_plots import (
    ellipse_outline,
    figure_to_png,
    plot_coverage,
    plot_projections,
    plot_scores,
)
from ipcverify.certification._summarize import capitalized, summarize
from ipcverify.certification._summary import WEAK_EPSILON, CertificateSummary

__all__ = [
    "figure_to_png",
    "ellipse_outline",
    "plot_scores",
    "plot_coverage",
    "plot_projections",
    "banner_colors",
    "display_text",
    "render_report",
]

#: Banner background and text colour per status (a certified weak target: :data:`_WEAK`).
_COLORS = {
    CertificateStatus.CERTIFIED: ("#1b7f3b", "#ffffff"),
    CertificateStatus.UNTESTED: ("#1b5e7f", "#ffffff"),
    CertificateStatus.UNCHECKED: ("#1b5e7f", "#ffffff"),
    CertificateStatus.NOT_CALIBRATED: ("#9a6700", "#ffffff"),
    CertificateStatus.CONTRADICTED: ("#b42318", "#ffffff"),
}
_WEAK = ("#f5b400", "#1f2328")
_LEVEL_COLORS = {"pass": "#1b7f3b", "warn": "#9a6700", "fail": "#b42318", "info": "#57606a"}


def banner_colors(status: CertificateStatus, summary: CertificateSummary) -> tuple[str, str]:
    """Background and text colour of the verdict banner: amber for a certified weak target.

    Examples
    --------
    >>> from ipcverify.certification._summary import Check
    >>> s = CertificateSummary(status="CERTIFIED", status_detail="", claim="", epsilon=0.5,
    ...     certified_epsilon=0.45, delta=0.1, unit="row", checks=(), date_utc="2025-01-31T12:00:00Z",
    ...     ipcverify_version="0", model_sha256="0" * 64, model_sha256_of="network", labels=("y_0",))
    >>> banner_colors(CertificateStatus.CERTIFIED, s)
    ('#f5b400', '#1f2328')
    """
    if summary.certified and summary.strength == "weak":
        return _WEAK
    return _COLORS[status]


def _img(fig: Figure, alt: str) -> str:
    data = base64.b64encode(figure_to_png(fig)).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _fmt(v: Any) -> str:
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


def _table(rows: list[tuple[str, Any]]) -> str:
    body = "".join(f"<tr><th>{html.escape(k)}</th><td>{_fmt(v)}</td></tr>" for k, v in rows)
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


def _unit_words(unit: str) -> str:
    """How the page names a counted unit: ``samples`` (rows of the data) are rows."""
    return "rows" if unit == "samples" else unit


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
                f"{s.epsilon:g}: {strength}; certified rate {_fmt(s.certified_epsilon)}",
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


def _header(cert: Certificate, s: CertificateSummary) -> list[str]:
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


def _calibration_section(cal: CalibrationSummary | None) -> list[str]:
    parts = ["<h2>Calibration</h2>"]
    if cal is None:
        parts.append(
            "<p><b>Absent.</b> This model carries no calibration, so the calibration certificate is "
            "missing. Run <code>ipcverify calibrate MODEL CALIBRATION_DATA --epsilon E --delta D --out "
            "calibrated.pt</code> on held-out data.</p>"
        )
        return parts
    rows: list[tuple[str, Any]] = [
        ("mode", cal.mode + (" (training-conditional)" if cal.mode == "pac" else " (split conformal)")),
        ("epsilon (target violation rate)", cal.epsilon),
        ("delta", cal.delta),
        ("calibration samples n", cal.n),
        ("calibrated per", cal.grouping),
        ("certified violation rate", cal.certified_epsilon),
    ]
    if len(cal.groups) == 1:
        rows += [("order statistic k", cal.groups[0].k), ("scale factor s", cal.groups[0].scale)]
    parts.append(_table(rows))
    if len(cal.groups) > 1:
        grows = "".join(
            f"<tr><td>{html.escape(g.label)}</td><td>{_fmt(g.n)}</td><td>{_fmt(g.k)}</td>"
            f"<td>{_fmt(g.scale)}</td></tr>"
            for g in cal.groups
        )
        parts.append(f"<table><tr><th>group</th><th>n</th><th>k</th><th>scale</th></tr>{grows}</table>")
    return parts


def _domain_section(cert: Certificate) -> list[str]:
    d = cert.domain
    parts = ["<h2>Domain of validity</h2>"]
    if d is None:
        parts.append(
            "<p><b>Absent.</b> This model carries no domain-of-validity test, so nothing flags queries "
            "unlike the calibration data. Recalibrate with a current ipcverify to fit one.</p>"
        )
        return parts
    parts.append(f"<p>{html.escape(d.sentence())}</p>")
    rows: list[tuple[str, Any]] = [
        ("method", d.method),
        ("false-alarm rate alpha", d.alpha),
        ("threshold (whitened distance)", d.threshold),
        ("calibration inputs (reference)", d.n_reference),
    ]
    if d.n == 0:
        rows.append(("test queries", "none: no test data given, so the held-out test was not run"))
    else:
        rows += [("test queries checked", d.n), ("test queries outside", d.outside)]
    parts.append(_table(rows))
    return parts


def _test_section(cert: Certificate, ev: CertifyEvidence | None, s: CertificateSummary) -> list[str]:
    t = cert.test
    parts = ["<h2>Test set</h2>"]
    if t is None or ev is None or cert.volume is None:
        parts.append(
            "<p><b>No test data was given: the held-out test was not run.</b> The calibration certificate "
            "above does not need one, but "
            "nothing on this page checks it independently: run <code>ipcverify certify MODEL --data "
            "TEST</code> with fresh held-out samples.</p>"
        )
        return parts
    n_y = len(s.labels)
    volume = (
        f"ln of volume in ({s.units})^{n_y}" if s.units is not None else f"ln of volume in {s.units_text}"
    )
    rows: list[tuple[str, Any]] = [
        (f"test {_unit_words(t.unit)}", t.n),
        ("violations", t.violations),
        ("empirical violation rate", t.empirical_rate),
        (f"upper bound (Clopper-Pearson, confidence {1 - t.delta:.6g})", t.upper_bound),
        (f"two-sided interval ({1 - t.delta:.6g})", f"[{t.interval[0]:.4g}, {t.interval[1]:.4g}]"),
        (f"mean log-volume of the sets ({volume})", cert.volume.mean_log),
        (f"median log-volume ({volume})", cert.volume.median_log),
    ]
    parts.append(_table(rows))
    if cert.consistency.checked:
        parts.append(_consistency_line("Consistency check: test", cert.consistency))
    parts += _group_test_part(cert)
    parts.append(_img(plot_scores(ev, cert.calibration is not None), "histogram of normalised test scores"))
    if cert.coverage is not None:
        parts.append("<h2>Conditional coverage</h2>")
        parts.append(
            "<p>The guarantee above is marginal (averaged over all inputs), not per region of the state "
            "space. This plot shows how the violation rate varies across bins of "
            f"<code>{html.escape(cert.coverage.column)}</code>.</p>"
        )
        eps = None if cert.calibration is None else cert.calibration.epsilon
        parts.append(_img(plot_coverage(cert.coverage, t.delta, eps), "violation rate per bin"))
    if cert.worst_bin is not None:
        w = cert.worst_bin
        wrows = "".join(
            f"<tr><td>{html.escape(c)}</td><td>{_fmt(cov)}</td><td>[{lo:.4g}, {hi:.4g}]</td><td>{n}</td></tr>"
            for c, (cov, lo, hi, n) in w.by_column.items()
        )
        parts.append(
            f"<p>Worst-bin coverage over {w.bins} quantile bins of every state column and of ||yhat||: "
            f"<b>{100 * w.coverage:.2f} %</b> (in a bin of <code>{html.escape(w.column)}</code>). A set that "
            "is small because it under-covers a hard region shows here.</p>"
            f"<table><tr><th>column</th><th>worst-bin coverage</th><th>bin</th><th>n</th></tr>{wrows}</table>"
        )
    parts.append("<h2>Example sets</h2>")
    parts.append(
        "<p class='small'>The smallest, median and largest set of the test data, and one violated row "
        "(if any), projected on pairs of coordinates of y. A truth outside the n-dimensional set can "
        "still lie inside some, or even all, of its 2-D shadows.</p>"
    )
    axes = [s.axis_label(i) for i in range(n_y)]
    parts.append(_img(plot_projections(ev, axes), "projections of example ellipsoids"))
    return parts


def _consistency_line(label: str, cons: Consistency) -> str:
    """One paragraph: the test lower bound against the allowed rate, the verdict and the rule."""
    verdict = "consistent" if cons.consistent else "CONTRADICTS the calibration"
    return (
        f"<p>{html.escape(label)} lower bound {cons.test_lower_bound:.4g} vs. allowed rate "
        f"{cons.allowed_rate:.4g}: <b>{verdict}</b>. <span class='small'>{html.escape(cons.rule)}</span></p>"
    )


def _group_test_part(cert: Certificate) -> list[str]:
    """The flight-level table: the test counted per group, both statistics, and what was compared."""
    g = cert.group_test
    if g is None:
        return []
    parts = [f"<h3>Counted per group of <code>{html.escape(g.column)}</code> (flights, runs)</h3>"]
    if cert.test is not None and cert.test.unit == "samples":
        parts.append(
            "<p>The row-level interval above assumes <b>independent rows</b>. Rows of one flight are "
            "correlated, so it can be far too narrow. The counts below use one statistic per group and are "
            "valid when the test groups are i.i.d., whatever the correlation within a group.</p>"
        )
    rows = ""
    for unit, label, res in (
        ("trajectory", "any violation in the group", g.trajectory),
        ("sample", "one random row of the group (seeded)", g.sample),
    ):
        mark = "compared with the calibration" if g.compared_unit == unit else "reported"
        rows += (
            f"<tr><td>{html.escape(label)}</td><td>{_fmt(res.violations)} / {_fmt(res.n)}</td>"
            f"<td>{_fmt(res.empirical_rate)}</td><td>{_fmt(res.upper_bound)}</td>"
            f"<td>[{res.interval[0]:.4g}, {res.interval[1]:.4g}]</td><td>{mark}</td></tr>"
        )
    conf = f"{1 - g.trajectory.delta:.6g}"
    parts.append(
        f"<table><tr><th>statistic per group</th><th>violations / groups</th><th>rate</th>"
        f"<th>upper bound ({conf})</th><th>two-sided interval ({conf})</th><th>role</th></tr>{rows}</table>"
    )
    c = g.consistency
    if c.checked:
        parts.append(_consistency_line(f"Group-level consistency ({g.compared_unit} count):", c))
    else:
        parts.append(f"<p class='small'>Not compared with the calibration: {html.escape(c.reason)}.</p>")
    parts.append(
        f"<p class='small'>{g.n_groups:,} test groups, {g.n_rows:,} rows; the random row of each group "
        f"is drawn with seed {g.seed}. Proof: proofs/group_calibration.md, section 6.</p>"
    )
    return parts


def _theorem1_section(cert: Certificate) -> list[str]:
    parts = ["<h2>Theorem 1 of the paper</h2>"]
    t1 = cert.theorem1
    if t1 is None:
        parts.append(f"<p><b>{html.escape(capitalized(cert.theorem1_reason))}.</b> Nothing is claimed.</p>")
        return parts
    cls = "ok" if t1.usable else "vacuous"
    parts.append(f'<p class="{cls}">{html.escape(t1.explanation())}</p>')

    def nneed(v: int | None) -> str:
        return "no N" if v is None else f"{v:.3g}"

    rows = "".join(
        f"<tr><th>{label}</th><td>{b.lipschitz:.4g}</td><td>{t1.empirical_term:.4g}</td>"
        f"<td>{b.complexity:.4g}</td><td>{t1.confidence_term:.4g}</td><td>{b.bound:.4g}</td>"
        f"<td>{'yes' if b.vacuous else 'no'}</td><td>{nneed(b.n_needed)}</td></tr>"
        for label, b in (
            ("sound L_g (upper bound; valid)", t1.sound),
            ("empirical L_g (lower estimate; NOT a guarantee)", t1.optimistic),
        )
    )
    parts.append(
        "<table><tr><th></th><th>L_g</th><th>empirical truncated hinge</th>"
        "<th>(12/&alpha;) L_g &radic;(p/N)</th><th>&radic;(ln(2/&delta;)/2N)</th><th>bound</th>"
        f"<th>vacuous</th><th>N for bound &lt; 1</th></tr>{rows}</table>"
    )
    source = (
        f" The training terms come from the {html.escape(cert.theorem1_source)}."
        if cert.theorem1_source
        else ""
    )
    parts.append(
        f"<p class='small'>p = {t1.n_parameters:,} parameters, N = {t1.n_train:,} training samples, "
        f"&alpha; = {t1.alpha:g}, &delta; = {t1.delta:g}.{source} The sound L_g bounds the Lipschitz "
        f"constant over the parameter ball of radius {t1.radius:g} around the trained weights and the "
        "bounding box of the training data. The empirical L_g is the largest per-sample gradient norm at "
        "the trained weights: a lower estimate, so its bound is optimistic and proves nothing. A bound "
        "&ge; 1 says nothing about a probability.</p>"
    )
    return parts


def _identity_section(cert: Certificate) -> list[str]:
    m = cert.model
    rows: list[tuple[str, Any]] = [
        ("model file", m.path),
        ("model file SHA-256", m.file_sha256),
        ("network SHA-256", m.network_sha256),
        ("architecture", ", ".join(f"{k}={v}" for k, v in m.architecture.items())),
        ("parameters p", m.n_parameters),
    ]
    if m.selection is not None:
        rows.append(("settings the recipe leaves open, chosen by rule", m.selection.get("summary", "")))
        rows.append(("the rule", (m.selection.get("rule") or {}).get("rule", "")))
    if cert.test_data is not None:
        rows += [
            ("test data", cert.test_data.source),
            ("test data SHA-256 (content)", cert.test_data.content_sha256),
        ]
    if cert.calibration is not None:
        rows.append(("calibration data SHA-256 (content)", cert.calibration.data_sha256))
    if cert.train_data is not None:
        rows.append(("training data SHA-256 (content)", cert.train_data.content_sha256))
    return [
        "<h2>Identity</h2>",
        _table(rows),
        "<p class='small'>Generated by ipcverify. The machine-readable record is "
        "<code>certificate.json</code> beside this file.</p>",
        "<h2>Review</h2>",
        '<table class="sign"><tr><th>reviewed by</th><td></td></tr><tr><th>signature</th><td></td></tr>'
        "<tr><th>date</th><td></td></tr></table></body></html>",
    ]


def render_report(result: CertifyResult) -> str:
    """The full HTML page for a certification result (a string; no external resources).

    The summary at the top is the certificate's own (``certificate.summary``, made by
    :func:`~ipcverify.certification.certify`); a certificate built without one gets one made now, dated now.

    Examples
    --------
    >>> from ipcverify.data._synthetic import make_lagged_perception
    >>> from ipcverify.contract._model import IPCModel
    >>> from ipcverify.network._modules import IPCNetwork
    >>> from ipcverify.network._architecture import ModelConfig
    >>> from ipcverify.certification import certify  # certify imports this module, not the other way round
    >>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")))
    >>> page = render_report(certify(m, make_lagged_perception(500, seed=2)))
    >>> page.startswith("<!DOCTYPE html>") and "http" not in page
    True
    """
    cert = result.certificate
    summary = cert.summary if cert.summary is not None else summarize(cert)
    parts = _header(cert, summary)
    parts += _calibration_section(cert.calibration)
    parts += _domain_section(cert)
    parts += _test_section(cert, result.evidence, summary)
    parts += _theorem1_section(cert)
    parts += _identity_section(cert)
    return "\n".join(parts)
