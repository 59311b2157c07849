"""Latency and throughput of one IPC: single queries against a bare torch forward, batches, ONNX.

Every number is measured on a named **workload** (:class:`Workload`: a calibrated model with
its domain of validity and a query set), and reported beside the share of its queries outside
the domain. The first workload is the one of record (``python -m benchmarks.run``: held-out
quad flights drawn like the calibration flights, the domain fitted by flight); the others get
the same measurements on fewer paths (:func:`bench_latency`), among them the out-of-domain
workload the benchmark used before (12 unseen flights sampled densely, a row-level domain:
85 % of the queries outside).

Single query (what a control loop does once per camera frame), all with torch and
ONNX Runtime limited to **one thread**:

* ``bare_forward`` -- the reference: ``model.network.body`` (a plain
  ``torch.nn.Sequential``) on a pre-normalised float32 tensor of shape (1, d + n),
  inside one ``torch.inference_mode()`` block entered outside the timing loop (the
  cheapest torch call there is; no normalisation, no set, no decision).
* ``ellipsoid`` -- :meth:`ipcverify.decision.IPCQuery.ellipsoid`: (x, yhat) -> calibrated (c, C).
  The decisions below are :class:`ipcverify.decision.LandingQuery` over that query.
* ``decide_float`` -- query -> ellipsoid -> domain test -> float landing decision (not a proof).
* ``decide`` -- query -> ellipsoid -> domain test -> landing decision of record (float64 with a
  rigorous rounding bound, exact arithmetic inside the band: every answer proven), over the
  test split's queries in order: the path the landing controller runs. The model should carry
  the domain of validity a default :func:`~ipcverify.contract.calibrate` fits (as
  ``python -m benchmarks.run`` gives it); ``decide_without_domain_test`` is the same model and
  queries with the domain dropped, to show what the domain test costs. Also over the same
  queries shuffled (``decide_shuffled``: no frame-to-frame coherence for the domain test's
  cache), and split by answer: accepted, rejected inside the domain, outside the domain.
* ``onnx_float64`` / ``onnx_float32`` -- ONNX Runtime on the exported graph, (1, d) inputs.

``predict_sets`` is :func:`ipcverify.contract.predict_sets`, the guarded batch path of
``ipcverify predict`` (sets, calibration, singular test and the domain test's ``in_domain``;
the distances are computed only when read); ``predict_sets_without_domain`` is the same with
the model's domain dropped, ``domain_contains`` the domain test alone.
:func:`domain_methods` times the exact threshold test three ways on the workload's queries
(SciPy's k-d tree, a float32 BLAS product over every reference, the compiled k-d tree search
that ships) and the exact distances.

Each is timed call by call in interleaved rounds; p50 and p99 are taken per round and
the median (and min/max) over rounds is reported, with both ratios to the bare forward.
``fast_path`` reports how the landing decisions of the test split were reached
(:func:`ipcverify.decision.landing_by_bound`: float bound alone, exact integer turn-off
height, or the exact rational fallback). Batch throughput is queries per second of
``model.predict`` (validated ``Ellipsoid``), the bare float64 engine arrays,
ONNX Runtime (float64 and float32) and the bare torch forward, all single-threaded;
``engine_arrays_blas_default_threads`` repeats the engine with NumPy's BLAS at one thread
per core (its default), which on 2 shared cores is far slower for mid-sized batches.
``float64_layers_only`` is the network's layers alone in float64 (the engine's own products
and fused bias passes, nothing else): no evaluation whose sets of record are float64 can beat
it, so its ratio to the bare (float32) torch forward,
``batch_float64_layers_ratio_to_bare_forward``, is the ceiling of
``batch_predict_ratio_to_bare_forward``.
"""

from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from benchmarks.common import spread, time_calls
from case_studies.quad_landing.landing.state_machine import LandingParams
from ipcverify.contract import IPCModel
from ipcverify.contract._prediction import predict_sets
from ipcverify.data import PerceptionDataset, PerceptionInputs
from ipcverify.decision import IPCQuery, LandingQuery
from ipcverify.decision._landing_bound import landing_by_bound

__all__ = [
    "BATCH_SIZES",
    "Workload",
    "batch_throughput",
    "bench_latency",
    "domain_methods",
    "outside_fraction",
    "single_query",
]

BATCH_SIZES: tuple[int, ...] = (1, 10, 100, 1_000, 10_000, 100_000)
#: Batch sizes of the workloads after the first (the targets' sizes).
SECOND_SIZES: tuple[int, ...] = (10_000, 100_000)


