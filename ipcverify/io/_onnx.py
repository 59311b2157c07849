"""Export a trained (and globally calibrated) IPC to ONNX, and check the export.

The exported graph maps ``x`` (B, d) and ``yhat`` (B, n) to ``center`` (B, n) and
``shape`` (B, n, n), the contract's ellipsoids ``E(c, C) = {y : ||C (y - c)|| <= 1}``,
with exactly the operations of the float64 engine: input standardisation, then the engine's
own nodes (:meth:`ipcverify.network.Engine.onnx_nodes`): for the paper's heads
(:mod:`ipcverify.network._onnx_mlp`) the MLP, the centre head and the shape head (Cholesky
diagonal ``exp(clip(., -12, 12))`` or the full matrix); for the default low-rank ensemble
(:mod:`ipcverify.network._onnx_lowrank`) the members' stacked MLPs, the moment matching and a
Cholesky factorisation written out entry by entry. Then ``C / scale`` for a calibrated model.

* ``dtype="float64"`` (default) evaluates in float64 like the reference engine, so the
  exported sets are the calibrated sets up to the summation order of the matrix
  products (relative differences near 1e-15).
* ``dtype="float32"`` is the network's training precision: smaller and, in ONNX
  Runtime, faster for large batches; differences to the float64 engine are near
  1e-6 relative, inside the calibration's ``SCALE_MARGIN`` of 1e-5 only for
  well-conditioned shapes -- prefer float64 where the guarantee matters.

A model with a global calibration is exported with its scale; a Mondrian calibration
needs a group lookup per query that the graph does not do, so its export is refused.

**The domain of validity is not in the graph.** A calibrated model's guarantee covers only
queries that pass its domain test (:mod:`ipcverify.guard._domain`): the distance to the nearest of up
to 10,000 calibration inputs, compared with a threshold in float64. An ONNX graph could compute
that distance, but with its own summation order, so near the threshold it could answer the
other way than the model -- it would not be the same test. The export therefore refuses a model
with a domain test unless ``without_domain=True`` (CLI ``--no-domain``): the exported sets are
then trustworthy only for queries the caller checks with the model itself
(``ipcverify predict``'s ``in_domain``, :class:`~ipcverify.decision.IPCQuery`). The graph's metadata
says ``domain_test = "not included"``.
The graph is built directly with :mod:`onnx.helper` (``pip install 'ipcverify[onnx]'``);
:func:`check_onnx` runs it in ONNX Runtime and compares it with the torch network and
the float64 engine.

Examples
--------
>>> import os, tempfile
>>> from ipcverify import IPCModel
>>> from ipcverify import example
>>> from ipcverify.network import ModelConfig
>>> m = example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(8,), param="cholesky")).model
>>> info = export_onnx(m, os.path.join(tempfile.mkdtemp(), "ipc.onnx"))  # doctest: +SKIP
>>> info.calibrated  # doctest: +SKIP
False
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from numpy.typing import NDArray

from ipcverify._package import VERSION
from ipcverify._wording._spelling import Remedy, option
from ipcverify.contract._model import IPCModel
from ipcverify.data._files import atomic_write
from ipcverify.errors import InvalidInputError

FloatArray = NDArray[np.float64]
Dtype = Literal["float64", "float32"]
#: ONNX opset of the exported graph.
OPSET = 17
_INSTALL_HINT = "install the optional extra: pip install 'ipcverify[onnx]'"


def _require(module: str) -> Any:
    try:
        return __import__(module)
    except ImportError:
        raise InvalidInputError(f"ONNX support needs the {module!r} package; {_INSTALL_HINT}") from None


def _scale(model: IPCModel) -> float | None:
    cal = model.calibration
    if cal is None:
        return None
    groups = cal.groups()
    if len(groups) == 1:
        return float(groups[0].scale)
    raise InvalidInputError(
        f"cannot export a model calibrated per group ({cal.summary().grouping}): its scale depends on a "
        "group looked up per query, which the ONNX graph does not do; calibrate it globally (without "
        f"{option('mondrian_column')}) to export it, or export the uncalibrated network and apply the "
        "group scales "
        "yourself"
    )


@dataclass(frozen=True, kw_only=True)
class ExportInfo:
    """What :func:`export_onnx` wrote.

    Attributes
    ----------
    path : Path
        The ONNX file.
    dtype : {"float64", "float32"}
        Precision of the graph.
    calibrated : bool
        Whether the calibration scale is part of the graph.
    scale : float or None
        The calibration scale applied (``shape = C / scale``).
    network_hash : str
        Fingerprint of the network's weights (as in calibration records).
    nbytes : int
        File size.
    """

    path: Path
    dtype: Dtype
    calibrated: bool
    scale: float | None
    network_hash: str
    nbytes: int

    def __post_init__(self) -> None:
        if self.dtype not in ("float64", "float32"):
            raise InvalidInputError(f"dtype must be 'float64' or 'float32'; got {self.dtype!r}")
        if self.calibrated != (self.scale is not None):
            raise InvalidInputError("a calibrated export must record its scale (and only then)")


def build_onnx(model: IPCModel, dtype: Dtype = "float64", *, without_domain: bool = False) -> Any:
    """The ONNX ``ModelProto`` of ``model``'s (calibrated) sets.

    Parameters
    ----------
    model : IPCModel
        Uncalibrated, or with a calibration of one group (a single scale).
    dtype : {"float64", "float32"}
        Precision of inputs, weights and outputs.
    without_domain : bool
        Export a model that carries a domain-of-validity test without it (the graph cannot
        reproduce it exactly; see the module docstring). Refused otherwise.

    Raises
    ------
    InvalidInputError
        For a Mondrian calibration, a domain test without ``without_domain``, an unknown ``dtype``,
        or when ``onnx`` is missing.
    """
    _scale(model)  # a Mondrian calibration cannot be exported at all: say that first
    check_domain_export(model, without_domain)
    if dtype not in ("float64", "float32"):
        raise InvalidInputError(
            f"dtype must be 'float64' or 'float32'; got {dtype!r} (use {option('dtype', 'float64')})"
        )
    onnx = _require("onnx")
    from onnx import TensorProto, helper, numpy_helper

    if model.config.activation == "elu" and dtype == "float64":
        raise InvalidInputError(
            "ONNX Runtime has no float64 Elu kernel, so an elu network cannot be exported in float64; "
            f"export it with {option('dtype', 'float32')}",
            remedies=(Remedy("dtype", "float32"),),
        )
    scale = _scale(model)
    eng = model.engine
    cfg = model.config
    d, n = cfg.x_dim, cfg.y_dim
    np_t = np.float64 if dtype == "float64" else np.float32
    elem = TensorProto.DOUBLE if dtype == "float64" else TensorProto.FLOAT
    inits: list[Any] = []
    nodes: list[Any] = []

    def const(name: str, value: Any, kind: Any = np_t) -> str:
        inits.append(numpy_helper.from_array(np.asarray(value, dtype=kind), name))
        return name

    def node(op: str, inputs: list[str], out: str, **attrs: Any) -> str:
        nodes.append(helper.make_node(op, inputs, [out], name=out, **attrs))
        return out

    z = node("Concat", ["x", "yhat"], "inputs", axis=1)
    z = node("Sub", [z, const("in_mean", eng.in_mean)], "centred")
    z = node("Mul", [z, const("in_scale", eng.in_scale)], "standardised")
    eng.onnx_nodes(z, node, const, scale, np_t)  # the network kind's own graph
    graph = helper.make_graph(
        nodes,
        "ipcverify_ipc",
        [
            helper.make_tensor_value_info("x", elem, ["B", d]),
            helper.make_tensor_value_info("yhat", elem, ["B", n]),
        ],
        [
            helper.make_tensor_value_info("center", elem, ["B", n]),
            helper.make_tensor_value_info("shape", elem, ["B", n, n]),
        ],
        initializer=inits,
    )
    proto = helper.make_model(
        graph,
        opset_imports=[helper.make_opsetid("", OPSET)],
        producer_name="ipcverify",
        producer_version=VERSION,
    )
    proto.ir_version = min(proto.ir_version, 8)
    meta = {
        "x_dim": str(d),
        "y_dim": str(n),
        "param": cfg.param,
        "center": cfg.center,
        "members": str(cfg.members),
        "dtype": dtype,
        "network_hash": model.weights.fingerprint(),
        "calibrated": "true" if scale is not None else "false",
        "domain_test": "not included" if model.domain is not None else "none in the model",
        "sets": "E(c, C) = {y : ||C (y - c)|| <= 1}; outputs center (B, n) and C = shape (B, n, n)",
    }
    if scale is not None and model.calibration is not None:
        c = model.calibration
        meta.update(scale=repr(scale), mode=c.mode, epsilon=repr(c.epsilon), delta=repr(c.delta), n=str(c.n))
    helper.set_model_props(proto, meta)
    onnx.checker.check_model(proto)
    return proto


def check_domain_export(model: IPCModel, without_domain: bool) -> None:
    """Refuse to export a model's sets without its domain test unless asked to (``--no-domain``).

    Parameters
    ----------
    model : IPCModel
        The model to export.
    without_domain : bool
        Whether the user asked to export without the domain test.

    Examples
    --------
    >>> from ipcverify import IPCModel
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> net = example(config=ModelConfig(x_dim=1, y_dim=1, hidden=(2,), param="cholesky")).model.network
    >>> check_domain_export(IPCModel(net), False)  # no domain test: nothing to leave out
    """
    dom = model.domain
    if dom is not None and not without_domain:
        raise InvalidInputError(
            f"this model carries a domain-of-validity test (its guarantee covers only queries within "
            f"distance {dom.threshold:.3g} of its {dom.n} calibration inputs), and an ONNX graph cannot "
            f"reproduce that test exactly; pass {option('without_domain')} to export the "
            "sets alone, and check each query with ipcverify predict (in_domain) or IPCQuery before "
            "trusting its set"
        )


def export_onnx(
    model: IPCModel, path: str | os.PathLike[str], dtype: Dtype = "float64", *, without_domain: bool = False
) -> ExportInfo:
    """Write ``model`` as an ONNX file (atomically); see the module docstring.

    Parameters
    ----------
    model : IPCModel
        The model.
    path : path-like
        The ONNX file to write.
    dtype : {"float64", "float32"}
        Precision of the exported graph.
    without_domain : bool
        Export the sets without the domain test (refused otherwise for a model that has one).

    Raises
    ------
    InvalidInputError
        For a Mondrian-calibrated model (refused: not exportable), a model with a domain test
        unless ``without_domain`` (the graph cannot carry it exactly), an unknown ``dtype``, or
        when the ``onnx`` package is missing.
    """
    proto = build_onnx(model, dtype, without_domain=without_domain)
    data = proto.SerializeToString()
    p = Path(path)
    atomic_write(p, lambda f: f.write(data))
    scale = _scale(model)
    return ExportInfo(
        path=p,
        dtype=dtype,
        calibrated=scale is not None,
        scale=scale,
        network_hash=model.weights.fingerprint(),
        nbytes=len(data),
    )


def onnx_session(path: str | os.PathLike[str], threads: int = 1) -> Any:
    """An ONNX Runtime CPU session for an exported file (``threads`` intra-op threads).

    Parameters
    ----------
    path : path-like
        The ONNX file.
    threads : int
        Intra-op threads of the session.
    """
    ort = _require("onnxruntime")
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = int(threads)
    opts.inter_op_num_threads = 1
    return ort.InferenceSession(str(path), sess_options=opts, providers=["CPUExecutionProvider"])


@dataclass(frozen=True, kw_only=True)
class OnnxCheck:
    """Largest relative differences of an ONNX export against the model, over a batch.

    ``vs_engine_*`` compare with the float64 engine (the sets of ``model.predict``);
    ``vs_torch_*`` with the float32 torch network (scaled by the calibration).
    Relative to the largest entry of the compared array.

    Attributes
    ----------
    samples : int
        Number of queries compared.
    vs_engine_center, vs_engine_shape : float
        Largest relative difference of the centres and of the shape matrices against the engine.
    vs_torch_center, vs_torch_shape : float
        The same against the torch network.
    """

    samples: int
    vs_engine_center: float
    vs_engine_shape: float
    vs_torch_center: float
    vs_torch_shape: float

    def passes(self, tolerance: float) -> bool:
        """All differences are at most ``tolerance``."""
        worst = max(self.vs_engine_center, self.vs_engine_shape, self.vs_torch_center, self.vs_torch_shape)
        return worst <= tolerance


def _rel(a: FloatArray, b: FloatArray) -> float:
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1e-300))


def check_onnx(model: IPCModel, path: str | os.PathLike[str], x: FloatArray, yhat: FloatArray) -> OnnxCheck:
    """Run the export in ONNX Runtime on ``(x, yhat)`` and compare with the torch network and the engine.

    Parameters
    ----------
    model : IPCModel
        The exported model.
    path : path-like
        The ONNX file.
    x : ndarray, shape (B, d)
        States to compare on.
    yhat : ndarray, shape (B, n)
        Estimates to compare on.

    Examples
    --------
    >>> # see tests/test_export.py for a full round trip
    """
    sess = onnx_session(path)
    dtype = np.float64 if sess.get_inputs()[0].type == "tensor(double)" else np.float32
    center, shape = sess.run(["center", "shape"], {"x": x.astype(dtype), "yhat": yhat.astype(dtype)})
    ref = model.predict_unguarded(x, yhat)
    scale = _scale(model) or 1.0
    with torch.inference_mode():
        tc, tC, _ = model.network(
            torch.tensor(np.asarray(x), dtype=torch.float32),
            torch.tensor(np.asarray(yhat), dtype=torch.float32),
        )
    tc64, tC64 = tc.double().numpy(), tC.double().numpy() / scale
    c64, C64 = np.asarray(center, dtype=np.float64), np.asarray(shape, dtype=np.float64)
    return OnnxCheck(
        samples=len(x),
        vs_engine_center=_rel(c64, ref.centers),
        vs_engine_shape=_rel(C64, ref.shapes),
        vs_torch_center=_rel(c64, tc64),
        vs_torch_shape=_rel(C64, tC64),
    )
