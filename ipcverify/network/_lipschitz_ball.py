"""What both sound Lipschitz bounds share: the box of ``X``, the parameter ball, an MLP's norm bounds in it.

The sound bounds on ``L_g`` (:mod:`ipcverify.network._lipschitz_mlp` for the paper's heads,
:mod:`ipcverify.network._lipschitz_lowrank` for the default ensemble) hold for every parameter vector
``theta`` in the Euclidean ball ``B(theta_hat, r)`` and every ``X = (x, y, yhat)`` in a
:class:`DataBox`. Both propagate the same layer-by-layer bounds through an MLP
(``proofs/lipschitz.md``, steps 2 and 4): :func:`hidden_norm_bounds` bounds the norm of
every layer's input, :func:`jacobian_bound` the operator norm of the MLP's output Jacobian
with respect to its own weights and biases. Every float64 step is rounded up by
:data:`ROUND_UP` (and spectral norms by a further ``1 + 1e-9``), so the computed numbers
bound the exact real-arithmetic ones.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ipcverify.errors import InvalidInputError

if TYPE_CHECKING:  # for annotations only: the CLI reads DEFAULT_RADIUS without loading pandas
    from ipcverify.data._dataset import PerceptionDataset

FloatArray = NDArray[np.float64]

#: Radius of the parameter ball of the sound bound. Fixed here, never tuned on data.
DEFAULT_RADIUS = 0.1
#: Relative safety margin on the sound bound (float64 rounding in norms and SVDs).
FLOAT_MARGIN = 1e-6
#: Factor applied after every monotone float64 step of the bounds (covers its rounding).
ROUND_UP = 1.0 + 1e-12
#: Relative margin on a spectral or Euclidean norm computed by LAPACK / NumPy.
SVD_MARGIN = 1e-9


@dataclass(frozen=True)
class DataBox:
    """An axis-aligned box for ``X = (x, y, yhat)``: per-coordinate lower and upper bounds.

    Attributes
    ----------
    x_lo, x_hi : ndarray, shape (d,)
        Bounds of the state ``x`` (finite, ``x_lo <= x_hi``; stored flattened and read-only).
    y_lo, y_hi : ndarray, shape (n,)
        Bounds of the truth ``y``.
    yhat_lo, yhat_hi : ndarray, shape (n,)
        Bounds of the estimate ``yhat`` (the same dimension as ``y``). A bound that is not
        finite, a lower bound above its upper bound or mismatched shapes raise
        :class:`InvalidInputError`.

    Examples
    --------
    >>> from ipcverify import example
    >>> box = DataBox.from_dataset(example(50, seed=0).data)
    >>> box.x_lo.shape, box.y_hi.shape
    ((6,), (3,))
    """

    x_lo: FloatArray
    x_hi: FloatArray
    y_lo: FloatArray
    y_hi: FloatArray
    yhat_lo: FloatArray
    yhat_hi: FloatArray

    def __post_init__(self) -> None:
        for name in ("x", "y", "yhat"):
            lo = np.array(getattr(self, f"{name}_lo"), dtype=np.float64).ravel()
            hi = np.array(getattr(self, f"{name}_hi"), dtype=np.float64).ravel()
            if lo.shape != hi.shape or not (np.isfinite(lo).all() and np.isfinite(hi).all()):
                raise InvalidInputError(f"box bounds of {name} must be finite arrays of equal shape")
            if (lo > hi).any():
                raise InvalidInputError(f"box of {name}: a lower bound exceeds its upper bound")
            lo.setflags(write=False)
            hi.setflags(write=False)
            object.__setattr__(self, f"{name}_lo", lo)
            object.__setattr__(self, f"{name}_hi", hi)
        if self.y_lo.shape != self.yhat_lo.shape:
            raise InvalidInputError("y and yhat boxes must have the same dimension")

    @classmethod
    def from_dataset(cls, data: PerceptionDataset) -> DataBox:
        """The bounding box of a dataset's ``x``, ``y`` and ``yhat``."""
        return cls(
            data.x.min(0), data.x.max(0), data.y.min(0), data.y.max(0), data.yhat.min(0), data.yhat.max(0)
        )

    def check_dims(self, x_dim: int, y_dim: int) -> None:
        """Refuse a box whose dimensions are not the model's.

        Examples
        --------
        >>> box = DataBox(np.zeros(2), np.ones(2), np.zeros(1), np.ones(1), np.zeros(1), np.ones(1))
        >>> box.check_dims(2, 3)
        Traceback (most recent call last):
        ...
        ipcverify.errors.InvalidInputError: box has x_dim=2, y_dim=1; the model expects x_dim=2, y_dim=3
        """
        if self.x_lo.shape != (x_dim,) or self.y_lo.shape != (y_dim,):
            raise InvalidInputError(
                f"box has x_dim={self.x_lo.size}, y_dim={self.y_lo.size}; the model expects "
                f"x_dim={x_dim}, y_dim={y_dim}"
            )

    def to_dict(self) -> dict[str, list[float]]:
        """Plain-data form."""
        return {k: getattr(self, k).tolist() for k in ("x_lo", "x_hi", "y_lo", "y_hi", "yhat_lo", "yhat_hi")}