@dataclass(frozen=True)
class Workload:
    """A calibrated model (with its domain of validity) and the queries it is timed on, in order."""

    name: str
    model: IPCModel
    queries: PerceptionDataset
    description: str


def outside_fraction(model: IPCModel, queries: PerceptionDataset) -> float | None:
    """Share of the queries outside the model's domain of validity (None without a domain)."""
    if model.domain is None:
        return None
    return float(1.0 - model.domain.contains(queries.x, queries.yhat).mean())


def _onnx_sessions(model: IPCModel, folder: Path) -> dict[str, Any]:
    from ipcverify.io import export_onnx
    from ipcverify.io._onnx import onnx_session

    try:
        import onnx  # noqa: F401
        import onnxruntime  # noqa: F401
    except ImportError:
        return {}
    out = {}
    for dtype in ("float64", "float32"):
        info = export_onnx(
            model,
            folder / f"ipc_{dtype}.onnx",
            dtype=dtype,  # type: ignore[arg-type]
            without_domain=True,  # the sets' latency; the domain test is timed on the query path
        )
        out[dtype] = (
            onnx_session(info.path, threads=1),
            np.float64 if dtype == "float64" else np.float32,
            info,
        )
    return out


def _fast_path_shares(
    q: LandingQuery, xs: np.ndarray, ys: np.ndarray, in_domain: np.ndarray
) -> dict[str, Any]:
    """How the landing decisions of these queries' sets are reached (every query, and in the domain)."""
    lower, upper = q.target.lower.tolist(), q.target.upper.tolist()
    tiers = []
    for x, y in zip(xs, ys, strict=True):
        c, C = q.ellipsoid(x, y)
        r = landing_by_bound(c.tolist(), C.ravel().tolist(), lower, upper)
        tiers.append(
            "exact_rational" if r is None else ("exact_integer_height" if r.exact_turnoff else "float_bound")
        )
    t = np.array(tiers)

    def shares(mask: np.ndarray) -> dict[str, Any]:
        n = int(mask.sum())
        return {"queries": n, **{k: float((t[mask] == k).mean()) if n else None for k in _TIERS}}

    return {
        "all_queries": shares(np.ones(len(t), dtype=bool)),
        "in_domain_queries": shares(in_domain),
        "note": "float_bound: decided by tier 1 alone; exact_integer_height: P_z (or a z face) needed exact "
        "integers (a few microseconds); exact_rational: a margin in the rounding band, decided by "
        "landing_decision (about a millisecond) -- the fallback rate",
    }


_TIERS = ("float_bound", "exact_integer_height", "exact_rational")


