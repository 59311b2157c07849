"""The reproduction's ``report.html``: one self-contained page (figures as base64 PNG).

:func:`render_report` turns a ``summary.json`` dictionary and the figures' PNG bytes into
HTML that references nothing outside itself, so it can be archived and read offline.

Examples
--------
>>> page = render_report({"runtime_seconds": 1.0}, {})
>>> page.startswith("<!DOCTYPE html>") and "http" not in page
True
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["render_report"]

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;margin:2em auto;
padding:0 1em;color:#1d1d1f;line-height:1.45}
h1{font-size:1.6em} h2{font-size:1.25em;margin-top:1.8em;border-bottom:1px solid #ddd}
table{border-collapse:collapse;margin:.6em 0 1em} td,th{border:1px solid #ccc;padding:.25em .55em;
text-align:right;font-variant-numeric:tabular-nums} th{background:#f3f3f3} td.l,th.l{text-align:left}
.ok{color:#1b7f3b;font-weight:600} .no{color:#b42318;font-weight:600} .muted{color:#666}
img{max-width:100%} pre{background:#f6f6f6;padding:.6em;overflow-x:auto;font-size:.85em}
.box{background:#f7f9fc;border-left:4px solid #1b5e7f;padding:.5em 1em;margin:.8em 0}
"""


def _e(v: Any) -> str:
    return html.escape(str(v))


def _pct(v: Any, digits: int = 2) -> str:
    return "—" if v is None else f"{100 * float(v):.{digits}f} %"


def _num(v: Any, digits: int = 4) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    return f"{float(v):.{digits}g}"


def _interval(iv: Sequence[float] | None) -> str:
    return "—" if not iv else f"[{100 * iv[0]:.2f}, {100 * iv[1]:.2f}] %"


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]], left: int = 1) -> str:
    th = "".join(f'<th class="{"l" if i < left else ""}">{_e(h)}</th>' for i, h in enumerate(header))
    body = "".join(
        "<tr>" + "".join(f'<td class="{"l" if i < left else ""}">{c}</td>' for i, c in enumerate(r)) + "</tr>"
        for r in rows
    )
    return f"<table><tr>{th}</tr>{body}</table>"


def _img(figs: Mapping[str, bytes], name: str, alt: str) -> str:
    if name not in figs:
        return ""
    data = base64.b64encode(figs[name]).decode("ascii")
    return f'<p><img alt="{_e(alt)}" src="data:image/png;base64,{data}"></p>'


def _yes(v: Any) -> str:
    return '<span class="ok">yes</span>' if v else '<span class="no">no</span>'


def _claims(summary: Mapping[str, Any]) -> str:
    claims = summary.get("claims") or {}
    rows = [
        (_e(k.replace("_", " ")), _yes(c["holds"]), _yes(c["supported"]), _e(c["detail"]))
        for k, c in claims.items()
    ]
    if not rows:
        return ""
    return (
        "<h2>Acceptance claims</h2><p class='muted'>'holds': the point statement on the observed counts; "
        "'supported': what the sample sizes establish at 95 % confidence (Clopper–Pearson).</p>"
        + _table(["claim", "holds", "supported", "numbers"], rows)
    )


def _table1(summary: Mapping[str, Any], figs: Mapping[str, bytes]) -> str:
    rows = summary.get("table1")
    if not rows:
        return ""
    keys = sorted(rows, key=int)
    body = [
        (
            _e(k),
            _e(rows[k]["n"]),
            _e(rows[k]["violations"]),
            _pct(rows[k]["rate"]),
            _interval(rows[k]["interval"]),
            _pct(rows[k]["upper"]),
            _pct(rows[k].get("paper_rate")),
            _e(f"{rows[k].get('paths_with_violations', '—')} / {rows[k].get('paths', '—')}"),
        )
        for k in keys
    ]
    conf = rows[keys[0]]["confidence"]
    return (
        "<h2>Table I — the buffer-1 IPC at buffer sizes 1–5</h2>"
        "<p>Test sets flown on the same paths and approach flights at every buffer size; intervals "
        "and upper "
        f"bounds are exact (Clopper–Pearson), simultaneous over the rows at {100 * conf:.0f} %. They "
        "treat the "
        "10 Hz samples as independent; neighbouring samples on a path are correlated, so the intervals are "
        "somewhat optimistic (the last column shows over how many paths/flights the violations spread).</p>"
        + _table(
            [
                "buffer size",
                "n",
                "violations",
                "rate",
                "interval",
                "upper bound",
                "paper",
                "paths hit / paths",
            ],
            body,
        )
        + _img(figs, "table1", "Table I beside the paper")
    )


