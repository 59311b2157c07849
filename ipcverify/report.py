"""The certificate as one self-contained HTML page (plots embedded as base64 PNG).

The page references no external resource (no scripts, styles, fonts or images
from the network), so it can be archived and opened offline. Plots are drawn with
matplotlib's Agg canvas on private :class:`~matplotlib.figure.Figure` objects
(no global pyplot state):

* the distribution of the test scores ``g / s`` with the calibrated boundary at 1;
* the violation rate per bin of a column (conditional coverage) with per-bin
  Clopper--Pearson intervals;
* 2-D projections of a few calibrated ellipsoids with their ground truths.
"""

from __future__ import annotations

import base64
import html
import io
import math
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ipcverify.bounds import clopper_pearson_interval
from ipcverify.calibration.protocol import CalibrationSummary
from ipcverify.certificate import Certificate, CertificateStatus, CertifyEvidence, CertifyResult, Consistency
from ipcverify.evaluation import BinCoverage

__all__ = [
    "figure_to_png",
    "ellipse_outline",
    "plot_scores",
    "plot_coverage",
    "plot_projections",
    "render_report",
]

_COLORS = {
    CertificateStatus.CERTIFIED: "#1b7f3b",
    CertificateStatus.UNTESTED: "#1b5e7f",
    CertificateStatus.UNCHECKED: "#1b5e7f",
    CertificateStatus.NOT_CALIBRATED: "#9a6700",
    CertificateStatus.CONTRADICTED: "#b42318",
}


def figure_to_png(fig: Figure, dpi: int = 100) -> bytes:
    """Render a figure with the Agg canvas to PNG bytes.

    Examples
    --------
    >>> fig = Figure(figsize=(2, 1)); _ = fig.add_subplot().plot([0, 1])
    >>> figure_to_png(fig)[:8] == b"\\x89PNG\\r\\n\\x1a\\n"
    True
    """
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def plot_scores(evidence: CertifyEvidence, calibrated: bool) -> Figure:
    """Histogram of the test scores ``g / s`` with the set boundary (1) marked."""
    s = evidence.normalized_scores
    fig = Figure(figsize=(7.0, 3.2))
    ax = fig.add_subplot()
    hi = max(1.5, float(np.quantile(s, 0.995)) * 1.05)
    over = int((s > hi).sum())
    ax.hist(np.minimum(s, hi), bins=80, range=(0.0, hi), color="#4c72b0", alpha=0.85)
    ax.axvline(1.0, color="#b42318", lw=2, label="set boundary (g / s = 1)" if calibrated else "g = 1")
    ax.set_xlabel("normalised score g / s  (> 1: truth outside its set)" if calibrated else "raw score g")
    ax.set_ylabel("test samples")
    n_viol = int(evidence.violated.sum())
    title = f"Test scores: {n_viol} of {len(s)} outside"
    if over:
        title += f" ({over} beyond {hi:.3g}, drawn in the last bin)"
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.16, top=0.9)
    return fig


def plot_coverage(coverage: BinCoverage, delta: float, epsilon: float | None) -> Figure:
    """Violation rate per bin of a column, with two-sided Clopper--Pearson intervals at ``delta`` per bin."""
    fig = Figure(figsize=(7.0, 3.2))
    ax = fig.add_subplot()
    counts = np.asarray(coverage.counts)
    viol = np.asarray(coverage.violations)
    pos = np.arange(len(counts))
    rates = np.array([v / c if c else np.nan for v, c in zip(viol, counts, strict=True)])
    lo = np.array(
        [
            clopper_pearson_interval(int(v), int(c), delta)[0] if c else np.nan
            for v, c in zip(viol, counts, strict=True)
        ]
    )
    hi = np.array(
        [
            clopper_pearson_interval(int(v), int(c), delta)[1] if c else np.nan
            for v, c in zip(viol, counts, strict=True)
        ]
    )
    ok = counts > 0
    ax.errorbar(
        pos[ok],
        rates[ok],
        yerr=np.vstack([rates[ok] - lo[ok], hi[ok] - rates[ok]]),
        fmt="o",
        color="#4c72b0",
        capsize=3,
        label=f"violation rate, {1 - delta:.4g} interval per bin",
    )
    if epsilon is not None:
        ax.axhline(epsilon, color="#b42318", ls="--", label=f"epsilon = {epsilon:g}")
    ax.set_xticks(pos, coverage.bin_names(), rotation=35, ha="right", fontsize=7)
    ax.set_xlabel(f"bin of {coverage.column}")
    ax.set_ylabel("violation rate")
    ax.set_ylim(bottom=0.0)
    ax.set_title(f"Conditional coverage by {coverage.column}", fontsize=10)
    ax.legend(fontsize=8, loc="upper right")
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.3, top=0.9)
    return fig


