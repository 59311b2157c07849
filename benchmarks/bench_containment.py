"""Benchmarks for containment proofs (not a test: nothing here asserts a time).

Measures, for n = 3:

* the vectorised closed form over a batch of 10^5 ellipsoids (float slack + mask);
* the compiled S-lemma SDP per problem (cvxpy + Clarabel solve only, and the full
  ``prove`` including the exact certificate);
* the exact re-check ``verify`` of closed-form and SDP certificates;
* ``landing_decision`` per measurement (what the landing state machine calls);
* how often each prover answers UNKNOWN over a sweep of conditioning (1 to 1e6) and
  relative margins (1e-1 to 1e-12, contained and not);
* the S-lemma SDP route for Proposition 1 (``prove(..., method="sdp")`` against the box
  ``{P} ⊕ (-G_tau)``) on landing decisions of a trained IPC (``tests/data/landing_sets.npz``,
  ``python -m docgen.landing_sets``): its cost per decision (Clarabel alone, the whole
  route with its exact certificate, ``verify``) beside the closed form's (``landing_decision``)
  and the controller's (``LandingRule.decide``), wall and CPU time; its agreement with the
  closed form; how far Clarabel's multipliers lie from the program's exact solution ``s / 2``;
  which faces the solver's own multiplier certifies and which need the centre. It draws
  ``docs/img/containment_sdp.png``.

Run ``python -m benchmarks.bench_containment``; results are printed and written to
``benchmarks/containment_results.json``.
"""

from __future__ import annotations

import itertools
import json
import statistics
import time
from collections import Counter
from fractions import Fraction
from pathlib import Path

import clarabel
import cvxpy as cp
import numpy as np

from benchmarks.common import machine_info
from case_studies.quad_landing.landing.state_machine import LandingParams
from ipcverify.certification._report_plots import figure_to_png
from ipcverify.data._files import atomic_write
from ipcverify.decision import landing_decision
from ipcverify.decision._landing import LandingRule
from ipcverify.decision.containment import Status, prove, verify
from ipcverify.decision.containment._face_lmi import FaceSystem, face_centre
from ipcverify.decision.containment._face_sdp import solve_face_sdp
from ipcverify.decision.containment._margin import contained_float, support_slack
from ipcverify.decision.containment._sdp import sdp_problem
from ipcverify.sets import Box, Ellipsoid, Polytope

ROOT = Path(__file__).resolve().parents[1]
OUT = Path(__file__).with_name("containment_results.json")
LANDING_SETS = ROOT / "tests" / "data" / "landing_sets.npz"
SDP_FIGURE = ROOT / "docs" / "img" / "containment_sdp.png"


def _orth(rng, n):
    q, r = np.linalg.qr(rng.standard_normal((n, n)))
    return q * np.sign(np.diag(r))


def _shape(rng, n, log_cond):
    s = 10.0 ** np.sort(rng.uniform(0.0, log_cond, n))
    s[0], s[-1] = 1.0, 10.0**log_cond
    return _orth(rng, n) @ np.diag(s * 10.0 ** rng.uniform(-2, 2)) @ _orth(rng, n).T


def _ellipsoid(rng, n, log_cond):
    return Ellipsoid(rng.normal(scale=3.0, size=n), _shape(rng, n, log_cond))


def _ms(samples):
    return {
        "median_ms": 1e3 * statistics.median(samples),
        "p90_ms": 1e3 * float(np.quantile(samples, 0.9)),
        "n": len(samples),
    }


