"""Benchmarks for containment proofs (not a test: nothing here asserts a time).

Measures, for n = 3:

* the vectorised closed form over a batch of 10^5 ellipsoids (float slack + mask);
* the compiled S-lemma SDP per problem (cvxpy + Clarabel solve only, and the full
  ``prove`` including the exact certificate);
* the exact re-check ``verify`` of closed-form and SDP certificates;
* ``landing_decision`` per measurement (what the landing state machine calls);
* how often each prover answers UNKNOWN over a sweep of conditioning (1 to 1e6) and
  relative margins (1e-1 to 1e-12, contained and not).

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
from ipcverify.containment import Status, contained_float, prove, support_slack, verify
from ipcverify.containment.sdp import sdp_problem
from ipcverify.landing import landing_decision
from ipcverify.sets import Box, Ellipsoid, Polytope

OUT = Path(__file__).with_name("containment_results.json")


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
    from ipcverify.containment.sdp import normalised, trust_region_maximiser

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
        "sdp_homothetic": (_homothetic, None),
        "sdp_general": (_general, None),
    }
    table = {}
    for name, (make, method) in cases.items():
        total, unknown, wrong = Counter(), Counter(), 0
        for log_cond, margin, sign in itertools.product(conds, margins, [-1.0, 1.0]):
            for _ in range(per_cell):
                inner, outer, truth = make(rng, 3, log_cond, margin, sign)
                cert = prove(inner, outer, method=method)
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
        }
    return {"conditioning": ["1", "1e3", "1e6"], "margins": margins, "per_cell": per_cell, "cases": table}


def main() -> None:
    rng = np.random.default_rng(20240601)
    results = {
        "machine": {**machine_info(), "cvxpy": cp.__version__, "clarabel": clarabel.__version__},
        "closed_form_batch_n3": bench_closed_form_batch(rng),
        "sdp_per_problem_n3": bench_sdp(rng),
        "exact_recheck_n3": bench_exact(rng),
        "unknown_rates_n3": unknown_rates(rng),
    }
    OUT.write_text(json.dumps(results, indent=2) + "\n")
    print(json.dumps(results, indent=2))
    print(f"written to {OUT}")


if __name__ == "__main__":
    main()