def single_query(
    model: IPCModel,
    queries: PerceptionDataset,
    rounds: int = 5,
    calls: int = 2000,
    onnx: dict[str, Any] | None = None,
    full: bool = True,
) -> dict[str, Any]:
    """Per-call latency (microseconds) of the single-query paths; see the module docstring.

    ``full=False`` times only the bare forward, ``decide`` and ``decide_without_domain_test``.
    """
    q = LandingQuery(IPCQuery(model), LandingParams.defaults().target)
    body = model.network.body
    eng = model.engine
    xs, ys = np.ascontiguousarray(queries.x), np.ascontiguousarray(queries.yhat)
    m = len(xs)
    z = ((np.hstack([xs, ys]) - eng.in_mean) * eng.in_scale).astype(np.float32)
    zt = [torch.from_numpy(z[i : i + 1].copy()) for i in range(min(m, 256))]
    decisions = [q.decide(xs[i], ys[i]) for i in range(m)]
    verdicts = np.array([d.verdict.name for d in decisions])
    groups = {
        "accepting": np.flatnonzero(verdicts == "ACCEPT"),
        "rejecting": np.flatnonzero(verdicts == "REJECT"),
        "outside_domain": np.flatnonzero(verdicts == "OUTSIDE_DOMAIN"),
    }
    shuffled = np.random.default_rng(0).permutation(m)

    def cycler(fn: Any, idx: np.ndarray) -> Any:
        state = {"i": 0}
        n_idx = len(idx)

        def call() -> None:
            j = idx[state["i"] % n_idx]
            state["i"] += 1
            fn(j)

        return call

    paths: dict[str, Any] = {}
    with torch.inference_mode():
        paths["bare_forward"] = cycler(lambda j: body(zt[j % len(zt)]), np.arange(len(zt)))
        if full:
            paths["ellipsoid"] = cycler(lambda j: q.ellipsoid(xs[j], ys[j]), np.arange(m))
            paths["decide_float"] = cycler(lambda j: q.decide_float(xs[j], ys[j]), np.arange(m))
        paths["decide"] = cycler(lambda j: q.decide(xs[j], ys[j]), np.arange(m))
        if full:
            paths["decide_shuffled"] = cycler(lambda j: q.decide(xs[j], ys[j]), shuffled)
        if model.domain is not None:
            bare_q = LandingQuery(IPCQuery(model.with_calibration(model.calibration, None)), q.target)
            paths["decide_without_domain_test"] = cycler(lambda j: bare_q.decide(xs[j], ys[j]), np.arange(m))
        for name, idx in groups.items() if full else ():
            if len(idx):
                paths[f"decide_{name}_queries"] = cycler(lambda j: q.decide(xs[j], ys[j]), idx)
        if full:
            paths["model_predict_one"] = cycler(
                lambda j: model.predict_unguarded(xs[j : j + 1], ys[j : j + 1]), np.arange(m)
            )
        for dtype, entry in (onnx or {}).items() if full else ():
            sess, np_t, _ = entry
            xo, yo = xs.astype(np_t), ys.astype(np_t)
            paths[f"onnx_{dtype}"] = cycler(
                lambda j, s=sess, a=xo, b=yo: s.run(None, {"x": a[j : j + 1], "yhat": b[j : j + 1]}),
                np.arange(m),
            )
        p50: dict[str, list[float]] = {k: [] for k in paths}
        p99: dict[str, list[float]] = {k: [] for k in paths}
        for _ in range(rounds):
            for name, fn in paths.items():
                t = time_calls(fn, calls) * 1e6
                p50[name].append(float(np.median(t)))
                p99[name].append(float(np.quantile(t, 0.99)))
    out: dict[str, Any] = {
        "unit": "microseconds per query",
        "torch_threads": torch.get_num_threads(),
        "queries": m,
        "accept_fraction": float((verdicts == "ACCEPT").mean()),
        "verdict_fractions": {k: float(len(v) / m) for k, v in groups.items()},
        "paths": {k: {"p50": spread(p50[k]), "p99": spread(p99[k])} for k in paths},
        "fast_path": _fast_path_shares(q, xs, ys, verdicts != "OUTSIDE_DOMAIN") if full else None,
        "decided_by_in_domain": {
            k: int(sum(d.decided_by.name == k and d.in_domain for d in decisions)) for k in ("BOUND", "EXACT")
        },
    }
    bare = out["paths"]["bare_forward"]
    for k in paths:
        r = out["paths"][k]
        r["p50_ratio_to_bare_forward"] = r["p50"]["median"] / bare["p50"]["median"]
        r["p99_ratio_to_bare_forward"] = r["p99"]["median"] / bare["p99"]["median"]
    return out


def _rate(fn: Any, batch: int, min_seconds: float = 0.15, rounds: int = 3) -> dict[str, float]:
    fn()
    rates = []
    for _ in range(rounds):
        calls, t0 = 0, time.perf_counter()
        while True:
            fn()
            calls += 1
            dt = time.perf_counter() - t0
            if dt >= min_seconds:
                break
        rates.append(calls * batch / dt)
    return spread(rates)


