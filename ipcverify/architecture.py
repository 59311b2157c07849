"""The architecture of an IPC network: :class:`ModelConfig` (plain data, no torch).

Shared by the torch network (:mod:`ipcverify.model`), its float64 evaluation
(:mod:`ipcverify.inference`) and the ONNX export, so that none of them imports another
for its description.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Literal

from ipcverify.errors import InvalidInputError

__all__ = ["ACTIVATIONS", "LOGDIAG_CLAMP", "ModelConfig"]

#: Bound on the log of the Cholesky diagonal (keeps exp finite in float32).
LOGDIAG_CLAMP = 12.0
#: Hidden-layer non-linearities.
ACTIVATIONS = ("relu", "tanh", "elu")
Param = Literal["cholesky", "full"]
Center = Literal["offset", "raw"]


@dataclass(frozen=True, kw_only=True)
class ModelConfig:
    """Architecture of an IPC network.

    Parameters
    ----------
    x_dim, y_dim : int
        State dimension ``d`` and dimension ``n`` of the perceived quantity.
    hidden : tuple of int
        Hidden layer widths (paper: (64, 128)).
    param : {"cholesky", "full"}
        Parameterisation of the shape matrix.
    center : {"offset", "raw"}
        Centre as ``yhat`` plus a learned offset, or predicted directly.
    activation : {"relu", "tanh", "elu"}
        Hidden-layer non-linearity.

    Examples
    --------
    >>> ModelConfig(x_dim=6, y_dim=3).n_outputs
    9
    >>> ModelConfig(x_dim=6, y_dim=3, param="full").n_outputs
    12
    """

    x_dim: int
    y_dim: int
    hidden: tuple[int, ...] = (64, 128)
    param: Param = "cholesky"
    center: Center = "offset"
    activation: str = "relu"

    def __post_init__(self) -> None:
        object.__setattr__(self, "hidden", tuple(int(h) for h in self.hidden))
        if self.x_dim < 0 or self.y_dim < 1:
            raise InvalidInputError(
                f"need x_dim >= 0 and y_dim >= 1; got x_dim={self.x_dim}, y_dim={self.y_dim}"
            )
        if not self.hidden or any(h < 1 for h in self.hidden):
            raise InvalidInputError(f"hidden sizes must be positive integers, e.g. 64,128; got {self.hidden}")
        if self.param not in ("cholesky", "full"):
            raise InvalidInputError(f"param must be 'cholesky' or 'full'; got {self.param!r}")
        if self.center not in ("offset", "raw"):
            raise InvalidInputError(f"center must be 'offset' or 'raw'; got {self.center!r}")
        if self.activation not in ACTIVATIONS:
            raise InvalidInputError(
                f"activation must be one of {', '.join(ACTIVATIONS)}; got {self.activation!r}"
            )

    @property
    def n_shape_outputs(self) -> int:
        """Number of network outputs used for the shape matrix."""
        n = self.y_dim
        return n * n if self.param == "full" else n * (n + 1) // 2

    @property
    def n_outputs(self) -> int:
        """Total network output size (centre + shape)."""
        return self.y_dim + self.n_shape_outputs

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (for model files)."""
        d = asdict(self)
        d["hidden"] = list(self.hidden)
        return d

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ModelConfig:
        """Inverse of :meth:`to_dict`; unknown keys are refused."""
        known = {"x_dim", "y_dim", "hidden", "param", "center", "activation"}
        unknown = set(data) - known
        if unknown:
            raise InvalidInputError(f"unknown model config key(s): {', '.join(sorted(unknown))}")
        # values are validated by __post_init__; a missing x_dim / y_dim raises TypeError as before
        kwargs: dict[str, Any] = {k: (tuple(v) if k == "hidden" else v) for k, v in data.items()}
        return cls(**kwargs)
