"""Latency and throughput of one IPC: single queries against a bare torch forward, batches, ONNX.

Single query (what a control loop does once per camera frame), all with torch and
ONNX Runtime limited to **one thread**:

* ``bare_forward`` -- the reference: ``model.network.body`` (a plain
  ``torch.nn.Sequential``) on a pre-normalised float32 tensor of shape (1, d + n),
  inside one ``torch.inference_mode()`` block entered outside the timing loop (the
  cheapest torch call there is; no normalisation, no set, no decision).
* ``ellipsoid`` -- :meth:`ipcverify.query.IPCQuery.ellipsoid`: (x, yhat) -> calibrated (c, C).
* ``decide_float`` -- query -> ellipsoid -> domain test -> float landing decision (not a proof).
* ``decide`` -- query -> ellipsoid -> domain test -> landing decision of record (float64 with a
  rigorous rounding bound, exact arithmetic inside the band: every answer proven), over the
  test split's queries in order: the path the landing controller runs. The model should carry
  the domain of validity a default :func:`~ipcverify.calibrate.calibrate` fits (as
  ``python -m benchmarks.run`` gives it); ``decide_without_domain_test`` is the same model and
  queries with the domain dropped, to show what the domain test costs. Also over the same
  queries shuffled (``decide_shuffled``: no frame-to-frame coherence for the domain test's
  cache), and split by answer: accepted, rejected inside the domain, outside the domain.
* ``onnx_float64`` / ``onnx_float32`` -- ONNX Runtime on the exported graph, (1, d) inputs.

Each is timed call by call in interleaved rounds; p50 and p99 are taken per round and
the median (and min/max) over rounds is reported, with both ratios to the bare forward.
``fast_path`` reports how the landing decisions of the test split were reached
(:func:`ipcverify.landing_bound.landing_by_bound`: float bound alone, exact integer turn-off
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
from pathlib import Path
from typing import Any

import numpy as np
import torch

from benchmarks.common import spread, time_calls
from case_studies.quad_landing.landing.state_machine import LandingParams
from ipcverify.data import PerceptionDataset
from ipcverify.inference import CHUNK
from ipcverify.landing_bound import landing_by_bound
from ipcverify.lowrank_engine import LowRankEngine
from ipcverify.model import IPCModel
from ipcverify.query import IPCQuery

__all__ = ["BATCH_SIZES", "single_query", "batch_throughput", "bench_latency"]

BATCH_SIZES: tuple[int, ...] = (1, 10, 100, 1_000, 10_000, 100_000)


def _onnx_sessions(model: IPCModel, folder: Path) -> dict[str, Any]:
    from ipcverify.export import export_onnx, onnx_session

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


def _fast_path_shares(q: IPCQuery, xs: np.ndarray, ys: np.ndarray, in_domain: np.ndarray) -> dict[str, Any]:
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
) -> dict[str, Any]:
    """Per-call latency (microseconds) of the single-query paths; see the module docstring."""
    q = IPCQuery(model, LandingParams.defaults().target)
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
        paths["ellipsoid"] = cycler(lambda j: q.ellipsoid(xs[j], ys[j]), np.arange(m))
        paths["decide_float"] = cycler(lambda j: q.decide_float(xs[j], ys[j]), np.arange(m))
        paths["decide"] = cycler(lambda j: q.decide(xs[j], ys[j]), np.arange(m))
        paths["decide_shuffled"] = cycler(lambda j: q.decide(xs[j], ys[j]), shuffled)
        if model.domain is not None:
            bare_q = IPCQuery(model.with_calibration(model.calibration, None), q.target)
            paths["decide_without_domain_test"] = cycler(lambda j: bare_q.decide(xs[j], ys[j]), np.arange(m))
        for name, idx in groups.items():
            if len(idx):
                paths[f"decide_{name}_queries"] = cycler(lambda j: q.decide(xs[j], ys[j]), idx)
        paths["model_predict_one"] = cycler(
            lambda j: model.predict(xs[j : j + 1], ys[j : j + 1]), np.arange(m)
        )
        for dtype, entry in (onnx or {}).items():
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
        "fast_path": _fast_path_shares(q, xs, ys, verdicts != "OUTSIDE_DOMAIN"),
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
) -> dict[str, Any]:
    """Queries per second per batch size for predict, engine arrays, ONNX Runtime and bare torch."""
    reps = -(-max(sizes) // len(queries))
    xs_all, ys_all = np.tile(queries.x, (reps, 1)), np.tile(queries.yhat, (reps, 1))
    eng = model.engine
    body = model.network.body
    scale = 1.0 if model.calibration is None else None
    # the network's layers alone in float64 (the engine's products, chunked as the engine
    # chunks; no standardisation, heads, moments or Cholesky): a ceiling for any evaluation
    # of the same network whose sets are float64
    layers = eng.layers if isinstance(eng, LowRankEngine) else eng.mlp
    chunk = eng.chunk if isinstance(eng, LowRankEngine) else CHUNK
    out: dict[str, Any] = {"unit": "queries per second", "sizes": list(sizes), "paths": {}}
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

        fns: dict[str, Any] = {
            "model_predict": lambda xs=xs, ys=ys: model.predict(xs, ys),
            "engine_arrays": engine_arrays,
            "bare_torch_forward": bare,
            "float64_layers_only": float64_layers,
        }
        for dtype, entry in (onnx or {}).items():
            sess, np_t, _ = entry
            xo, yo = xs.astype(np_t), ys.astype(np_t)
            fns[f"onnx_{dtype}"] = lambda s=sess, a=xo, c=yo: s.run(None, {"x": a, "yhat": c})
        for name, fn in fns.items():
            out["paths"].setdefault(name, {})[str(b)] = _rate(fn, b)
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


def bench_latency(
    model: IPCModel,
    queries: PerceptionDataset,
    rounds: int = 5,
    calls: int = 2000,
    sizes: tuple[int, ...] = BATCH_SIZES,
) -> dict[str, Any]:
    """Single-query latency, batch throughput and the ONNX check, in one dictionary."""
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        onnx = _onnx_sessions(model, Path(tmp))
        result: dict[str, Any] = {"onnx_available": bool(onnx)}
        if onnx:
            from ipcverify.export import check_onnx

            n = min(len(queries), 2000)
            result["onnx_check"] = {
                dtype: vars(check_onnx(model, onnx[dtype][2].path, queries.x[:n], queries.yhat[:n]))
                for dtype in ("float64", "float32")
            }
        result["single_query"] = single_query(model, queries, rounds, calls, onnx)
        result["batch_throughput"] = batch_throughput(model, queries, sizes, onnx)
    sq = result["single_query"]["paths"]
    result["single_query_ratio_to_bare_forward"] = sq["decide"]["p50_ratio_to_bare_forward"]
    result["single_query_p99_ratio_to_bare_forward"] = sq["decide"]["p99_ratio_to_bare_forward"]
    result["single_query_float_ratio_to_bare_forward"] = sq["decide_float"]["p50_ratio_to_bare_forward"]
    result["single_query_has_domain_test"] = model.domain is not None
    if "decide_without_domain_test" in sq:
        result["single_query_ratio_without_domain_test"] = sq["decide_without_domain_test"][
            "p50_ratio_to_bare_forward"
        ]
    bt = result["batch_throughput"]["paths"]
    result["batch_predict_ratio_to_bare_forward"] = {
        str(b): bt["model_predict"][str(b)]["median"] / bt["bare_torch_forward"][str(b)]["median"]
        for b in sizes
    }
    result["batch_float64_layers_ratio_to_bare_forward"] = {
        str(b): bt["float64_layers_only"][str(b)]["median"] / bt["bare_torch_forward"][str(b)]["median"]
        for b in sizes
    }
    return result
