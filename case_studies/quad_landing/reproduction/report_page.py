"""The reproduction's ``report.html``: a results section, self-contained (figures as base64 PNG).

:func:`render_report` turns a ``summary.json`` dictionary and the figures' PNG bytes into one
HTML page written like the results section of a paper: what was done, the claims in words
with what the statistics support, Table I beside the paper's, which error source makes which
part of it, the landing experiment, and the certified bound beside the empirical rate. The
page embeds its figures and links the full numbers (``summary.json``, beside it) instead of
dumping them.

Examples
--------
>>> page = render_report({"runtime_seconds": 1.0}, {})
>>> page.startswith("<!DOCTYPE html>") and "http" not in page and 'href="summary.json"' in page
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from case_studies.quad_landing.reproduction.html_parts import CSS, esc, figure, interval, num, pct, table, yes
from case_studies.quad_landing.reproduction.markdown import unsafe_cell
from case_studies.quad_landing.reproduction.report_contracts import contracts_section, why_not_held

__all__ = ["render_report"]


def _claims(summary: Mapping[str, Any]) -> str:
    claims = summary.get("claims") or {}
    default = (summary.get("contracts") or {}).get("default_calibrated") or {}
    quick = bool(summary.get("quick"))

    def numbers(k: str, c: Mapping[str, Any]) -> str:
        if c["holds"] or not default:
            return esc(c["detail"])
        return (
            esc(c["detail"]) + f"<br><span class='muted'>why: {esc(why_not_held(k, default, quick))}</span>"
        )

    rows = [
        (esc(c.get("statement") or k.replace("_", " ")), yes(c["holds"]), yes(c["supported"]), numbers(k, c))
        for k, c in claims.items()
    ]
    if not rows:
        return ""
    return (
        "<h2>Claims of ipcverify's default contract (default_calibrated)</h2>"
        "<p>Each claim is checked twice: <i>holds</i> reads it off the observed counts; "
        "<i>supported</i> asks whether the sample sizes establish it at 95 % confidence (exact "
        "Clopper–Pearson bounds).</p>"
        + table(["claim", "holds", "supported by the statistics", "numbers"], rows, text=(0, 3))
    )


def _table1(summary: Mapping[str, Any], figs: Mapping[str, bytes]) -> str:
    rows = summary.get("table1")
    if not rows:
        return ""
    keys = sorted(rows, key=int)
    proto = summary.get("table1_protocol") or {}
    speed = (proto.get("speed_m_s") or {}).get("pilot") or {}
    conf = rows[keys[0]]["confidence"]
    body = [
        (
            esc(k),
            esc(rows[k]["n"]),
            esc(rows[k]["violations"]),
            pct(rows[k]["rate"]),
            interval(rows[k]["interval"]),
            pct(rows[k].get("paper_rate")),
        )
        for k in keys
    ]
    text = (
        "<h2>1. Table I: the contract holds where it was learned</h2>"
        f"<p>{esc(proto.get('training', 'The IPC was learned at buffer size 1.'))}. "
        f"{esc(proto.get('test', ''))}"
        + (
            f" (median speed {speed['median']:.2f} m/s, 90th percentile {speed['p90']:.2f} m/s)."
            if speed
            else "."
        )
        + f" Intervals are exact Clopper–Pearson, simultaneous {100 * conf:.0f} % over the rows; "
        "they treat the "
        "5 Hz samples along a few flights as independent, so they are somewhat optimistic.</p>"
    )
    return (
        text
        + table(
            ["buffer size", "n", "violations", "rate", "95 % CP interval", "paper"],
            body,
            "Table I. Violation rate of the IPC learned at buffer size 1.",
        )  # fmt: skip
        + figure(
            figs,
            "table1",
            "Figure 1. Table I with Clopper–Pearson intervals (circles) and the paper's "
            "values (squares); a rate of 0 is drawn as a triangle at its upper bound.",
        )  # fmt: skip
    )


def _timing(summary: Mapping[str, Any], figs: Mapping[str, bytes]) -> str:
    t = summary.get("camera_timing")
    if not t:
        return ""
    p = t["parameters"]
    per = t["per_buffer"]
    rows = [
        (
            esc(b),
            esc(f"{v['age_ms']['median']:.1f}"),
            esc(f"{v['age_ms']['p05']:.1f} – {v['age_ms']['p95']:.1f}"),
            esc(f"{v['error_mm']['median']:.1f}"),
            esc(f"{v['error_mm']['p95']:.1f}"),
        )
        for b, v in sorted(per.items(), key=lambda kv: int(kv[0]))
    ]
    return (
        "<h2>2. The camera's timing</h2>"
        "<p>The image a measurement reads is decided by the camera-timing model: a free-running camera "
        f"clock (random phase, rate offset), {1e3 * p['exposure']:.1f} ms exposure and "
        f"{1e3 * p['readout']:.1f} ms rolling-shutter readout rendered into the image, "
        f"{1e3 * p['isp_latency']:.1f} ms ISP latency with jitter, a V4L2 queue of <i>b</i> buffers "
        f"(policy “{esc(p['policy'])}”) drained by a reader loop that needs {t['reader_mean_ms']:.1f} ms per "
        f"frame on average on the Raspberry Pi 3 (the camera delivers one every "
        f"{t['camera_period_ms']:.1f} ms), "
        f"with stalls ({p['stall_rate']:g} per second), and a {p['mocap_rate']:g} Hz motion capture whose "
        "sample is paired with the image when the reader finishes. No parameter was fitted to Table I "
        "(sources in docs/case_study.md).</p>"
        + table(
            ["buffer size", "median age (ms)", "5–95 % age (ms)", "median error (mm)", "95 % error (mm)"],
            rows,
            "Table 2. Image age (image older than the paired state) and perception error on the "
            "Table I test flights.",
        )  # fmt: skip
        + figure(figs, "ages", "Figure 2. Image age per buffer size on the test flights.")
    )


def _ablation(summary: Mapping[str, Any], figs: Mapping[str, bytes]) -> str:
    ab = summary.get("ablation")
    if not ab:
        return ""
    rows_in = ab["rows"]
    buffers = sorted(next(iter(rows_in.values()))["table1"], key=int) if rows_in else []
    order = {"reference": 0, "alone": 1, "removed": 2}
    rows = []
    for _, r in sorted(rows_in.items(), key=lambda kv: order.get(kv[1]["group"], 3)):
        rates = [pct(r["table1"][b]["rate"], 1) for b in buffers]
        rows.append([esc(r["label"]), esc(r["group"]), *rates, esc(f"{r['median_age_ms'][buffers[0]]:.0f}")])
    paper = summary.get("paper", {}).get("table1", {})
    rows.append(["paper", "—", *[pct(paper.get(b, paper.get(int(b))), 1) for b in buffers], "—"])
    s = ab["sizes"]
    only = (
        f" <i>This run measured {len(rows_in)} of the 18 configurations (<code>[ablation] variants</code>; "
        "<code>--quick</code> runs three): the full run has them all.</i>"
        if len(rows_in) < 18
        else ""
    )
    return (
        "<h3>2.1 Which error source makes which part of Table I</h3>"
        f"<p>Each configuration learns its own IPC at buffer size 1 ({s['n_train']} training and "
        f"{s['n_calibration']} calibration samples, PAC ε = {s['epsilon']:g}) and is tested on "
        f"{s['n_pilot']} pilot measurements per buffer size, the same flights for all. “Alone” keeps the "
        "driver queue, without which the buffer size changes nothing. An image age is how much older "
        "the image is than the motion-capture state paired with it; it is negative when the state is "
        "the older one, as where the motion capture's own latency (10 ms) outlasts what is left of the "
        "camera's delay (rows without the driver queue or the camera's base latency)."
        + only
        + "</p>"
        + table(
            ["configuration", "group", *[f"b = {b}" for b in buffers], "median age at b = 1 (ms)"],
            rows,
            "Table 3. Ablation: Table I per configuration.",
            text=(0, 1),
        )  # fmt: skip
        + figure(
            figs,
            "ablation",
            "Figure 3. Table I with each error source alone (left) and removed "
            "(right), beside all sources, the previous fixed-lag model and the paper.",
        )  # fmt: skip
    )


def _landing_row(side: Mapping[str, Any]) -> list[str]:
    return [
        esc(side["runs"]),
        esc(side["safe"]),
        esc(unsafe_cell(side)),
        esc(side["aborted"]),
        pct(side.get("unsafe_rate")),
        interval(side.get("unsafe_interval")),
        num(side.get("mean_queries"), 3),
    ]


_LANDING_HEAD = ["contract and runs", "runs", "safe", "unsafe", "aborted", "unsafe rate", "95 % CP interval",
                 "queries / run"]  # fmt: skip


def _landing_table(land: Mapping[str, Any], paper: Mapping[str, Any], caption: str) -> str:
    ipc, base = land["ipc"], land["baseline"]
    rows = [
        ["IPC, paper-style", *_landing_row(ipc["paper_runs"])],
        ["baseline, paper-style", *_landing_row(base["paper_runs"])],
        ["IPC, Monte Carlo", *_landing_row(ipc)],
        ["baseline, Monte Carlo", *_landing_row(base)],
    ]
    if paper:
        rows.append(["paper: IPC / baseline", esc(paper["runs"]),
                     esc(f"{paper['ipc_safe']} / {paper['runs'] - paper['baseline_unsafe']}"),
                     esc(f"0 / {paper['baseline_unsafe']}"), "—", "—", "—", "—"])  # fmt: skip
    return table(_LANDING_HEAD, rows, caption)


def _landing(summary: Mapping[str, Any], figs: Mapping[str, bytes]) -> str:
    land = summary.get("landing")
    if not land:
        return ""
    paper = (summary.get("paper") or {}).get("landing", {})
    k = land["buffer_size"]
    return (
        f"<h2>3. Safe landing at buffer size {esc(k)}</h2>"
        "<p>The paper's state machine with the learned IPC and with the trivial baseline E(ŷ, 10⁴ I), "
        "on the same "
        "scenarios: the vehicle arrives in transit, measures at the first detection, and lands only when the "
        "IPC's ellipsoid fits the target region G (tracking tolerance "
        f"{1000 * land['tracking_tolerance']:.1f} mm, at most {land['max_measurements']} measurements "
        "per run). A run is safe if the motors are cut inside "
        "{y} ⊕ G; a run that flies into the pad (a pad perceived below its surface) is unsafe; "
        "aborted runs never count as safe.</p>"
        + _landing_table(land, paper, f"Table 4. Landing at buffer size {k}.")
        + figure(
            figs,
            "topview",
            "Figure 4. The paper-style runs with the pad at the origin: IPC paths and "
            "measurements (circles, size ~ ellipsoid), motor cuts of the IPC (stars) and of the baseline "
            "(crosses; triangles where it flew into the pad); G dashed around the pad.",
        )  # fmt: skip
        + figure(
            figs,
            "campaign",
            "Figure 5. Where the motors were cut in the Monte Carlo runs, top and side views, with G.",
        )  # fmt: skip
        + figure(figs, "trajectories", "Figure 6. Three paired runs in 3-D, G dashed at the pad.")
    )


def _certified(summary: Mapping[str, Any], figs: Mapping[str, bytes]) -> str:
    land = summary.get("landing")
    if not land:
        return ""
    ipc = land["ipc"]
    b, ev, loop, cov = ipc["certified"], ipc["empirical_vs_certified"], land["closed_loop"], land["coverage"]
    rows = [
        ("certified bound M·ε (union over the queries of a run)", num(b["union_bound"]),
         esc(f"{b['union_confidence']:.6g}")),
        ("refined bound ε·UCB(E[N])", num(b["refined_bound"]), esc(f"{b['refined_confidence']:.6g}")),
        ("empirical unsafe rate (Monte Carlo)",
         esc(f"{ev['unsafe']}/{ev['runs']} = {pct(ev.get('unsafe_rate'))}"),
         esc(interval(ev.get("unsafe_interval")))),
    ]  # fmt: skip
    loop_rows = [
        (esc(name), esc(loop[name]["n"]), esc(loop[name]["violations"]), pct(loop[name].get("rate")),
         interval(loop[name].get("interval")), esc(num(loop[name].get("contradicts_epsilon"))))
        for name in ("first", "accepted", "all")
    ]  # fmt: skip
    flag = cov.get("shift_detected")
    verdict = {
        True: "The closed loop queries the IPC outside its domain of validity more often than the test's "
        "false-alarm rate explains; those queries are answered OUTSIDE_DOMAIN and never accepted.",
        False: "No shift detected at 95 % confidence: the closed loop stays inside the IPC's domain of "
        "validity "
        "about as often as calibration-like samples do.",
    }.get(flag, "")
    return (
        "<h2>4. Certified versus empirical unsafe landings</h2>"
        f"<div class='box'><b>Assumption A.</b> {esc(b['assumption'])} Under it an unsafe landing needs a "
        "violated accepted query, so P(unsafe) ≤ ε·E[N] ≤ ε·M.</div>"
        + table(["quantity", "value", "confidence"], rows, "Table 5. The bound beside the observed rate.")
        + f"<p>ε = {num(b['epsilon'])} (certified by the PAC calibration), M = {b['max_queries']} queries, "
        f"mean {num(b['mean_queries'], 3)} queries per run.</p>"
        + table(
            ["queries", "n", "truth outside the set", "rate", "95 % interval", "contradicts ε"],
            loop_rows,
            "Table 6. The closed loop's own queries.",
        )  # fmt: skip
        + f"<p>{esc(verdict)}</p>"
        + figure(
            figs,
            "coverage",
            "Figure 7. Distance of the closed-loop queries to the calibration inputs "
            "against held-out samples, with the domain test's threshold.",
        )  # fmt: skip
    )


def _extra_landing(summary: Mapping[str, Any]) -> str:
    land = summary.get("landing_buffer3")
    if not land:
        return ""
    k = land["buffer_size"]
    return (
        f"<h3>3.1 The same landing at buffer size {esc(k)}</h3>"
        f"<p>With an IPC learned at buffer size {esc(k)} "
        "(“the contract holds for the conditions it was learned under”), on the same scenarios.</p>"
        + _landing_table(land, {}, f"Table 4b. Landing at buffer size {k}.")
    )


def _flights_out(group_test: Mapping[str, Any] | None) -> str:
    """``k/G`` held-out flights with at least one sample outside its set, or a dash."""
    if not group_test:
        return "—"
    t = group_test["trajectory"]
    return f"{t['violations']}/{t['n']}"


def _flight_scale(fl: Mapping[str, Any]) -> str:
    """The flight-level scale, or why there is none (too few flights for epsilon)."""
    if not fl:
        return "—"
    if fl.get("flight_scale") is not None:
        return f"{fl['flight_scale']:.3g} ({fl['n_flights']} flights)"
    need = math.ceil(1.0 / fl["epsilon"] - 1.0)
    return f"not attainable: ε = {fl['epsilon']:g} needs at least {need} flights, {fl['n_flights']} given"


def _run_claim(fl: Mapping[str, Any]) -> str:
    """The run-level PAC claim of a contract's network: its epsilon and scale (or why there is none)."""
    if not fl or fl.get("run_scale") is None:
        return "—"
    return f"ε = {fl['run_epsilon']:.3g}, scale {fl['run_scale']:.3g} (floor {fl['run_floor']:.3g})"


