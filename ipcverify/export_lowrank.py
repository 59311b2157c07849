"""ONNX graph of the low-rank ensemble (:mod:`ipcverify.lowrank`), written with elementwise operations.

ONNX has no Cholesky operator. The graph therefore forms the moment-matched covariance
``Sigma`` (B, n, n) with matrix products and then writes its Cholesky factor and the
triangular inverse out entry by entry (``n (n + 1) / 2`` entries each), exactly as the
float64 engine does (:func:`ipcverify.lowrank_engine.cholesky_lower`,
:func:`~ipcverify.lowrank_engine.lower_inverse`), so both agree to rounding. The members
are evaluated together: one batched ``MatMul`` per layer with the stacked (K, in, out)
weights. Used by :func:`ipcverify.export.build_onnx`; checked in ONNX Runtime against the
engine and the torch network by :func:`ipcverify.export.check_onnx`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ipcverify.architecture import LOGDIAG_CLAMP
from ipcverify.lowrank_engine import LowRankEngine

__all__ = ["lowrank_nodes"]

#: ``node(op, inputs, output_name, **attributes) -> output_name``
NodeFn = Callable[..., str]
#: ``const(name, value, dtype=graph dtype) -> name`` (an initializer)
ConstFn = Callable[..., str]


def lowrank_nodes(
    eng: LowRankEngine,
    z: str,
    node: NodeFn,
    const: ConstFn,
    scale: float | None,
    dtype: type[np.floating[Any]],
) -> None:
    """Add the nodes from the standardised inputs ``z`` (B, d + n) to the outputs ``center`` and ``shape``.

    ``yhat`` must be a graph input; ``scale`` (the calibration's, or None) divides the shape;
    ``dtype`` is the graph's float type.
    """
    from onnx import numpy_helper

    cfg = eng.config
    n, k = cfg.y_dim, cfg.members
    i64 = np.int64
    width = eng.first_weight.shape[2] - n - n * n
    act = {"relu": "Relu", "tanh": "Tanh", "elu": "Elu"}[cfg.activation]

    def piece(src: str, start: int, stop: int, name: str, axis: int = -1) -> str:
        return node(
            "Slice",
            [
                src,
                const(f"{name}_start", [start], i64),
                const(f"{name}_stop", [stop], i64),
                const(f"{name}_axis", [axis], i64),
            ],
            name,
        )

    lin = node(
        "Add",
        [node("MatMul", [z, const("lin_weight", eng.lin_weight)], "lin_mm"), const("lin_bias", eng.lin_bias)],
        "lin",
    )
    first = node("MatMul", [z, const("W0", eng.first_weight)], "matmul0")  # (K, B, ·)
    first = node("Add", [first, const("b0", eng.first_bias)], "linear0")
    h = node(act, [piece(first, 0, width, "hidden_in0")], "hidden0")
    skip = piece(first, width, width + n, "center_skip")
    fskip = piece(first, width + n, width + n + n * n, "factor_skip")
    last = len(eng.weights) - 1
    for i, (w, b) in enumerate(zip(eng.weights, eng.biases, strict=True)):
        h = node(
            "Add",
            [node("MatMul", [h, const(f"W{i + 1}", w)], f"matmul{i + 1}"), const(f"b{i + 1}", b)],
            f"linear{i + 1}",
        )
        if i < last:
            h = node(act, [h], f"hidden{i + 1}")
    offset = node("Add", [piece(h, 0, n, "o_net"), skip], "o")  # (K, B, n)
    log_diag = node(
        "Clip", [piece(h, n, 2 * n, "h_raw"), const("lo", -LOGDIAG_CLAMP), const("hi", LOGDIAG_CLAMP)], "h"
    )
    factor = node("Add", [piece(h, 2 * n, 2 * n + n * n, "v_net"), fskip], "v_flat")
    factor = node("Reshape", [factor, const("v_shape", [k, -1, n, n], i64)], "V")
    mean = node("ReduceMean", [offset], "o_mean", axes=[0], keepdims=0)  # (B, n)
    dev = node("Sub", [offset, mean], "o_dev")
    cols = node(
        "Concat",
        [factor, node("Unsqueeze", [dev, const("ax_last", [-1], i64)], "dev_col")],
        "columns",
        axis=-1,
    )  # (K, B, n, n + 1)
    outer = node("MatMul", [cols, node("Transpose", [cols], "columns_t", perm=[0, 1, 3, 2])], "outer")
    spread = node(
        "Div",
        [
            node("ReduceSum", [outer, const("ax0", [0], i64)], "outer_sum", keepdims=0),
            const("members", float(k)),
        ],
        "spread",
    )
    diag = node(
        "ReduceMean",
        [node("Exp", [node("Mul", [log_diag, const("two", 2.0)], "h2")], "var")],
        "var_mean",
        axes=[0],
        keepdims=0,
    )
    diag = node("Mul", [node("Unsqueeze", [diag, "ax_last"], "var_col"), const("eye", np.eye(n))], "diag")
    cov = node("Add", [spread, diag], "Sigma")  # (B, n, n)

    rows_of_sigma = [
        node("Gather", [cov, const(f"row_index{i}", i, i64)], f"Sigma_row{i}", axis=1) for i in range(n)
    ]
    col_index = [const(f"col_index{j}", [j], i64) for j in range(n)]

    def entry(i: int, j: int) -> str:  # Sigma[:, i, j] as (B, 1)
        return node("Gather", [rows_of_sigma[i], col_index[j]], f"Sigma_{i}{j}", axis=1)

    nan = const("nan", np.nan)
    zero = const("zero", 0.0)
    L: dict[tuple[int, int], str] = {}
    for i in range(n):
        for j in range(i + 1):
            s = entry(i, j)
            for m in range(j):
                s = node("Sub", [s, node("Mul", [L[i, m], L[j, m]], f"L{i}{m}_L{j}{m}")], f"s{i}{j}_{m}")
            if i == j:
                ok = node("Where", [node("Greater", [s, zero], f"pos{i}"), s, nan], f"pivot{i}")
                L[i, i] = node("Sqrt", [ok], f"L{i}{i}")
            else:
                L[i, j] = node("Div", [s, L[j, j]], f"L{i}{j}")
    X: dict[tuple[int, int], str] = {}
    one = const("one", 1.0)
    for i in range(n):
        X[i, i] = node("Div", [one, L[i, i]], f"X{i}{i}")
        for j in range(i):
            terms = [node("Mul", [L[i, m], X[m, j]], f"L{i}{m}_X{m}{j}") for m in range(j, i)]
            acc = terms[0]
            for t, term in enumerate(terms[1:]):
                acc = node("Add", [acc, term], f"acc{i}{j}_{t}")
            X[i, j] = node("Neg", [node("Div", [acc, L[i, i]], f"q{i}{j}")], f"X{i}{j}")
    zero_value = numpy_helper.from_array(np.zeros(1, dtype=dtype), "zero_value")
    zeros = node("ConstantOfShape", [node("Shape", [X[0, 0]], "col_shape")], "zeros", value=zero_value)
    rows = [
        node("Concat", [X[i, j] if j <= i else zeros for j in range(n)], f"row{i}", axis=1) for i in range(n)
    ]
    inv = node(
        "Reshape", [node("Concat", rows, "rows", axis=1), const("shape_shape", [-1, n, n], i64)], "M_inv"
    )
    node(
        "Add",
        [node("Add", ["yhat", lin], "base"), node("Mul", [mean, const("sigma", eng.sigma)], "offset")],
        "center",
    )
    raw = node("Mul", [inv, const("inv_sigma", eng.inv_sigma)], "shape" if scale is None else "raw_shape")
    if scale is not None:
        node("Div", [raw, const("scale", scale)], "shape")
