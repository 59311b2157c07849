"""Figures of the reproduction, drawn on private matplotlib figures (no pyplot state).

* :func:`plot_topview` — the paper's 2-D figure: every run translated so the pad is at
  the origin; crosses where the baseline cut the motors, stars where the IPC did, circles
  at the IPC's measurements sized by their ellipsoids; with a zoom on ``G``.
* :func:`plot_campaign` — the Monte Carlo analogue: every run's motor-off offset.
* :func:`plot_table1` — Table I with Clopper--Pearson intervals beside the paper's numbers.
* :func:`plot_trajectories` — a few runs in 3-D.
* :func:`plot_coverage` — nearest-neighbour distances of closed-loop queries vs test data.
* :func:`plot_ablation` — Table I of every error source alone and removed, beside the paper's.
* :func:`plot_ages` — how old the test images are at each buffer size.

Every figure that shows where the motors were cut draws the target region ``G`` around the
pad at the origin. :func:`figure_png` renders a figure to PNG bytes with the Agg canvas;
:func:`draw_figures` draws all of a reproduction's.

Examples
--------
>>> from case_studies.quad_landing.reproduction.table1 import Table1, Table1Row
>>> row = Table1Row(buffer_size=1, n=1000, violations=1, rate=0.001, upper=0.004, interval=(0.0, 0.004),
...                 confidence=0.95, paper_rate=0.0019, paths=None, paths_with_violations=None)
>>> figure_png(plot_table1(Table1((row,))))[:4] == b"\\x89PNG"
True
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle

from case_studies.quad_landing.landing.runs import LandingRun, Outcome
from case_studies.quad_landing.landing.state_machine import LandingParams
from case_studies.quad_landing.reproduction.coverage import CoverageCheck
from case_studies.quad_landing.reproduction.table1 import PAPER_TABLE1, Table1
from case_studies.quad_landing.reproduction.variants import SOURCE_LABELS, VariantStudy, VariantTable
from case_studies.quad_landing.sim.camera import SOURCES

__all__ = [
    "figure_png",
    "plot_topview",
    "plot_campaign",
    "plot_table1",
    "plot_trajectories",
    "plot_coverage",
    "plot_ablation",
    "plot_ages",
    "draw_figures",
]

_COLORS = [
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
]


def figure_png(fig: Figure, dpi: int = 90) -> bytes:
    """PNG bytes of ``fig`` (Agg canvas, tight bounding box)."""
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def _g_box(ax: Any, scale: float = 100.0) -> None:
    target = LandingParams.defaults().target
    lo, hi = target.lower * scale, target.upper * scale
    ax.add_patch(
        Rectangle(
            (lo[0], lo[1]),
            hi[0] - lo[0],
            hi[1] - lo[1],
            fill=False,
            ls="--",
            lw=1.2,
            color="black",
            label="G (x-y)",
        )
    )


def _color(i: int) -> str:
    return _COLORS[i % len(_COLORS)]


def plot_topview(ipc: Sequence[LandingRun], baseline: Sequence[LandingRun]) -> Figure:
    """The paper's 2-D figure for paired runs (same scenarios), pad at the origin.

    Left: the IPC runs' paths, their measurements (circle area grows with the ellipsoid's
    horizontal half-width) and where each contract cut the motors. Right: the same cut
    positions in centimetres around ``G``.
    """
    fig = Figure(figsize=(11, 5.2))
    ax, zoom = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.15, 1]})
    for i, run in enumerate(ipc):
        c, pad = _color(i), run.pad
        traj = run.trajectory - pad
        ax.plot(traj[:, 0], traj[:, 1], color=c, lw=0.8, alpha=0.6)
        for q in run.queries:
            if q.half_widths is None:
                continue
            p = q.position - pad
            ax.scatter(
                p[0],
                p[1],
                s=40 + 4000 * float(np.max(q.half_widths[:2])),
                facecolors="none",
                edgecolors=c,
                lw=1.0,
            )
        if run.cut_position is not None:
            off = run.cut_position - pad
            ax.scatter(off[0], off[1], marker="*", s=120, color=c, edgecolors="black", lw=0.4, zorder=5)
            zoom.scatter(
                100 * off[0], 100 * off[1], marker="*", s=150, color=c, edgecolors="black", lw=0.4, zorder=5
            )
    for i, run in enumerate(baseline):
        if run.cut_position is not None:
            off = run.cut_position - run.pad
            mark = "v" if run.hit_pad else "x"  # into the pad: where it hit it
            ax.scatter(off[0], off[1], marker=mark, s=60, color=_color(i), lw=1.8, zorder=4)
            zoom.scatter(100 * off[0], 100 * off[1], marker=mark, s=80, color=_color(i), lw=2.0, zorder=4)
    ax.scatter([0], [0], marker="s", s=60, color="black", zorder=6)
    _g_box(ax, scale=1.0)
    ax.set_aspect("equal")
    ax.set_xlabel("x - y_x (m)")
    ax.set_ylabel("y - y_y (m)")
    ax.set_title("runs, pad at the origin")
    handles = [
        Line2D([], [], marker="*", ls="", color="gray", markersize=11, label="IPC: motors off"),
        Line2D([], [], marker="x", ls="", color="gray", markersize=8, mew=2, label="baseline: motors off"),
        Line2D([], [], marker="v", ls="", color="gray", markersize=8, label="baseline: flew into the pad"),
        Line2D(
            [],
            [],
            marker="o",
            ls="",
            mfc="none",
            color="gray",
            markersize=9,
            label="IPC measurement (size ~ ellipsoid)",
        ),
        Line2D([], [], marker="s", ls="", color="black", label="pad"),
        Line2D([], [], ls="--", color="black", label="G around the pad"),
    ]
    ax.legend(handles=handles, loc="best", fontsize=8)
    _g_box(zoom)
    zoom.set_aspect("equal")
    lim = 12.0
    offs = [
        100 * np.abs(r.cut_position - r.pad)[:2].max()
        for r in [*ipc, *baseline]
        if r.cut_position is not None
    ]
    if offs:
        lim = max(lim, 1.1 * max(offs))
    zoom.set_xlim(-lim, lim)
    zoom.set_ylim(-lim, lim)
    zoom.set_xlabel("x - y_x (cm)")
    zoom.set_ylabel("y - y_y (cm)")
    zoom.set_title("where the motors were cut or the pad was hit (dashed: G)")
    zoom.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def plot_campaign(ipc: Sequence[LandingRun], baseline: Sequence[LandingRun]) -> Figure:
    """Motor-off offsets of every Monte Carlo run (cm), horizontal and vertical, with ``G``.

    A run that flew into the pad is drawn where it hit the pad (a triangle).
    """
    fig = Figure(figsize=(11, 4.6))
    top, side = fig.subplots(1, 2)
    for runs, marker, color, label in ((baseline, "x", "#d62728", "baseline"), (ipc, "*", "#1f77b4", "IPC")):
        counts = {o: sum(1 for r in runs if r.outcome is o) for o in Outcome}
        into = sum(1 for r in runs if r.hit_pad)
        text = (
            f"{label}: {counts[Outcome.SAFE]} safe, {counts[Outcome.UNSAFE]} unsafe"
            + (f" ({into} into the pad)" if into else "")
            + f", {counts[Outcome.ABORTED]} aborted"
        )
        labelled = False  # one legend entry per contract, on its first non-empty group
        for hit, mark in ((False, marker), (True, "v")):
            off = np.array(
                [100 * r.offset for r in runs if r.offset is not None and r.hit_pad == hit]
            ).reshape(-1, 3)
            if not len(off):
                continue
            size = 40 if mark == "*" else 25
            top.scatter(
                off[:, 0],
                off[:, 1],
                marker=mark,
                s=size,
                color=color,
                alpha=0.7,
                label=None if labelled else text,
            )
            side.scatter(
                np.hypot(off[:, 0], off[:, 1]), off[:, 2], marker=mark, s=size, color=color, alpha=0.7
            )
            labelled = True
    _g_box(top)
    top.set_aspect("equal")
    top.set_xlabel("x - y_x (cm)")
    top.set_ylabel("y - y_y (cm)")
    top.set_title("motor-off position (triangles: pad hit), top view (dashed: G)")
    top.legend(fontsize=8, loc="upper left")
    top.grid(alpha=0.3)
    target = LandingParams.defaults().target
    lo, hi = 100 * target.lower[2], 100 * target.upper[2]
    side.axhspan(lo, hi, color="green", alpha=0.12, label="G (z)")
    side.axvline(5.0, color="black", ls="--", lw=1.0, label="5 cm")
    side.set_xlabel("horizontal distance to the pad centre (cm)")
    side.set_ylabel("height above the pad (cm)")
    side.set_title("motor-off position (triangles: pad hit), side view")
    side.legend(fontsize=8)
    side.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def plot_table1(table: Table1) -> Figure:
    """Violation rate per buffer size (log scale) with Clopper--Pearson intervals, and the paper's.

    A zero rate is drawn as a downward triangle at its upper bound.
    """
    fig = Figure(figsize=(6.4, 4.2))
    ax = fig.subplots()
    ks = list(table.buffers)
    floor = 1e-4
    for r in table.rows:
        k = r.buffer_size
        lo, hi = r.interval
        if r.rate > 0:
            ax.errorbar(
                [k - 0.06],
                [r.rate],
                yerr=[[r.rate - max(lo, floor)], [hi - r.rate]],
                fmt="o",
                color="#1f77b4",
                capsize=4,
            )
        else:
            ax.plot([k - 0.06], [r.upper], marker="v", color="#1f77b4", ls="")
            ax.vlines(k - 0.06, floor, r.upper, color="#1f77b4")
    paper = [(r.buffer_size, r.paper_rate) for r in table.rows if r.paper_rate is not None]
    ax.plot(
        [k + 0.06 for k, _ in paper], [v for _, v in paper], "s", color="#ff7f0e", label="paper (Table I)"
    )
    ax.plot([], [], "o", color="#1f77b4", label="this reproduction (CP interval)")
    ax.set_yscale("log")
    ax.set_ylim(floor, 1.0)
    ax.set_xticks(ks)
    ax.set_xlabel("camera buffer size (V4L2 buffers)")
    ax.set_ylabel("violation rate of the buffer-1 IPC")
    ax.set_title("Table I: the IPC learned at buffer size 1, tested at 1-5")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    return fig


def plot_trajectories(ipc: Sequence[LandingRun], baseline: Sequence[LandingRun], count: int = 3) -> Figure:
    """A few paired runs in 3-D (pad at the origin): IPC solid, baseline dashed."""
    fig = Figure(figsize=(7.5, 6))
    ax = fig.add_subplot(projection="3d")
    for i, (a, b) in enumerate(zip(ipc[:count], baseline[:count], strict=False)):
        c = _color(i)
        for run, ls in ((a, "-"), (b, "--")):
            t = run.trajectory - run.pad
            ax.plot(t[:, 0], t[:, 1], t[:, 2], ls=ls, color=c, lw=1.2)
        for q in a.queries:
            p = q.position - a.pad
            ax.scatter([p[0]], [p[1]], [p[2]], color=c, s=30, marker="o", edgecolors="black", lw=0.4)
        for run, m in ((a, "*"), (b, "x")):
            if run.cut_position is not None:
                o = run.cut_position - run.pad
                ax.scatter([o[0]], [o[1]], [o[2]], color=c, s=80, marker=m)
    ax.scatter([0], [0], [0], color="black", marker="s", s=40)
    g = LandingParams.defaults().target
    xs, ys = (
        [g.lower[0], g.upper[0], g.upper[0], g.lower[0], g.lower[0]],
        [g.lower[1], g.lower[1], g.upper[1], g.upper[1], g.lower[1]],
    )
    for z in (g.lower[2], g.upper[2]):
        ax.plot(xs, ys, [z] * 5, color="black", ls="--", lw=0.8)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title("3-D paths: IPC (solid, dots = measurements) vs baseline (dashed); G dashed at the pad")
    return fig


def plot_coverage(coverage: CoverageCheck) -> Figure:
    """Histogram of the domain test's distances: held-out test data vs closed-loop queries."""
    fig = Figure(figsize=(6.4, 3.8))
    ax = fig.subplots()
    dist = coverage.distances
    if dist:
        test, q = np.asarray(dist["test"]), np.asarray(dist["queries"])
        top = float(max(test.max(initial=0), q.max(initial=0)))
        bins = np.linspace(0, top * 1.01 + 1e-9, 40).tolist()
        ax.hist(
            test,
            bins=bins,
            density=True,
            alpha=0.5,
            label="held-out test samples (drawn like the calibration data)",
        )
        ax.hist(q, bins=bins, density=True, alpha=0.5, label="closed-loop IPC queries")
        ax.axvline(
            coverage.threshold,
            color="black",
            ls="--",
            lw=1,
            label="domain threshold",
        )
    ax.set_xlabel("distance to the nearest calibration input (whitened)")
    ax.set_ylabel("density")
    ax.set_title("domain of validity: do the closed loop's queries look like the calibration data?")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