def bench_closed_form_batch(rng, b=100_000, repeats=5):
    shapes = rng.standard_normal((b, 3, 3)) * 0.2 + np.eye(3) * 20.0
    e = Ellipsoid(rng.normal(scale=0.01, size=(b, 3)), shapes)
    box = Box([-0.06, -0.06, -0.06], [0.06, 0.06, 0.06])
    poly = Polytope(*box.faces())
    t_box, t_poly = [], []
    for _ in range(repeats):
        t = time.perf_counter()
        mask = contained_float(e, box)
        t_box.append(time.perf_counter() - t)
        t = time.perf_counter()
        support_slack(e, poly)
        t_poly.append(time.perf_counter() - t)
    return {
        "batch": b,
        "box_total_ms": 1e3 * statistics.median(t_box),
        "polytope_6_faces_total_ms": 1e3 * statistics.median(t_poly),
        "box_per_ellipsoid_us": 1e6 * statistics.median(t_box) / b,
        "accepted_fraction": float(mask.mean()),
        "note": "float-decided (not a proof); Ellipsoid construction time excluded",
    }


def _contained_pair(rng, n=3):
    """A random pair with E1 inside E2 (E2 = E1 grown by 1.2-2x about a nearby point)."""
    e1 = _ellipsoid(rng, n, rng.uniform(0, 3))
    grow = rng.uniform(1.2, 2.0)
    shift = np.linalg.solve(e1.shapes[0], rng.standard_normal(n)) * 0.1
    return e1, Ellipsoid(e1.centers[0] + shift, e1.shapes[0] / grow)


def bench_sdp(rng, count=200):
    prob, lam, tau, q2 = sdp_problem(3)
    solve, end_to_end, statuses = [], [], Counter()
    pairs = [
        _contained_pair(rng) if i % 2 else (_ellipsoid(rng, 3, 1.0), _ellipsoid(rng, 3, 1.0))
        for i in range(count)
    ]
    prove(*pairs[0])  # compile once (DPP), not timed
    for e1, e2 in pairs:
        t = time.perf_counter()
        cert = prove(e1, e2)
        end_to_end.append(time.perf_counter() - t)
        statuses[cert.status.value] += 1
        t = time.perf_counter()
        prob.solve(solver=cp.CLARABEL)  # parameters of the last problem: the bare solve
        solve.append(time.perf_counter() - t)
    return {
        "solve_only": _ms(solve),
        "prove_containment_end_to_end": _ms(end_to_end),
        "statuses": dict(statuses),
    }