@dataclass(frozen=True)
class LipschitzBound:
    """An **upper bound** on ``L_g`` over ``B(theta_hat, radius)`` and a box of ``X``.

    Attributes
    ----------
    value : float
        The bound (already multiplied by ``1 + FLOAT_MARGIN``).
    radius : float
        Radius of the parameter ball.
    jacobian_bound : float
        Bound on the operator norm of ``d(network output) / d theta`` (for an ensemble: of
        one member's outputs with respect to its own parameters, the largest over members).
    output_gradient_bound : float
        Bound on the norm of the gradient of ``g`` with respect to the network outputs (for
        an ensemble: all members' outputs).
    hidden_norm_bounds : tuple of float
        Bounds on the Euclidean norm of each layer's input (normalised input first; for an
        ensemble the largest over members).
    box : DataBox
        The box of ``X`` over which the bound holds.
    kind : str
        What the value is (a sound upper bound, unless a caller says otherwise).
    """

    value: float
    radius: float
    jacobian_bound: float
    output_gradient_bound: float
    hidden_norm_bounds: tuple[float, ...]
    box: DataBox = field(repr=False)
    kind: str = "sound (upper bound over the parameter ball and the data box)"

    @classmethod
    def chain(
        cls, jacobian: float, output_gradient: float, radius: float, hidden: Iterable[float], box: DataBox
    ) -> LipschitzBound:
        """The bound the chain rule gives: ``output_gradient * jacobian``, times ``1 + FLOAT_MARGIN``.

        Both sound bounds end here (``proofs/lipschitz.md``, "Result").

        Parameters
        ----------
        jacobian : float
            Bound on the operator norm of ``d(network output) / d theta`` (see :attr:`jacobian_bound`).
        output_gradient : float
            Bound on the norm of the gradient of ``g`` with respect to the network outputs.
        radius : float
            Radius of the parameter ball the two bounds hold over.
        hidden : iterable of float
            Bounds on the norm of each layer's input, normalised input first.
        box : DataBox
            The box of ``X`` the two bounds hold over.

        Returns
        -------
        LipschitzBound
            The bound; a product that overflows raises :class:`InvalidInputError`.

        Examples
        --------
        >>> box = DataBox(*(np.zeros(1) for _ in range(6)))
        >>> round(LipschitzBound.chain(2.0, 3.0, 0.1, [1.0], box).value, 9)
        6.000006
        """
        value = output_gradient * jacobian * (1.0 + FLOAT_MARGIN)
        if not math.isfinite(value):
            raise InvalidInputError(
                "the sound Lipschitz bound overflowed; the box or the weights are too large"
            )
        return cls(
            value=value,
            radius=radius,
            jacobian_bound=jacobian,
            output_gradient_bound=output_gradient,
            hidden_norm_bounds=tuple(float(v) for v in hidden),
            box=box,
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {
            "value": self.value,
            "radius": self.radius,
            "jacobian_bound": self.jacobian_bound,
            "output_gradient_bound": self.output_gradient_bound,
            "hidden_norm_bounds": list(self.hidden_norm_bounds),
            "kind": self.kind,
        }


def require_kind(network: object, kind: type) -> None:
    """Refuse a network of another kind than the bound's (each kind's engine calls its own).

    Examples
    --------
    >>> require_kind(object(), int)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: this is for a int network; got a object (ask the network's own ...
    """
    if not isinstance(network, kind):
        raise InvalidInputError(
            f"this is for a {kind.__name__} network; got a {type(network).__name__} (ask the network's own "
            "engine: ipcverify.network.engine_for(network))"
        )


def check_radius(radius: float) -> float:
    """``radius`` as a float, or an error unless it is finite and ``>= 0``.

    Parameters
    ----------
    radius : float
        Radius of the parameter ball (0 bounds the trained parameters alone); NaN, infinite or
        negative raises :class:`InvalidInputError`.

    Examples
    --------
    >>> check_radius(0.1)
    0.1
    """
    if not (math.isfinite(radius) and radius >= 0):
        raise InvalidInputError(f"radius must be finite and >= 0; got {radius!r}")
    return float(radius)


def operator_norm(w: FloatArray) -> float:
    """An upper bound on the spectral norm of ``w`` (LAPACK's value times ``1 + SVD_MARGIN``).

    Parameters
    ----------
    w : ndarray, shape (p, q)
        A weight matrix; an empty one has norm 0. The tiny ``1e-300`` added keeps the bound
        positive.

    Examples
    --------
    >>> operator_norm(np.diag([3.0, -4.0])) >= 4.0
    True
    """
    if w.size == 0:
        return 0.0
    return float(np.linalg.norm(w, 2)) * (1.0 + SVD_MARGIN) + 1e-300


def hidden_norm_bounds(
    layers: list[tuple[FloatArray, FloatArray]], input_bound: float, radius: float
) -> list[float]:
    """Bounds ``H_0, ..., H_{L-1}`` on the norms of the inputs of the ``L`` layers of an MLP.

    ``layers`` holds ``(W_l, b_l)`` in the orientation ``out = W_l h + b_l`` (any
    orientation gives the same spectral norms); ``H_0 = input_bound``; the activation
    satisfies ``|phi(t)| <= |t|``. Every layer's weights and bias may move by a Frobenius
    norm of at most ``radius`` (``proofs/lipschitz.md``, step 2)::

        H_l = ||W_l|| H_{l-1} + ||b_l|| + r sqrt(H_{l-1}^2 + 1).

    Parameters
    ----------
    layers : list of (ndarray, ndarray)
        The MLP's ``(W_l, b_l)``, first layer first (the last layer's own bound is not needed).
    input_bound : float
        ``H_0``: a bound on the norm of the (normalised) input.
    radius : float
        ``r``, the parameter ball's radius (0: the trained weights alone).

    Examples
    --------
    >>> hidden_norm_bounds([(np.eye(2), np.zeros(2)), (np.eye(2), np.zeros(2))], 1.0, 0.0)[1] >= 1.0
    True
    """
    bounds = [input_bound]
    for w, b in layers[:-1]:
        h = bounds[-1]
        bounds.append(
            (operator_norm(w) * h + float(np.linalg.norm(b)) + radius * math.sqrt(h * h + 1.0)) * ROUND_UP
        )
    return bounds


def jacobian_bound(layers: list[tuple[FloatArray, FloatArray]], hidden: list[float], radius: float) -> float:
    """Bound ``J`` on the operator norm of ``d(MLP output) / d(its weights and biases)`` in the ball.

    With ``P_L = 1``, ``P_l = P_{l+1} (||W_{l+1}|| + r)``:
    ``J^2 = sum_l P_l^2 (H_{l-1}^2 + 1)`` (``proofs/lipschitz.md``, step 4; ``hidden`` from
    :func:`hidden_norm_bounds`).

    Parameters
    ----------
    layers : list of (ndarray, ndarray)
        The MLP's ``(W_l, b_l)``, as for :func:`hidden_norm_bounds`.
    hidden : list of float
        ``H_0, ..., H_{L-1}`` from :func:`hidden_norm_bounds` (same ``layers`` and ``radius``).
    radius : float
        ``r``, the parameter ball's radius.

    Examples
    --------
    >>> layers = [(np.eye(2), np.zeros(2))]
    >>> jacobian_bound(layers, hidden_norm_bounds(layers, 3.0, 0.0), 0.0) >= 10.0 ** 0.5
    True
    """
    ops = [operator_norm(w) for w, _ in layers]
    n_layers = len(layers)
    P = [1.0] * n_layers
    for i in range(n_layers - 2, -1, -1):
        P[i] = P[i + 1] * (ops[i + 1] + radius) * ROUND_UP
    return math.sqrt(sum(P[i] ** 2 * (hidden[i] ** 2 + 1.0) for i in range(n_layers))) * ROUND_UP