def _ipcs(summary: Mapping[str, Any]) -> str:
    rows = []
    for info in (summary.get("ipc") or {}).values():
        c, cert, fl = info["calibration"], info["certificate"], info.get("flight_level") or {}
        by_flight = _flight_scale(fl)
        rows.append([
            esc(f"buffer {info['buffer_size']}"), esc(info["n_parameters"]),
            esc(f"{c['mode']}, ε {c['epsilon']:g}, δ {c['delta']:g}, n {c['n']}"),
            num(c["certified_epsilon"]),
            esc(cert["status"]), esc(f"{cert['test']['violations']}/{cert['test']['n']}"),
            esc(_flights_out(cert.get("group_test"))),
            esc(f"{fl['row_scale']:.3g}" if fl else "—"), esc(by_flight), esc(_run_claim(fl)),
        ])  # fmt: skip
    if not rows:
        return ""
    note = (
        "<p>The calibration treats the 10 Hz samples as exchangeable rows; samples of one flight "
        "are correlated. The last column calibrates the same network with whole flights as the "
        "exchangeable units (conformal risk control, marginal: a new flight's expected share of "
        "samples outside is at most ε). With about a hundred flights that guarantee must leave "
        "room for a whole new flight outside its sets, so its scale is larger; the landing keeps "
        "the row-level PAC calibration its certified bound is derived for. The last column is the "
        "run-level PAC claim (proofs/run_claims.md): with probability 1 − δ a new flight's expected share "
        "of samples outside is at most the ε shown, the smallest its flights can certify when they "
        "cannot certify the row-level ε (no claim about a new flight goes below 1 − δ^(1/G)).</p>"
    )
    return "<h2>5. The learned IPCs</h2>" + table(
        ["IPC", "parameters", "calibration", "certified ε", "certificate", "held-out violations",
         "held-out flights with a violation", "scale (rows)", "scale (flights)",
         "run-level PAC claim (flights)"], rows,
        "Table 7. The IPCs and their certificates (ipcverify certify on held-out data).",
        text=(0, 2, 4, 8, 9),
    ) + note  # fmt: skip