def bench_exact(rng, count=200):
    box_certs, sdp_certs, landing = [], [], []
    for _ in range(count):
        e = Ellipsoid(rng.normal(size=3), rng.standard_normal((3, 3)) + 4 * np.eye(3))
        box_certs.append(prove(e, Box(-np.ones(3) * 2, np.ones(3) * 2)))
    for _ in range(count // 2):
        sdp_certs.append(prove(*_contained_pair(rng)))
    out = {}
    for name, certs in (("closed_form_box", box_certs), ("sdp", sdp_certs)):
        ts = []
        for c in certs:
            t = time.perf_counter()
            verify(c)
            ts.append(time.perf_counter() - t)
        out[name] = {**_ms(ts), "statuses": dict(Counter(c.status.value for c in certs))}
    for _ in range(count):
        q = _orth(rng, 3)
        e = Ellipsoid(rng.uniform(-5, 5, 3), q @ np.diag(1 / rng.uniform(0.01, 0.05, 3)) @ q.T)
        t = time.perf_counter()
        landing_decision(e, LandingParams.defaults().target)
        landing.append(time.perf_counter() - t)
    out["landing_decision"] = _ms(landing)
    return out


# ------------------------------------------------------------ UNKNOWN rates
def _homothetic(rng, n, log_cond, margin, sign):
    e1 = _ellipsoid(rng, n, log_cond)
    f = 2.0 ** int(rng.integers(0, 4))
    v = rng.standard_normal(n)
    v *= (f - 1.0) * (1.0 - sign * margin) / np.linalg.norm(v)
    c2 = e1.centers[0] - np.linalg.solve(e1.shapes[0], v)
    c1q = [Fraction(float(x)) for x in e1.centers[0]]
    d = [a - Fraction(float(b)) for a, b in zip(c1q, c2, strict=True)]
    rows = [[Fraction(float(x)) for x in r] for r in e1.shapes[0]]
    dist2 = sum(sum(x * y for x, y in zip(r, d, strict=True)) ** 2 for r in rows)
    return e1, Ellipsoid(c2, e1.shapes[0] / f), dist2 <= Fraction(f - 1.0) ** 2


def _general(rng, n, log_cond, margin, sign):
    """E2 scaled so that the float estimate of max_{E1} g2^2 is 1 - sign * margin (truth unknown)."""
    e1 = _ellipsoid(rng, n, log_cond)
    e2 = Ellipsoid(
        e1.centers[0] + rng.normal(size=n) / np.linalg.norm(e1.shapes[0], 2),
        _shape(rng, n, min(log_cond, 3.0)),
    )
    from ipcverify.decision.containment._sdp import normalised, trust_region_maximiser

    d_mat, d = normalised(e1, e2)
    u, _ = trust_region_maximiser(d_mat, d)
    tau = float(np.sum((d_mat @ (u - d)) ** 2))
    return e1, Ellipsoid(e2.centers[0], e2.shapes[0] * np.sqrt((1.0 - sign * margin) / tau)), None


def _box(rng, n, log_cond, margin, sign):
    e = _ellipsoid(rng, n, log_cond)
    c, h = e.centers[0], e.half_widths()[0]
    rel = np.full(2 * n, 0.1)
    tight = rng.choice(2 * n, size=rng.integers(1, 2 * n + 1), replace=False)
    rel[tight] = sign * margin * rng.uniform(0.5, 1.0, tight.size)
    return e, Box(c - h * (1 + rel[n:]), c + h * (1 + rel[:n])), None


def unknown_rates(rng, per_cell=8):
    conds = [0.0, 3.0, 6.0]
    margins = [1e-1, 1e-3, 1e-6, 1e-9, 1e-12]
    cases = {
        "closed_form_box": (_box, None),
        "socp_box": (_box, "socp"),
        "sdp_box": (_box, "sdp"),
        "sdp_homothetic": (_homothetic, None),
        "sdp_general": (_general, None),
    }
    table = {}
    for name, (make, method) in cases.items():
        total, unknown, wrong, closed_disagree = Counter(), Counter(), 0, 0
        for log_cond, margin, sign in itertools.product(conds, margins, [-1.0, 1.0]):
            for _ in range(per_cell):
                inner, outer, truth = make(rng, 3, log_cond, margin, sign)
                cert = prove(inner, outer, method=method)
                if name == "sdp_box" and cert.status is not Status.UNKNOWN:
                    closed_disagree += cert.status is not prove(inner, outer).status
                total[margin] += 1
                unknown[margin] += cert.status is Status.UNKNOWN
                if truth is not None and cert.status is not Status.UNKNOWN:
                    wrong += (cert.status is Status.PROVEN) != truth
        table[name] = {
            "problems": sum(total.values()),
            "unknown": sum(unknown.values()),
            "unknown_rate": sum(unknown.values()) / sum(total.values()),
            "unknown_by_margin": {f"{m:g}": unknown[m] / total[m] for m in margins},
            "wrong_against_exact_oracle": wrong if name == "sdp_homothetic" else None,
            "disagreements_with_closed_form": closed_disagree if name == "sdp_box" else None,
        }
    return {"conditioning": ["1", "1e3", "1e6"], "margins": margins, "per_cell": per_cell, "cases": table}


# ------------------------------------------------- Proposition 1 by the SDP route
def _timed(fn, items):
    """Per-call wall times (s) and the total CPU seconds of ``fn`` over ``items``; the results.

    One untimed call on the first item first, so that a compiled kernel's loading (Numba's
    cache) or a solver's set-up is not charged to the decisions.
    """
    wall, out = [], []
    if items:
        fn(items[0])
    cpu0 = time.process_time()
    for item in items:
        t = time.perf_counter()
        out.append(fn(item))
        wall.append(time.perf_counter() - t)
    return {**_ms(wall), "cpu_s_total": time.process_time() - cpu0, "wall_s_total": sum(wall)}, out


def _face_kinds(cert, e, box):
    """Per face: "centre" if the certified multiplier is the exact s/2, else "solver"."""
    system = FaceSystem(e, box)
    return [
        "centre" if q == face_centre(system, j) else "solver"
        for j, q in enumerate(cert.multipliers["lambda"])
    ]


def bench_landing_sdp(count=None):
    """Every decision of the file (or the first ``count``), each path timed in its own loop."""
    with np.load(LANDING_SETS) as f:
        centers, shapes = f["centers"][:count], f["shapes"][:count]
        target = Box(f["target_lower"], f["target_upper"])
    count = len(centers)
    sets = [Ellipsoid(c, C) for c, C in zip(centers, shapes, strict=True)]
    rule = LandingRule(target)
    t_rule, _ = _timed(lambda e: rule.decide(e.centers[0], e.shapes[0]), sets)
    t_closed, decisions = _timed(lambda e: landing_decision(e, target), sets)
    problems = [(e, d.certificate.outer) for e, d in zip(sets, decisions, strict=True)]
    t_solve, solutions = _timed(lambda p: solve_face_sdp(*p), problems)
    t_sdp, certs = _timed(lambda p: prove(*p, method="sdp"), problems)
    t_verify, checks = _timed(verify, certs)
    pairs = Counter(
        (d.certificate.status.value, c.status.value) for d, c in zip(decisions, certs, strict=True)
    )
    disagree = sum(v for (a, b), v in pairs.items() if b != "UNKNOWN" and a != b)
    reverified = sum(v.status is c.status for v, c in zip(checks, certs, strict=True))
    # on the faces that hold: the solver's multiplier against the program's exact solution s/2
    dist, rel_slack, kinds = [], [], []
    for (e, box), sol, cert in zip(problems, solutions, certs, strict=True):
        system = FaceSystem(e, box)
        centre = np.array([float(face_centre(system, j)) for j in range(len(system))])
        rel = support_slack(e, box)[0] / np.concatenate([e.half_widths()[0]] * 2)
        holds = (rel >= 0) & (centre > 0)
        dist += np.abs(sol.lam[holds] / centre[holds] - 1.0).tolist()
        if cert.status is Status.PROVEN:
            rel_slack += rel.tolist()
            kinds += _face_kinds(cert, e, box)
    rel_slack, kinds = np.array(rel_slack), np.array(kinds)
    return {
        "decisions": count,
        "source": "tests/data/landing_sets.npz (python -m docgen.landing_sets): a trained IPC's sets "
        "on the case study's flights, world frame, against {P} + (-G_tau)",
        "per_decision": {
            "landing_rule_decide (controller, float64 with rounding bound)": t_rule,
            "landing_decision (closed form, exact)": t_closed,
            "sdp_clarabel_solve_only": t_solve,
            "prove_sdp (solve + exact certificate + witness)": t_sdp,
            "verify_sdp_certificate (exact)": t_verify,
        },
        "closed_form_vs_sdp": {f"{a}/{b}": v for (a, b), v in sorted(pairs.items())},
        "disagreements": disagree,
        "sdp_unknown": sum(v for (_, b), v in pairs.items() if b == "UNKNOWN"),
        "sdp_certificates_reverified": reverified,
        "faces_that_hold_solver_multiplier_relative_distance_to_s_over_2": {
            "median": float(np.median(dist)),
            "p99": float(np.quantile(dist, 0.99)),
            "max": float(np.max(dist)),
        },
        "faces_of_proven_certificates": {
            "certified_by_solver_multiplier": int((kinds == "solver").sum()),
            "certified_by_centre_s_over_2": int((kinds == "centre").sum()),
            "smallest_relative_slack_certified_by_solver": float(rel_slack[kinds == "solver"].min())
            if (kinds == "solver").any()
            else None,
        },
        "_figure": {"rel_slack": rel_slack, "kinds": kinds},
    }


def plot_landing_sdp(fig_data, summary):
    """Left: CPU cost per decision of each route. Right: which multiplier certified each face."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 3.7), layout="constrained")
    left, right = fig.subplots(1, 2)
    per = summary["per_decision"]
    names = {
        "landing_rule_decide (controller, float64 with rounding bound)": (
            "LandingRule.decide\n(controller, proof)"
        ),
        "landing_decision (closed form, exact)": "landing_decision\n(closed form, exact)",
        "sdp_clarabel_solve_only": "Clarabel solve only",
        "prove_sdp (solve + exact certificate + witness)": 'prove(method="sdp")\n(solve + exact check)',
        "verify_sdp_certificate (exact)": "verify(SDP certificate)",
    }
    ms = [1e3 * per[k]["cpu_s_total"] / per[k]["n"] for k in names]
    y = np.arange(len(names))[::-1]
    left.barh(y, ms, color=["tab:gray", "tab:green", "tab:blue", "tab:blue", "tab:purple"])
    for yi, v in zip(y, ms, strict=True):
        left.text(v * 1.1, yi, f"{v:.3g} ms", va="center", fontsize=7)
    left.set_yticks(y, list(names.values()), fontsize=7)
    left.set_xscale("log")
    left.set_xlim(right=20 * max(ms))
    left.set_xlabel("CPU time per landing decision (ms)")
    left.set_title("cost of each route (n = 3, six faces)", fontsize=9)
    rel, kinds = fig_data["rel_slack"], fig_data["kinds"]
    edges = np.array([0.0, 1e-15, 1e-9, 1e-6, 1e-3, 1.0, np.inf])
    labels = ["< 1e-15", "1e-15..1e-9", "1e-9..1e-6", "1e-6..1e-3", "1e-3..1", "> 1"]
    idx = np.clip(np.searchsorted(edges, rel, side="right") - 1, 0, len(labels) - 1)
    solver = np.bincount(idx[kinds == "solver"], minlength=len(labels))
    centre = np.bincount(idx[kinds == "centre"], minlength=len(labels))
    x = np.arange(len(labels))
    right.bar(x, solver, color="tab:blue", label="Clarabel's own multiplier")
    right.bar(x, centre, bottom=solver, color="tab:orange", label="polished to the centre s/2")
    right.set_xticks(x, labels, fontsize=7, rotation=20)
    right.set_yscale("log")
    right.set_ylim(bottom=0.8)
    right.set_xlabel("relative slack of the face (slack / half-width)")
    right.set_ylabel("faces of PROVEN certificates")
    right.set_title("which multiplier passed the exact check", fontsize=9)
    right.legend(fontsize=7, loc="upper center")
    pairs = summary["closed_form_vs_sdp"]
    fig.suptitle(
        f"Proposition 1 by the S-lemma SDP, {summary['decisions']} landing decisions of a trained IPC:\n"
        f"{pairs.get('PROVEN/PROVEN', 0)} PROVEN and {pairs.get('REFUTED/REFUTED', 0)} REFUTED by both "
        f"routes, {summary['disagreements']} disagreements, {summary['sdp_unknown']} UNKNOWN",
        fontsize=9,
    )
    return fig


def main() -> None:
    rng = np.random.default_rng(20240601)
    landing = bench_landing_sdp()
    fig_data = landing.pop("_figure")
    png = figure_to_png(plot_landing_sdp(fig_data, landing), dpi=110)
    atomic_write(SDP_FIGURE, lambda f: f.write(png))
    results = {
        "machine": {**machine_info(), "cvxpy": cp.__version__, "clarabel": clarabel.__version__},
        "closed_form_batch_n3": bench_closed_form_batch(rng),
        "sdp_per_problem_n3": bench_sdp(rng),
        "exact_recheck_n3": bench_exact(rng),
        "unknown_rates_n3": unknown_rates(rng),
        "proposition1_sdp_route": landing,
    }
    OUT.write_text(json.dumps(results, indent=2) + "\n")
    print(json.dumps(results, indent=2))
    print(f"written to {OUT}")


if __name__ == "__main__":
    main()