def _ipcs(summary: Mapping[str, Any]) -> str:
    ipcs = summary.get("ipc") or {}
    parts = []
    for name, info in ipcs.items():
        c, cert = info["calibration"], info["certificate"]
        rows = [
            ("buffer size", _e(info["buffer_size"])),
            ("parameters", _e(info["n_parameters"])),
            (
                "calibration",
                _e(f"{c['mode']}, epsilon {c['epsilon']:g}, delta {c['delta']:g}, n {c['n']}, k {c['k']}"),
            ),
            ("scale factor", _num(c["scale"])),
            ("certified epsilon", _num(c["certified_epsilon"])),
            ("certificate", _e(cert["status"])),
            (
                "test bound",
                _e(
                    f"{cert['test']['violations']}/{cert['test']['n']} violated; upper bound "
                    f"{cert['test']['upper_bound']:.4g} at confidence {1 - cert['test']['delta']:g}"
                ),
            ),
        ]
        parts.append(
            f"<h3>IPC {_e(name)}</h3>"
            + _table(["", ""], rows)
            + f"<p class='muted'>{_e(cert['statement'])}</p>"
        )
    return "<h2>The learned IPCs</h2>" + "".join(parts) if parts else ""


def _landing_rows(side: Mapping[str, Any]) -> list[str]:
    return [
        _e(side["runs"]),
        _e(side["safe"]),
        _e(side["unsafe"]),
        _e(side["aborted"]),
        _pct(side.get("unsafe_rate")),
        _interval(side.get("unsafe_interval")),
        _num(side.get("mean_queries"), 3),
    ]


def _landing(summary: Mapping[str, Any], figs: Mapping[str, bytes]) -> str:
    land = summary.get("landing")
    if not land:
        return ""
    ipc, base = land["ipc"], land["baseline"]
    paper = (summary.get("paper") or {}).get("landing", {})
    head = ["", "runs", "safe", "unsafe", "aborted", "unsafe rate", "95 % CP interval", "queries / run"]
    rows = [
        ["IPC, paper-style", *_landing_rows(ipc["paper_runs"])],
        ["baseline, paper-style", *_landing_rows(base["paper_runs"])],
        ["IPC, Monte Carlo", *_landing_rows(ipc)],
        ["baseline, Monte Carlo", *_landing_rows(base)],
    ]
    if paper:
        rows.append(
            [
                "paper: IPC / baseline",
                _e(paper["runs"]),
                _e(f"{paper['ipc_safe']} / {paper['runs'] - paper['baseline_unsafe']}"),
                _e(f"0 / {paper['baseline_unsafe']}"),
                "—",
                "—",
                "—",
                "—",
            ]
        )
    text = (
        f"<h2>Safe landing at buffer size {_e(land['buffer_size'])}</h2>"
        f"<p>Tracking tolerance tau = {1000 * land['tracking_tolerance']:.1f} mm, cap of "
        f"{land['max_measurements']} measurements per run. Safe: the position at the motor-off command is in "
        "{y} ⊕ G; aborted runs never count as safe. Both contracts fly the same scenarios.</p>"
        + _table(head, rows)
        + _img(figs, "topview", "top view of the paper-style runs")
        + _img(figs, "campaign", "motor-off offsets of the Monte Carlo runs")
        + _img(figs, "trajectories", "3-D trajectories")
    )
    return text