def _timings(summary: Mapping[str, Any]) -> str:
    stages = summary.get("stage_seconds") or {}
    rows = [(esc(k), esc(f"{v:.1f}")) for k, v in stages.items()]
    total, cpu = summary.get("runtime_seconds"), summary.get("cpu_seconds")
    machine = summary.get("machine") or {}
    load = machine.get("load_average_start"), machine.get("load_average_end")
    busy = (
        f" The machine's load average was {load[0][0]:.1f} at the start and {load[1][0]:.1f} at the end "
        "(other work slows every stage down; the CPU time does not depend on it)."
        if load[0] and load[1]
        else ""
    )
    return (
        "<h2>6. How long it took</h2>"
        f"<p>{esc(total)} s in total on {esc(machine.get('cores_available', '?'))} cores "
        f"({esc(machine.get('platform', ''))}), {esc(cpu)} CPU-seconds in this process and its "
        f"workers.{busy}</p>"
        + (table(["stage", "seconds"], rows, "Table 8. Stage timings.") if rows else "")
        + "<p>Every number of this page, the settings and the seeds are in "
        '<a href="summary.json">summary.json</a> beside it.</p>'
    )


def render_report(summary: Mapping[str, Any], figures: Mapping[str, bytes]) -> str:
    """The report page for ``summary`` (the content of ``summary.json``) with ``figures`` (name -> PNG).

    Parameters
    ----------
    summary : mapping
        As written by :func:`.pipeline.reproduce`; missing sections are left out.
    figures : mapping of str to bytes
        PNGs named ``contracts``, ``table1``, ``ages``, ``ablation``, ``topview``, ``campaign``,
        ``trajectories``, ``coverage``.
    """
    quick = " with the reduced sizes of <code>--quick</code>" if summary.get("quick") else ""
    intro = (
        "<h1>Learning-based inverse perception contracts: the quadrotor landing, reproduced in "
        "simulation</h1><p class='lead'>We rerun the application study of Sun, Yang and Mitra, "
        "<i>Learning-based Inverse Perception Contracts and Applications</i>, in simulation: a quadrotor "
        "with a Raspberry Pi camera whose images reach the ArUco detector through a V4L2 buffer queue, "
        "unsynchronised with the motion capture. An IPC is learned at buffer size 1 and tested at buffer "
        f"sizes 1–5 (Table I), and the landing state machine is flown with it and with a trivial "
        f"baseline{quick}.</p>"
    )
    return (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>IPC reproduction: results</title>"
        f"<style>{CSS}</style></head><body>"
        + intro
        + contracts_section(summary, figures)
        + _claims(summary)
        + _table1(summary, figures)
        + _timing(summary, figures)
        + _ablation(summary, figures)
        + _landing(summary, figures)
        + _extra_landing(summary)
        + _certified(summary, figures)
        + _ipcs(summary)
        + _timings(summary)
        + "</body></html>"
    )
