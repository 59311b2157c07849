"""ONNX graph of the low-rank ensemble (:mod:`ipcverify.network._lowrank`), in elementwise operations.

ONNX has no Cholesky operator. The graph therefore forms the moment-matched covariance
``Sigma`` (B, n, n) with matrix products and then writes its Cholesky factor and the
triangular inverse out entry by entry (``n (n + 1) / 2`` entries each), exactly as the
float64 engine does (:func:`ipcverify.network.cholesky_lower`,
:func:`~ipcverify.network.lower_inverse`), so both agree to rounding. The members
are evaluated together: one batched ``MatMul`` per layer with the stacked (K, in, out)
weights. Used by :func:`ipcverify.io.build_onnx`; checked in ONNX Runtime against the
engine and the torch network by :func:`ipcverify.io.check_onnx`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ipcverify.network._architecture import LOGDIAG_CLAMP
from ipcverify.network._kind import ConstFn, NodeFn
from ipcverify.network._onnx_mlp import ACTIVATION_OPS, layer_nodes, scaled_shape_nodes

if TYPE_CHECKING:
    from ipcverify.network._lowrank_engine import LowRankEngine


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
    nu = n * (n + 1)
    i64 = np.int64
    width = eng.first_weight.shape[2] - nu
    act = ACTIVATION_OPS[cfg.activation]

    def piece(src: str, start: int, stop: int, name: str, axis: int = -1) -> str:
        bounds = [const(f"{name}_start", [start], i64), const(f"{name}_stop", [stop], i64)]
        return node("Slice", [src, *bounds, const(f"{name}_axis", [axis], i64)], name)

    lin_mm = node("MatMul", [z, const("lin_weight", eng.lin_weight)], "lin_mm")
    lin = node("Add", [lin_mm, const("lin_bias", eng.lin_bias)], "lin")
    first = node("MatMul", [z, const("W0", eng.first_weight)], "matmul0")  # (K, B, ·)
    first = node("Add", [first, const("b0", eng.first_bias)], "linear0")
    h = node(act, [piece(first, 0, width, "hidden_in0")], "hidden0")
    skip = piece(first, width, width + nu, "skip_u")
    h = layer_nodes(h, eng.weights, eng.biases, cfg.activation, node, const, start=1)
    # every member's U = [V | o] (n x (n + 1)) and log-diagonal h, in the engine's layout
    u_flat = node("Add", [piece(h, 0, nu, "u_net"), skip], "u_flat")
    U = node("Reshape", [u_flat, const("u_shape", [k, -1, n, n + 1], i64)], "U")
    offset = piece(U, n, n + 1, "o")  # (K, B, n, 1)
    mean = node(
        "Div",
        [
            node("ReduceSum", [offset, const("ax0", [0], i64)], "o_sum", keepdims=0),
            const("members", float(k)),
        ],
        "o_mean",
    )  # (B, n, 1)
    dev = node("Sub", [offset, mean], "o_dev")
    cols = node("Concat", [piece(U, 0, n, "V"), dev], "columns", axis=-1)  # (K, B, n, n + 1)
    cols = node("Transpose", [cols], "columns_t", perm=[1, 2, 0, 3])  # (B, n, K, n + 1)
    cols = node("Reshape", [cols, const("cols_shape", [-1, n, k * (n + 1)], i64)], "columns_flat")
    outer = node("MatMul", [cols, node("Transpose", [cols], "columns_flat_t", perm=[0, 2, 1])], "outer")
    spread = node("Div", [outer, "members"], "spread")  # (B, n, n)
    log_var = node(
        "Clip", [piece(h, nu, nu + n, "h_raw"), const("lo", -LOGDIAG_CLAMP), const("hi", LOGDIAG_CLAMP)], "h"
    )
    var = node("Exp", [node("Mul", [log_var, const("two", 2.0)], "h2")], "var")
    var = node("Div", [node("ReduceSum", [var, "ax0"], "var_sum", keepdims=0), "members"], "var_mean")
    diag = node(
        "Mul",
        [node("Unsqueeze", [var, const("ax_last", [-1], i64)], "var_col"), const("eye", np.eye(n))],
        "diag",
    )
    cov = node("Add", [spread, diag], "Sigma")  # (B, n, n)
    mean = node("Squeeze", [mean, "ax_last"], "o_mean_flat")  # (B, n)

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
    scaled_shape_nodes(inv, eng.inv_sigma, node, const, scale)