def _certified(summary: Mapping[str, Any], figs: Mapping[str, bytes]) -> str:
    land = summary.get("landing")
    if not land:
        return ""
    ipc = land["ipc"]
    b, ev, loop, cov = ipc["certified"], ipc["empirical_vs_certified"], land["closed_loop"], land["coverage"]
    rows = [
        (
            "certified bound M·eps (union over the queries of a run)",
            _num(b["union_bound"]),
            _e(f"{b['union_confidence']:.6g}"),
        ),
        ("refined bound eps·UCB(E[N])", _num(b["refined_bound"]), _e(f"{b['refined_confidence']:.6g}")),
        (
            "empirical unsafe rate (Monte Carlo)",
            _e(f"{ev['unsafe']}/{ev['runs']} = {_pct(ev.get('unsafe_rate'))}"),
            _e(_interval(ev.get("unsafe_interval"))),
        ),
    ]
    loop_rows = [
        (
            _e(name),
            _e(loop[name]["n"]),
            _e(loop[name]["violations"]),
            _pct(loop[name].get("rate")),
            _interval(loop[name].get("interval")),
            _e(loop[name].get("contradicts_epsilon", "—")),
        )
        for name in ("first", "accepted", "all")
    ]
    flag = cov.get("shift_detected")
    groups = cov.get("groups") or {}
    cov_rows = [
        (
            _e(g),
            _e(v["n"]),
            _e(v["exceed"]),
            _pct(v["rate"]),
            _interval(v["interval"]),
            _pct(cov["null_rate"]),
        )
        for g, v in groups.items()
    ]
    fr = cov.get("feature_range") or {}
    flag_text = (
        '<p class="no">Shift detected: the closed loop queries the IPC outside its domain of validity '
        "more often than the test's false-alarm rate explains. Those queries are answered "
        "OUTSIDE_DOMAIN and never accepted, so the landing never acts on them; the certified bound "
        "speaks only for the queries inside.</p>"
        if flag
        else '<p class="ok">No shift detected at 95 % confidence: the closed loop stays inside the '
        "IPC's domain of validity about as often as calibration-like samples do.</p>"
        if flag is not None
        else ""
    )
    return (
        "<h2>Certified vs empirical unsafe landings</h2>"
        f"<div class='box'><b>Assumption A.</b> {_e(b['assumption'])} Under it, an unsafe landing "
        "needs a violated "
        "accepted query (exact accept and cut tests; proofs/landing_safety.md), so P(unsafe) ≤ Σ_j P(query j "
        "made and violated) ≤ eps·E[N] ≤ eps·M.</div>"
        + _table(["quantity", "value", "confidence"], rows)
        + f"<p>eps = {_num(b['epsilon'])} (certified by the PAC calibration), M = {b['max_queries']}, "
        f"mean queries per run {_num(b['mean_queries'], 3)} (Hoeffding upper bound "
        f"{_num(b['mean_queries_upper'], 3)}).</p>"
        "<h3>The closed loop's own queries</h3><p>How often the truth was outside the IPC's set at "
        "the queries the "
        "state machine actually made; 'contradicts eps' is yes when the one-sided CP lower bound "
        "exceeds eps.</p>"
        + _table(["queries", "n", "violations", "rate", "95 % interval", "contradicts eps"], loop_rows)
        + "<h3>The closed loop and the IPC's domain of validity</h3>"
        "<p>The IPC's own domain test (fitted at calibration, the same one every query passes "
        "through): the whitened distance of each query to its nearest calibration input against the "
        f"test's threshold ({_num(cov['threshold'])}, false-alarm rate {_pct(cov['null_rate'])}).</p>"
        + (
            _table(
                ["queries", "n", "outside the domain", "rate", "95 % interval", "false-alarm rate"], cov_rows
            )
            if cov_rows
            else ""
        )
        + flag_text
        + (
            f"<p class='muted'>For comparison only, per-feature 0.5–99.5 % ranges of the calibration "
            f"data: {_pct(fr.get('queries_outside_any'))} of the queries and "
            f"{_pct(fr.get('test_outside_any'))} of the test samples have some feature outside a range "
            "(a range check alone does not decide: a query can be inside every range and far from all "
            "data).</p>"
            if fr
            else ""
        )
        + _img(figs, "coverage", "coverage histogram")
    )


def _buffer1(summary: Mapping[str, Any]) -> str:
    b1 = summary.get("landing_buffer1")
    if not b1:
        return ""
    head = ["", "runs", "safe", "unsafe", "aborted", "unsafe rate", "95 % CP interval", "queries / run"]
    rows = [
        ["IPC (learned at buffer 1)", *_landing_rows(b1["ipc"])],
        ["baseline", *_landing_rows(b1["baseline"])],
    ]
    return (
        "<h2>Control experiment: the same landing at buffer size 1</h2><p>With one frame of lag the "
        "perception "
        "error during the transit is about 2–3 cm, below G's 5 cm half-width: the baseline's failures at the "
        "landing buffer size come from the lag, not from the state machine.</p>" + _table(head, rows)
    )


def render_report(summary: Mapping[str, Any], figures: Mapping[str, bytes]) -> str:
    """The report page for ``summary`` (the content of ``summary.json``) with ``figures`` (name -> PNG).

    Parameters
    ----------
    summary : mapping
        As written by :func:`.pipeline.reproduce`; missing sections are left out.
    figures : mapping of str to bytes
        PNGs named ``table1``, ``topview``, ``campaign``, ``trajectories``, ``coverage``.
    """
    runtime = summary.get("runtime_seconds")
    quick = " (--quick sizes)" if summary.get("quick") else ""
    intro = (
        "<h1>Inverse perception contracts — quad-landing reproduction</h1>"
        "<p>A rerun of the application study of Sun, Yang and Mitra, <i>Learning-based Inverse Perception "
        "Contracts and Applications</i>, in simulation (case_studies/quad_landing), with certified "
        "bounds beside "
        f"the empirical rates{_e(quick)}. Command: <code>python -m case_studies.quad_landing "
        "reproduce --out DIR"
        f"{' --quick' if summary.get('quick') else ''}</code>; runtime {_e(runtime)} s on "
        f"{_e((summary.get('machine') or {}).get('cores_available', '?'))} cores.</p>"
    )
    settings = json.dumps(
        {k: summary.get(k) for k in ("settings", "seeds", "machine", "stage_seconds")}, indent=1
    )
    return (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>IPC reproduction</title>"
        f"<style>{_CSS}</style></head><body>"
        + intro
        + _claims(summary)
        + _table1(summary, figures)
        + _ipcs(summary)
        + _landing(summary, figures)
        + _certified(summary, figures)
        + _buffer1(summary)
        + f"<h2>Settings</h2><pre>{_e(settings)}</pre></body></html>"
    )
