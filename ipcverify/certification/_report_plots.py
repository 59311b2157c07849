"""The certificate page's plots, drawn with matplotlib's Agg canvas on private figures.

No global pyplot state: every function builds its own :class:`~matplotlib.figure.Figure`.
Every axis says what it measures and in which units: the coordinates of ``y`` carry the
user's labels and units (``ipcverify certify --labels ... --units ...``; default "units of the
data"), scores are dimensionless, counts and rates say what they count.

* :func:`plot_scores` -- the distribution of the test scores ``g / s`` with the boundary at 1;
* :func:`plot_coverage` -- the violation rate per bin of a column (conditional coverage) with
  per-bin Clopper--Pearson intervals;
* :func:`plot_projections` -- 2-D projections of a few calibrated ellipsoids with their truths.
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ipcverify.calibration._bounds import clopper_pearson_interval
from ipcverify.certification._certificate import CertifyEvidence
from ipcverify.certification._evaluation import BinCoverage
from ipcverify.certification._summary import DEFAULT_UNITS


def figure_to_png(fig: Figure, dpi: int = 100) -> bytes:
    """Render a figure with the Agg canvas to PNG bytes.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    dpi : int
        Resolution.

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
    """Histogram of the test scores ``g / s`` with the set boundary (1) marked.

    Parameters
    ----------
    evidence : CertifyEvidence
        The test scores.
    calibrated : bool
        Whether the model is calibrated: the boundary is then ``g / s = 1``, else ``g = 1``.
    """
    s = evidence.normalized_scores
    fig = Figure(figsize=(7.0, 3.2))
    ax = fig.add_subplot()
    hi = max(1.5, float(np.quantile(s, 0.995)) * 1.05)
    over = int((s > hi).sum())
    ax.hist(np.minimum(s, hi), bins=80, range=(0.0, hi), color="#4c72b0", alpha=0.85)
    ax.axvline(1.0, color="#b42318", lw=2, label="set boundary (g / s = 1)" if calibrated else "g = 1")
    ax.set_xlabel(
        "normalised score g / s (dimensionless; > 1: truth outside its set)"
        if calibrated
        else "raw score g (dimensionless; > 1: truth outside its set)"
    )
    ax.set_ylabel("test rows (count)")
    n_viol = int(evidence.violated.sum())
    title = f"Test scores: {n_viol:,} of {len(s):,} test rows outside"
    if over:
        title += f" ({over} beyond {hi:.3g}, drawn in the last bin)"
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.16, top=0.9)
    return fig


def plot_coverage(coverage: BinCoverage, delta: float, epsilon: float | None) -> Figure:
    """Violation rate per bin of a column, with two-sided Clopper--Pearson intervals at ``delta`` per bin.

    Parameters
    ----------
    coverage : BinCoverage
        Violations per bin.
    delta : float
        Confidence parameter of the intervals.
    epsilon : float or None
        The calibration's target, drawn as a line (None: no line).
    """
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
    # a text column's bins are its values; a numeric one's are ranges in the data's units
    ax.set_xlabel(f"bin of {coverage.column}" + ("" if coverage.labels else f" ({DEFAULT_UNITS})"))
    ax.set_ylabel("violation rate (share of rows)")
    # headroom above the highest interval (or epsilon) for the legend, which must not hide an interval
    tops = [*hi[ok][np.isfinite(hi[ok])], *([] if epsilon is None else [epsilon])]
    ax.set_ylim(0.0, 1.45 * max(tops) if tops and max(tops) > 0 else None)
    ax.set_title(f"Conditional coverage by {coverage.column}", fontsize=10)
    ax.legend(fontsize=8, loc="upper right", ncol=2)
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.3, top=0.9)
    return fig


def ellipse_outline(center: np.ndarray, shape: np.ndarray, i: int, j: int) -> np.ndarray:
    """Boundary of the projection of E(c, C) on coordinates (i, j), as (2, 200) points.

    Parameters
    ----------
    center : ndarray, shape (n,)
        The centre ``c``.
    shape : ndarray, shape (n, n)
        The shape matrix ``C``.
    i, j : int
        The coordinates to project on.
    """
    cinv = np.linalg.inv(shape)
    P = cinv @ cinv.T
    sub = P[np.ix_([i, j], [i, j])]
    L = np.linalg.cholesky(sub + 1e-300 * np.eye(2))
    t = np.linspace(0.0, 2.0 * np.pi, 200)
    return center[[i, j], None] + L @ np.vstack([np.cos(t), np.sin(t)])


def plot_projections(evidence: CertifyEvidence, axis_labels: Sequence[str] = ()) -> Figure:
    """2-D projections of the example ellipsoids with their truths (x) and estimates (+).

    ``axis_labels`` names every coordinate of ``y`` with its unit (``"forward [m]"``); default:
    the data's column names in "units of the data".

    Parameters
    ----------
    evidence : CertifyEvidence
        The examples.
    axis_labels : sequence of str
        See above.
    """
    k = len(evidence.example_index)
    n = evidence.example_centers.shape[1]
    names = tuple(axis_labels) or tuple(
        f"{c} ({DEFAULT_UNITS})" for c in (evidence.y_columns or tuple(f"y_{i}" for i in range(n)))
    )
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
                ax.get_yaxis().set_visible(False)  # a 1-D set: the vertical axis measures nothing
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
                    f"test row {int(evidence.example_index[r])} (0-based), "
                    f"{'inside' if inside else 'OUTSIDE'}",
                    fontsize=8,
                    loc="left",
                )
    fig.suptitle("Calibrated sets (projections); x = ground truth, + = perceived value", fontsize=10)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.06, top=0.93, wspace=0.45, hspace=0.5)
    return fig