#: Colours of the error sources in the ablation figure (the same in both panels).
_SOURCE_COLORS = dict(zip(SOURCES, _COLORS, strict=False))


def _rates(row: VariantTable, floor: float) -> tuple[list[int], list[float]]:
    ks = list(row.table.buffers)
    return ks, [max(row.table.row(k).rate, floor) for k in ks]


def plot_ablation(study: VariantStudy) -> Figure:
    """Table I of each error source alone (left) and removed (right), with all sources and the paper.

    Rates of zero are drawn at the bottom of the log axis. "Alone" means the driver queue plus
    that source: without the queue the buffer size changes nothing.
    """
    fig = Figure(figsize=(11, 5.4))
    axes = fig.subplots(1, 2, sharey=True)
    floor = 1e-3
    ref = {r.name: r for r in study.rows if r.group == "reference"}
    for ax, group, title in ((axes[0], "alone", "each source alone (with the driver queue)"),
                             (axes[1], "removed", "each source removed (all others on)")):  # fmt: skip
        for r in study.rows:
            if r.group != group:
                continue
            source = r.name.split("+")[-1].removeprefix("no-")
            ks, v = _rates(r, floor)
            label = SOURCE_LABELS.get(source, r.label) if source != "queue" else "driver queue"
            ax.plot(ks, v, "o-", color=_SOURCE_COLORS.get(source, "gray"), lw=1.2, ms=4, label=label)
        if "all" in ref:
            ks, v = _rates(ref["all"], floor)
            ax.plot(ks, v, "k-", lw=2.4, label="all sources")
        if "frames" in ref:
            ks, v = _rates(ref["frames"], floor)
            ax.plot(ks, v, "k:", lw=1.6, label="previous model (fixed b-frame lag)")
        paper = sorted(PAPER_TABLE1.items())
        ax.plot([k for k, _ in paper], [p for _, p in paper], "s--", color="#ff7f0e", lw=1.6, label="paper")
        ax.set_yscale("log")
        ax.set_ylim(floor * 0.8, 1.0)
        ax.set_xticks(range(1, 6))
        ax.set_xlabel("camera buffer size")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("violation rate (rates of 0 at the bottom)")
    handles, labels = axes[1].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0.0, 0.14, 1.0, 1.0))
    return fig


