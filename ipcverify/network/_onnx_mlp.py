"""ONNX graph of the paper's heads (:class:`~ipcverify.network.IPCNetwork`): the MLP and its two heads.

The operations of the dense float64 engine (:mod:`ipcverify.network._engine`): the MLP, the
centre head ``base + sigma * o`` and the shape head (Cholesky diagonal ``exp(clip(., -12, 12))``
or the full matrix), then ``L diag(1 / sigma)`` and the calibration's scale. Used by
:func:`ipcverify.io.build_onnx` through :meth:`InferenceEngine.onnx_nodes`; checked in ONNX
Runtime against the engine and the torch network by :func:`ipcverify.io.check_onnx`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ipcverify.network._architecture import LOGDIAG_CLAMP
from ipcverify.network._kind import ConstFn, NodeFn

if TYPE_CHECKING:
    from ipcverify.network._engine import InferenceEngine

FloatArray = NDArray[np.float64]

#: ONNX operator of each hidden-layer activation.
ACTIVATION_OPS = {"relu": "Relu", "tanh": "Tanh", "elu": "Elu"}


def layer_nodes(
    h: str,
    weights: Sequence[FloatArray],
    biases: Sequence[FloatArray],
    activation: str,
    node: NodeFn,
    const: ConstFn,
    start: int = 0,
) -> str:
    """Affine layers (``MatMul``, ``Add``), each but the last followed by the activation; the output's name.

    Layer ``i`` is named ``matmul{start + i}``, ``linear{start + i}``, ``hidden{start + i}``
    (stacked (K, in, out) weights of an ensemble broadcast over the members as they are).
    """
    act = ACTIVATION_OPS[activation]
    last = len(weights) - 1
    for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
        j = start + i
        h = node("MatMul", [h, const(f"W{j}", w)], f"matmul{j}")
        h = node("Add", [h, const(f"b{j}", b)], f"linear{j}")
        if i < last:
            h = node(act, [h], f"hidden{j}")
    return h


def scaled_shape_nodes(
    matrix: str, inv_sigma: FloatArray, node: NodeFn, const: ConstFn, scale: float | None
) -> None:
    """The output ``shape``: ``matrix diag(1 / sigma)``, divided by the calibration's ``scale`` if given."""
    raw = node("Mul", [matrix, const("inv_sigma", inv_sigma)], "shape" if scale is None else "raw_shape")
    if scale is not None:
        node("Div", [raw, const("scale", scale)], "shape")


def mlp_nodes(
    eng: InferenceEngine, z: str, node: NodeFn, const: ConstFn, scale: float | None, dtype: object = None
) -> None:
    """Add the nodes from the standardised inputs ``z`` (B, d + n) to the outputs ``center`` and ``shape``.

    ``yhat`` must be a graph input; ``scale`` (the calibration's, or None) divides the shape;
    ``dtype`` (the graph's float type) is not needed: every constant takes the graph's.
    """
    cfg = eng.config
    n = cfg.y_dim
    z = layer_nodes(z, eng.weights, eng.biases, cfg.activation, node, const)
    i64 = np.int64
    o = node("Slice", [z, const("o_start", [0], i64), const("o_end", [n], i64), const("ax", [1], i64)], "o")
    k = cfg.n_shape_outputs
    s = node("Slice", [z, const("s_start", [n], i64), const("s_end", [n + k], i64), "ax"], "s")
    base = "yhat" if cfg.center == "offset" else const("y_mean", eng.y_mean)
    node("Add", [base, node("Mul", [o, const("sigma", eng.sigma)], "offset")], "center")
    if cfg.param == "full":
        L = node("Reshape", [s, const("L_shape", [-1, n, n], i64)], "L")
    else:
        diag = np.zeros(k)
        diag[eng.diag_pos] = 1.0
        clipped = node("Clip", [s, const("lo", -LOGDIAG_CLAMP), const("hi", LOGDIAG_CLAMP)], "s_clipped")
        on_diag = node("Mul", [node("Exp", [clipped], "s_exp"), const("diag_mask", diag)], "diag_part")
        off_diag = node("Mul", [s, const("off_mask", 1.0 - diag)], "off_part")
        vals = node("Add", [on_diag, off_diag], "tril_values")
        embed = np.zeros((k, n * n))
        embed[np.arange(k), eng.tril_rows * n + eng.tril_cols] = 1.0
        flat = node("MatMul", [vals, const("tril_embed", embed)], "L_flat")
        L = node("Reshape", [flat, const("L_shape", [-1, n, n], i64)], "L")
    scaled_shape_nodes(L, eng.inv_sigma, node, const, scale)