def batch_throughput(
    model: IPCModel,
    queries: PerceptionDataset,
    sizes: tuple[int, ...] = BATCH_SIZES,
    onnx: dict[str, Any] | None = None,
    full: bool = True,
) -> dict[str, Any]:
    """Queries per second per batch size: the guarded ``predict_sets``, ``model.predict``, bare torch.

    ``full`` adds the engine's arrays, the float64 layers alone, ONNX Runtime and the engine with
    NumPy's default BLAS threads.
    """
    reps = -(-max(sizes) // len(queries))
    xs_all, ys_all = np.tile(queries.x, (reps, 1)), np.tile(queries.yhat, (reps, 1))
    eng = model.engine
    body = model.network.body
    scale = 1.0 if model.calibration is None else None
    # the network's layers alone in float64 (the engine's products, chunked as the engine
    # chunks; no standardisation, heads, moments or Cholesky): a ceiling for any evaluation
    # of the same network whose sets are float64
    layers, chunk = eng.float64_layers, eng.chunk
    domain = model.domain
    bare_model = model.with_calibration(model.calibration, None)
    if domain is not None:
        domain.prepare()  # the index is built once per model, not in the first timed call
    out: dict[str, Any] = {
        "unit": "queries per second",
        "sizes": list(sizes),
        "outside_fraction": outside_fraction(model, queries),
        "paths": {},
    }
    for b in sizes:
        xs, ys = xs_all[:b].copy(), ys_all[:b].copy()
        z = torch.from_numpy(((np.hstack([xs, ys]) - eng.in_mean) * eng.in_scale).astype(np.float32))

        def engine_arrays(xs: np.ndarray = xs, ys: np.ndarray = ys) -> None:
            c, C = model.raw_arrays(xs, ys)
            if scale is None:
                C / model.calibration.scale_for(xs, ys)[:, None, None]  # type: ignore[union-attr]

        def bare(z: torch.Tensor = z) -> None:
            with torch.inference_mode():
                body(z)

        z64 = z.numpy().astype(np.float64)

        def float64_layers(z64: np.ndarray = z64) -> None:
            for start in range(0, len(z64), chunk):
                layers(z64[start : start + chunk])

        inputs = PerceptionInputs(xs, ys)
        fns: dict[str, Any] = {
            "predict_sets": lambda inputs=inputs: predict_sets(model, inputs),
            "predict_sets_without_domain": lambda inputs=inputs: predict_sets(bare_model, inputs),
            "domain_contains": lambda xs=xs, ys=ys: domain.contains(xs, ys) if domain is not None else None,
            "model_predict": lambda xs=xs, ys=ys: model.predict_unguarded(xs, ys),
            "bare_torch_forward": bare,
        }
        if full:
            fns |= {"engine_arrays": engine_arrays, "float64_layers_only": float64_layers}
        for dtype, entry in (onnx or {}).items() if full else ():
            sess, np_t, _ = entry
            xo, yo = xs.astype(np_t), ys.astype(np_t)
            fns[f"onnx_{dtype}"] = lambda s=sess, a=xo, c=yo: s.run(None, {"x": a, "yhat": c})
        for name, fn in fns.items():
            out["paths"].setdefault(name, {})[str(b)] = _rate(fn, b)
        if not full:
            continue
        try:
            from threadpoolctl import threadpool_limits
        except ImportError:
            continue
        with threadpool_limits(limits=os.cpu_count(), user_api="blas"):
            out["paths"].setdefault("engine_arrays_blas_default_threads", {})[str(b)] = _rate(
                engine_arrays, b
            )
    onnx_names = [k for k in out["paths"] if k.startswith("onnx_")]
    out["onnx_faster_than_engine_at"] = {
        k: [
            b
            for b in sizes
            if out["paths"][k][str(b)]["median"] > out["paths"]["engine_arrays"][str(b)]["median"]
        ]
        for k in onnx_names
    }
    return out


def domain_methods(model: IPCModel, queries: PerceptionDataset, size: int = 10_000) -> dict[str, Any]:
    """The exact threshold test and the distances, timed several ways on ``size`` of the queries (tiled).

    ``exact_ckdtree``: SciPy's k-d tree on every whitened query (the test before issue 30);
    ``blas_product``: the float32 product over every reference with its rounding bound
    (:meth:`~ipcverify.guard.DomainIndex.scan`), the exact test in the band;
    ``tree_search``: :meth:`~ipcverify.guard.DomainModel.contains` (what ships: the compiled
    search, the product only for queries over the search budget); ``distance``: the exact
    distances (:meth:`~ipcverify.guard.DomainModel.distance`). Microseconds per query, wall and
    CPU, median of 3; ``agree``: the three tests gave the same answer for every query.
    """
    dom = model.domain
    if dom is None:
        return {}
    reps = -(-size // len(queries))
    x, y = np.tile(queries.x, (reps, 1))[:size].copy(), np.tile(queries.yhat, (reps, 1))[:size].copy()
    index = dom.index()

    def exact() -> np.ndarray:
        d, _ = dom._tree.query(dom.whiten(x, y), k=[dom.k])
        return np.asarray(d[:, 0] <= dom.threshold)

    def product() -> np.ndarray:
        w = dom.whiten(x, y)
        codes = index.scan(w, dom.threshold, dom.k)
        band = np.flatnonzero(codes == -1)
        if len(band):
            codes[band] = dom._tree.query(w[band], k=[dom.k])[0][:, 0] <= dom.threshold
        return np.asarray(codes == 1)

    methods = {
        "exact_ckdtree": exact,
        "blas_product": product,
        "tree_search": lambda: dom.contains(x, y),
        "distance": lambda: dom.distance(x, y),
    }
    out: dict[str, Any] = {"queries": size, "references": dom.n, "inputs": len(dom.mean), "methods": {}}
    answers = {}
    for name, fn in methods.items():
        answers[name] = fn()  # also compiles
        wall, cpu = [], []
        for _ in range(3):
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            wall.append((time.perf_counter() - t0) / size * 1e6)
            cpu.append((time.process_time() - c0) / size * 1e6)
        out["methods"][name] = {"us_per_query_wall": spread(wall), "us_per_query_cpu": spread(cpu)}
    inside = answers["exact_ckdtree"]
    out["agree"] = bool(
        np.array_equal(inside, answers["blas_product"])
        and np.array_equal(inside, answers["tree_search"])
        and np.array_equal(inside, answers["distance"] <= dom.threshold)
    )
    out["outside_fraction"] = float(1.0 - inside.mean())
    codes = index.decide(x, y, dom.mean, dom.whitening.T.copy(), dom.threshold, dom.k)
    out["tree_tiers"] = {
        "decided_by_the_search": float((codes >= 0).mean()),
        "over_budget_to_the_product": float((codes == -2).mean()),
        "in_the_band_to_the_exact_test": float((codes == -1).mean()),
        "index": index.prune_stats(),
    }
    return out


def _ratios(result: dict[str, Any], sizes: tuple[int, ...]) -> None:
    """The single-query and batch ratios to the bare forward, added to ``result`` in place."""
    sq = result["single_query"]["paths"]
    result["single_query_ratio_to_bare_forward"] = sq["decide"]["p50_ratio_to_bare_forward"]
    result["single_query_p99_ratio_to_bare_forward"] = sq["decide"]["p99_ratio_to_bare_forward"]
    if "decide_float" in sq:
        result["single_query_float_ratio_to_bare_forward"] = sq["decide_float"]["p50_ratio_to_bare_forward"]
    if "decide_without_domain_test" in sq:
        result["single_query_ratio_without_domain_test"] = sq["decide_without_domain_test"][
            "p50_ratio_to_bare_forward"
        ]
    bt = result["batch_throughput"]["paths"]
    bare = bt["bare_torch_forward"]
    for key, path in (
        ("batch_guarded_ratio_to_bare_forward", "predict_sets"),
        ("batch_predict_ratio_to_bare_forward", "model_predict"),
        ("batch_float64_layers_ratio_to_bare_forward", "float64_layers_only"),
    ):
        if path in bt:
            result[key] = {str(b): bt[path][str(b)]["median"] / bare[str(b)]["median"] for b in sizes}


def bench_latency(
    workloads: list[Workload] | IPCModel,
    queries: PerceptionDataset | None = None,
    rounds: int = 5,
    calls: int = 2000,
    sizes: tuple[int, ...] = BATCH_SIZES,
) -> dict[str, Any]:
    """Single-query latency, batch throughput and the domain test's methods, per workload.

    The first workload gets every path (and the ONNX check) and its numbers are also the top-level
    keys (the targets'); the others the guarded paths at :data:`SECOND_SIZES` (or ``sizes``, if
    smaller). A bare ``(model, queries)`` is one workload.
    """
    torch.set_num_threads(1)
    if isinstance(workloads, IPCModel):
        assert queries is not None  # noqa: S101 - benchmark harness
        workloads = [Workload("default", workloads, queries, "the given model and queries")]
    first = workloads[0]
    result: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        onnx = _onnx_sessions(first.model, Path(tmp))
        result["onnx_available"] = bool(onnx)
        if onnx:
            from ipcverify.io._onnx import check_onnx

            n = min(len(first.queries), 2000)
            result["onnx_check"] = {
                dtype: vars(
                    check_onnx(first.model, onnx[dtype][2].path, first.queries.x[:n], first.queries.yhat[:n])
                )
                for dtype in ("float64", "float32")
            }
        per: dict[str, Any] = {}
        for i, w in enumerate(workloads):
            full = i == 0
            wsizes = sizes if full else tuple(b for b in SECOND_SIZES if b <= max(sizes)) or sizes[-1:]
            r: dict[str, Any] = {
                "description": w.description,
                "queries": len(w.queries),
                "outside_fraction": outside_fraction(w.model, w.queries),
                "single_query_has_domain_test": w.model.domain is not None,
                "single_query": single_query(w.model, w.queries, rounds, calls, onnx if full else None, full),
                "batch_throughput": batch_throughput(
                    w.model, w.queries, wsizes, onnx if full else None, full
                ),
                "domain_methods": domain_methods(w.model, w.queries, min(10_000, max(sizes))),
            }
            _ratios(r, wsizes)
            per[w.name] = r
    result |= per[first.name]
    result["workload"] = first.name
    result["workloads"] = per
    return result