def plot_ages(frames: Mapping[str, pd.DataFrame], buffers: Sequence[int], period_ms: float) -> Figure:
    """How much older each test image is than the state paired with it, per buffer size."""
    fig = Figure(figsize=(6.4, 3.8))
    ax = fig.subplots()
    data = [1e3 * frames[f"pilot_k{b}"]["age"].to_numpy(float) for b in buffers]
    ax.boxplot(data, positions=list(buffers), whis=(5, 95), showfliers=True, flierprops={"markersize": 2})
    for j in range(1, 7):
        ax.axhline(j * period_ms, color="gray", lw=0.6, ls=":")
    ax.set_xlabel("camera buffer size")
    ax.set_ylabel("image age (ms); dotted: camera periods")
    ax.set_title("age of the test images (box: quartiles, whiskers: 5-95 %)")
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    return fig


def draw_figures(
    table: Table1,
    ablation: VariantStudy,
    paper_ipc: Sequence[LandingRun],
    paper_baseline: Sequence[LandingRun],
    mc_ipc: Sequence[LandingRun],
    mc_baseline: Sequence[LandingRun],
    coverage: CoverageCheck,
    frames: Mapping[str, pd.DataFrame],
    buffers: Sequence[int],
    period_ms: float = 1e3 / 60.0,
) -> dict[str, bytes]:
    """Every figure of a reproduction as PNG bytes, by name."""
    return {
        "table1": figure_png(plot_table1(table)),
        "ablation": figure_png(plot_ablation(ablation)),
        "ages": figure_png(plot_ages(frames, buffers, period_ms)),
        "topview": figure_png(plot_topview(paper_ipc, paper_baseline)),
        "campaign": figure_png(plot_campaign(mc_ipc, mc_baseline)),
        "trajectories": figure_png(plot_trajectories(paper_ipc, paper_baseline)),
        "coverage": figure_png(plot_coverage(coverage)),
    }