def ellipse_outline(center: np.ndarray, shape: np.ndarray, i: int, j: int) -> np.ndarray:
    """Boundary of the projection of E(c, C) on coordinates (i, j), as (2, 200) points."""
    cinv = np.linalg.inv(shape)
    P = cinv @ cinv.T
    sub = P[np.ix_([i, j], [i, j])]
    L = np.linalg.cholesky(sub + 1e-300 * np.eye(2))
    t = np.linspace(0.0, 2.0 * np.pi, 200)
    return center[[i, j], None] + L @ np.vstack([np.cos(t), np.sin(t)])


def plot_projections(evidence: CertifyEvidence) -> Figure:
    """2-D projections of the example ellipsoids with their truths (x) and estimates (+)."""
    k = len(evidence.example_index)
    n = evidence.example_centers.shape[1]
    names = evidence.y_columns or tuple(f"y_{i}" for i in range(n))
    pairs = [(0, 1), (0, 2), (1, 2)] if n >= 3 else ([(0, 1)] if n == 2 else [(0, 0)])
    fig = Figure(figsize=(3.0 * len(pairs), 2.6 * k))
    for r in range(k):
        c, C = evidence.example_centers[r], evidence.example_shapes[r]
        y, yh = evidence.example_truths[r], evidence.example_estimates[r]
        inside = np.linalg.norm(C @ (y - c)) <= 1.0
        for col, (i, j) in enumerate(pairs):
            ax = fig.add_subplot(k, len(pairs), r * len(pairs) + col + 1)
            if n == 1:
                h = 1.0 / abs(C[0, 0])
                ax.plot([c[0] - h, c[0] + h], [0, 0], color="#4c72b0", lw=3)
                ax.plot([y[0]], [0], "x", color="#b42318" if not inside else "#1b7f3b", ms=9)
                ax.plot([yh[0]], [0], "+", color="k", ms=9)
                ax.set_yticks([])
                ax.set_xlabel(names[0], fontsize=8)
            else:
                pts = ellipse_outline(c, C, i, j)
                ax.fill(pts[0], pts[1], color="#4c72b0", alpha=0.25)
                ax.plot(pts[0], pts[1], color="#4c72b0", lw=1)
                ax.plot([y[i]], [y[j]], "x", color="#1b7f3b" if inside else "#b42318", ms=9, mew=2)
                ax.plot([yh[i]], [yh[j]], "+", color="k", ms=9)
                ax.set_xlabel(names[i], fontsize=8)
                ax.set_ylabel(names[j], fontsize=8)
                ax.set_aspect("equal", adjustable="datalim")
            ax.tick_params(labelsize=7)
            if col == 0:
                ax.set_title(
                    f"test sample {int(evidence.example_index[r])} ({'inside' if inside else 'OUTSIDE'})",
                    fontsize=8,
                    loc="left",
                )
    fig.suptitle("Calibrated sets (projections); x = ground truth, + = perceived value", fontsize=10)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.06, top=0.93, wspace=0.45, hspace=0.5)
    return fig


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
body{font-family:-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;max-width:980px;margin:2em auto;
padding:0 1em;color:#1f2328;line-height:1.45}
h1{font-size:1.6em;margin-bottom:.2em}h2{font-size:1.2em;border-bottom:1px solid #d0d7de;padding-bottom:.2em;
margin-top:1.6em}
.status{color:#fff;padding:.5em .8em;border-radius:6px;font-weight:600}
.statement{font-size:1.08em;background:#f6f8fa;border-left:4px solid #4c72b0;padding:.7em 1em;margin:1em 0}
table{border-collapse:collapse;margin:.5em 0}
th,td{border:1px solid #d0d7de;padding:.25em .6em;text-align:left;font-size:.92em}
th{background:#f6f8fa;font-weight:600}
.vacuous{color:#b42318;font-weight:600}.ok{color:#1b7f3b;font-weight:600}
img{max-width:100%;display:block;margin:.6em 0}.small{font-size:.85em;color:#57606a}
code{background:#f6f8fa;padding:0 .25em;border-radius:3px}
"""


def _header(cert: Certificate) -> list[str]:
    color = _COLORS[cert.status]
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        "<title>ipcverify certificate</title>",
        f"<style>{_CSS}</style></head><body>",
        "<h1>Inverse perception contract: certificate</h1>",
        f'<p class="status" style="background:{color}">{html.escape(cert.status.value)}</p>',
        "<h2>What is guaranteed</h2>",
        f'<p class="statement">{html.escape(cert.statement)}</p>',
    ]
    if cert.test_bound_note:
        parts.append(f"<p>{html.escape(cert.test_bound_note)}</p>")
    parts.append(
        '<p class="small">Assumption behind every statement on this page: the calibration samples, the '
        "test samples and the samples met in deployment are exchangeable (for example, drawn i.i.d. from "
        "the same distribution), and none of them was used for training. Nothing here holds under "
        "distribution shift; the domain-of-validity test below flags queries unlike the calibration "
        "data.</p>"
    )
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
    parts.append(
        _table(
            [
                ("method", d.method),
                ("false-alarm rate alpha", d.alpha),
                ("threshold (whitened distance)", d.threshold),
                ("calibration inputs (reference)", d.n_reference),
                ("queries checked", d.n),
                ("queries outside", d.outside),
            ]
        )
    )
    return parts


def _test_section(cert: Certificate, ev: CertifyEvidence | None) -> list[str]:
    t = cert.test
    parts = ["<h2>Test set</h2>"]
    if t is None or ev is None or cert.volume is None:
        parts.append(
            "<p><b>No test data was given.</b> The calibration certificate above does not need one, but "
            "nothing on this page checks it independently: run <code>ipcverify certify MODEL --data "
            "TEST</code> with fresh held-out samples.</p>"
        )
        return parts
    rows: list[tuple[str, Any]] = [
        ("test samples", t.n),
        ("violations", t.violations),
        ("empirical violation rate", t.empirical_rate),
        (f"upper bound (Clopper-Pearson, confidence {1 - t.delta:.6g})", t.upper_bound),
        (f"two-sided interval ({1 - t.delta:.6g})", f"[{t.interval[0]:.4g}, {t.interval[1]:.4g}]"),
        ("mean log-volume of the sets", cert.volume.mean_log),
        ("median log-volume", cert.volume.median_log),
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
        "<p class='small'>The smallest, median and largest set of the test data, and one violated sample "
        "(if any), projected on pairs of coordinates of y. A truth outside the n-dimensional set can "
        "still lie inside some, or even all, of its 2-D shadows.</p>"
    )
    parts.append(_img(plot_projections(ev), "projections of example ellipsoids"))
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
        ("sample", "one random sample of the group (seeded)", g.sample),
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
        f"<p class='small'>{g.n_groups:,} test groups, {g.n_rows:,} rows; the random sample of each group "
        f"is drawn with seed {g.seed}. Proof: proofs/group_calibration.md, section 6.</p>"
    )
    return parts


def _theorem1_section(cert: Certificate) -> list[str]:
    parts = ["<h2>Theorem 1 of the paper</h2>"]
    t1 = cert.theorem1
    if t1 is None:
        parts.append(f"<p><b>{html.escape(cert.theorem1_reason.capitalize())}.</b> Nothing is claimed.</p>")
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
        "<code>certificate.json</code> beside this file.</p></body></html>",
    ]


def render_report(result: CertifyResult) -> str:
    """The full HTML page for a certification result (a string; no external resources).

    Examples
    --------
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> from ipcverify.model import IPCModel, IPCNetwork
    >>> from ipcverify.architecture import ModelConfig
    >>> from ipcverify.certify import certify  # certify imports this module, not the other way round
    >>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")))
    >>> page = render_report(certify(m, make_lagged_perception(500, seed=2)))
    >>> page.startswith("<!DOCTYPE html>") and "http" not in page
    True
    """
    cert = result.certificate
    parts = _header(cert)
    parts += _calibration_section(cert.calibration)
    parts += _domain_section(cert)
    parts += _test_section(cert, result.evidence)
    parts += _theorem1_section(cert)
    parts += _identity_section(cert)
    return "\n".join(parts)
