"""The certificate as one self-contained HTML page (plots embedded as base64 PNG).

The page references no external resource (no scripts, styles, fonts or images
from the network), so it can be archived, printed and opened offline. From the top:

* the verdict banner -- green for a certified strong target, **amber for a weak one**
  (``epsilon >= 0.1``, :data:`ipcverify.certification.WEAK_EPSILON`), red when the test data
  contradicts the calibration;
* the executive summary (:class:`~ipcverify.certification.CertificateSummary`): the claim in one
  sentence, epsilon, delta and the unit of the claim, the units and labels of ``y``, one row
  per check with its verdict, the date (UTC), the ipcverify version and the SHA-256 of the
  model and the data (the banner and the summary: :mod:`ipcverify.certification._report_head`);
* the calibration, the domain of validity, the test set (with the per-flight table and the
  plots of :mod:`ipcverify.certification._report_plots`), Theorem 1, and the identity of every file, with
  lines for a reviewer's signature.
"""

from __future__ import annotations

import base64
import html
from typing import Any

from matplotlib.figure import Figure

from ipcverify._wording._verdicts import calibrate_call, certify_call, domain_verdict, theorem1_verdict
from ipcverify.calibration._protocol import CalibrationSummary
from ipcverify.certification._certificate import Certificate, CertifyEvidence, CertifyResult
from ipcverify.certification._report_head import html_table, html_value, page_header
from ipcverify.certification._report_plots import (
    figure_to_png,
    plot_coverage,
    plot_projections,
    plot_scores,
)
from ipcverify.certification._summarize import capitalized, summarize
from ipcverify.certification._summary import CertificateSummary
from ipcverify.certification._test_result import Consistency


def _img(fig: Figure, alt: str) -> str:
    data = base64.b64encode(figure_to_png(fig)).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _unit_words(unit: str) -> str:
    """How the page names a counted unit: ``samples`` (rows of the data) are rows."""
    return "rows" if unit == "samples" else unit


def _calibration_section(cal: CalibrationSummary | None) -> list[str]:
    parts = ["<h2>Calibration</h2>"]
    if cal is None:
        parts.append(
            "<p><b>Absent.</b> This model carries no calibration, so the calibration certificate is "
            f"missing. Run <code>{html.escape(calibrate_call())}</code> on held-out data.</p>"
        )
        return parts
    rows: list[tuple[str, Any]] = [
        ("mode", cal.mode + (" (training-conditional)" if cal.mode == "pac" else " (split conformal)")),
        ("epsilon (target violation rate)", cal.epsilon),
        ("delta", cal.delta),
        ("calibration samples used n", cal.n),
        ("calibrated per", cal.grouping),
        ("certified violation rate", cal.certified_epsilon),
    ]
    if len(cal.groups) == 1:
        rows += [("order statistic k", cal.groups[0].k), ("scale factor s", cal.groups[0].scale)]
    parts.append(html_table(rows))
    if len(cal.groups) > 1:
        grows = "".join(
            f"<tr><td>{html.escape(g.label)}</td><td>{html_value(g.n)}</td><td>{html_value(g.k)}</td>"
            f"<td>{html_value(g.scale)}</td></tr>"
            for g in cal.groups
        )
        parts.append(f"<table><tr><th>group</th><th>n</th><th>k</th><th>scale</th></tr>{grows}</table>")
    return parts


def _domain_section(cert: Certificate) -> list[str]:
    d = cert.domain
    parts = ["<h2>Domain of validity</h2>"]
    if d is None:
        absent = domain_verdict(
            present=False, radius_zero=False, queries=0, well_above=False, row_level=False
        )
        parts.append(
            f"<p><b>{capitalized(absent)}.</b> This model carries no domain-of-validity test, so nothing "
            "flags queries unlike the calibration data. Recalibrate with a current ipcverify to fit one.</p>"
        )
        return parts
    verdict = d.verdict
    parts.append(f"<p><b>Verdict: {html.escape(verdict)}.</b> {html.escape(d.sentence())}</p>")
    rows: list[tuple[str, Any]] = [
        ("method", d.method),
        ("false-alarm rate alpha", d.flag_rate),
        ("threshold (whitened distance)", d.threshold),
        ("calibration inputs (reference)", d.n_reference),
    ]
    if d.n == 0:
        rows.append(("test queries", "none: no test data given, so the held-out test was not run"))
    else:
        rows += [("test queries checked", d.n), ("test queries outside", d.outside)]
    parts.append(html_table(rows))
    return parts


def _test_section(cert: Certificate, ev: CertifyEvidence | None, s: CertificateSummary) -> list[str]:
    t = cert.test
    parts = ["<h2>Test set</h2>"]
    if t is None or ev is None or cert.volume is None:
        parts.append(
            "<p><b>No test data was given: the held-out test was not run.</b> The calibration certificate "
            "above does not need one, but "
            f"nothing on this page checks it independently: run <code>{html.escape(certify_call())}</code> "
            "with fresh held-out samples.</p>"
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
        (f"upper bound (Clopper-Pearson, confidence {1 - t.delta:.6g})", t.bound_text()),
        (f"two-sided interval ({1 - t.delta:.6g})", f"[{t.interval[0]:.4g}, {t.interval[1]:.4g}]"),
        (f"mean log-volume of the sets ({volume})", cert.volume.mean_log),
        (f"median log-volume ({volume})", cert.volume.median_log),
    ]
    if (r := cert.test_rows) is not None:  # which rows were counted, and how they were checked
        rows += [
            ("rows of the test data", r.n),
            ("repeated rows (each distinct row is counted once)", r.repeated),
            ("checked against the training rows", r.how("training")),
            ("checked against the calibration rows", r.how("calibration")),
        ]
    parts.append(html_table(rows))
    if cert.consistency.checked:
        parts.append(_consistency_line("Consistency check: test", cert.consistency))
    parts += _group_test_part(cert)
    parts.append(_img(plot_scores(ev, cert.calibration is not None), "histogram of normalised test scores"))
    if cert.coverage is not None:
        parts.append("<h2>Conditional coverage</h2>")
        correlated = (
            ""
            if cert.group_test is None
            else " Each bin's interval counts its rows as independent samples; rows of one group of "
            f"<code>{html.escape(cert.group_test.column)}</code> are correlated, so the intervals are "
            "too narrow: read them as descriptive only."
        )
        parts.append(
            "<p>The guarantee above is marginal (averaged over all inputs), not per region of the state "
            "space. This plot shows how the violation rate varies across bins of "
            f"<code>{html.escape(cert.coverage.column)}</code>.{correlated}</p>"
        )
        eps = None if cert.calibration is None else cert.calibration.epsilon
        parts.append(_img(plot_coverage(cert.coverage, t.delta, eps), "violation rate per bin"))
    if cert.worst_bin is not None:
        w = cert.worst_bin
        wrows = "".join(
            f"<tr><td>{html.escape(c)}</td><td>{html_value(cov)}</td>"
            f"<td>[{lo:.4g}, {hi:.4g}]</td><td>{n}</td></tr>"
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
    statistics = (
        ("share", "share of the group's rows outside (mean over groups)"),
        ("share-of-runs", "share of the group's rows above the claim's"),
        ("trajectory", "any violation in the group"),
        ("sample", "one random row of the group (seeded)"),
    )
    for unit, label in statistics:
        res = g.result(unit)  # type: ignore[arg-type]
        if res is None or (unit == "sample" and g.compared_unit != "sample"):
            continue
        mark = "compared with the calibration" if g.compared_unit == unit else "reported"
        counted = (
            f"mean {html_value(res.empirical_rate)} over {html_value(res.n)}"
            if res.statistic == "mean"
            else f"{html_value(res.violations)} / {html_value(res.n)}"
        )
        rows += (
            f"<tr><td>{html.escape(label)}</td><td>{counted}</td>"
            f"<td>{html_value(res.empirical_rate)}</td><td>{html.escape(res.bound_text())}</td>"
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
        f"<p class='small'>{g.n_groups:,} test groups, {g.n_rows:,} rows; the mean share is bounded by "
        "betting "
        "bounds, the counts by Clopper-Pearson. Proofs: proofs/run_claims.md section 5, "
        "proofs/group_calibration.md section 6.</p>"
    )
    return parts


def _theorem1_section(cert: Certificate) -> list[str]:
    parts = ["<h2>Theorem 1 of the paper</h2>"]
    t1 = cert.theorem1
    if t1 is None:
        parts.append(f"<p><b>{html.escape(capitalized(cert.theorem1_reason))}.</b> Nothing is claimed.</p>")
        return parts
    cls = "ok" if t1.usable else "vacuous"
    verdict = html.escape(theorem1_verdict(t1.sound.vacuous))
    parts.append(f'<p class="{cls}"><b>Verdict: {verdict}.</b> {html.escape(t1.explanation())}</p>')

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
        html_table(rows),
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

    Parameters
    ----------
    result : CertifyResult
        What :func:`~ipcverify.certification.certify` returned.

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify import IPCModel
    >>> from ipcverify.network import ModelConfig
    >>> from ipcverify.certification import certify  # certify imports this module, not the other way round
    >>> m = example(config=ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")).model
    >>> page = render_report(certify(m, example(500, seed=2).data))
    >>> page.startswith("<!DOCTYPE html>") and "http" not in page
    True
    """
    cert = result.certificate
    summary = cert.summary if cert.summary is not None else summarize(cert)
    parts = page_header(cert, summary)
    parts += _calibration_section(cert.calibration)
    parts += _domain_section(cert)
    parts += _test_section(cert, result.evidence, summary)
    parts += _theorem1_section(cert)
    parts += _identity_section(cert)
    return "\n".join(parts)
