"""Deployment batches: a contract's sets for many queries, each marked in or out of its domain.

:func:`predict_sets` needs only the queries ``(x, yhat)`` -- a deployment log has no ground
truth. Every query gets its calibrated ellipsoid, its distance to the calibration inputs and
an ``in_domain`` flag (:mod:`ipcverify.domain`); a query whose set degenerates (singular shape
matrix, which happens far from the training data) is kept, marked ``in_domain = False`` and
counted, instead of stopping the batch. :func:`write_predictions` writes the arrays to NPZ.

Examples
--------
>>> import numpy as np
>>> from ipcverify.architecture import ModelConfig
>>> from ipcverify.data import PerceptionInputs
>>> from ipcverify.model import IPCModel, IPCNetwork
>>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(8,))))
>>> p = predict_sets(m, PerceptionInputs(np.zeros((4, 2)), np.zeros((4, 3))))
>>> p.centers.shape, p.in_domain.tolist()   # no domain model: every query counts as inside
((4, 3), [True, True, True, True])
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ipcverify.data import PerceptionInputs
from ipcverify.domain import DomainReport
from ipcverify.errors import InvalidInputError
from ipcverify.files import atomic_write
from ipcverify.model import IPCModel
from ipcverify.sets import SINGULAR_RCOND

__all__ = ["Predictions", "predict_sets", "write_predictions"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Predictions:
    """Sets for a batch of queries and what is known about their validity.

    Attributes
    ----------
    centers : ndarray (B, n)
    shapes : ndarray (B, n, n)
        ``E_i = {y : ||shapes_i (y - centers_i)|| <= 1}`` (calibrated if the model is).
    in_domain : bool ndarray (B,)
        The query is inside the domain of validity and its set is non-degenerate; the
        calibration certificate covers only these queries.
    distance : ndarray (B,)
        Distance to the calibration inputs (NaN without a domain model).
    singular : bool ndarray (B,)
        The set is degenerate (singular or non-finite shape matrix).
    calibrated : bool
        Whether the model's calibration was applied.
    domain : DomainReport or None
        How many queries the domain test flags (None without a domain model).
    """

    centers: FloatArray
    shapes: FloatArray
    in_domain: NDArray[np.bool_]
    distance: FloatArray
    singular: NDArray[np.bool_]
    calibrated: bool
    domain: DomainReport | None = None

    @property
    def outside(self) -> int:
        """Queries outside the domain (or with a degenerate set)."""
        return int((~self.in_domain).sum())


def predict_sets(model: IPCModel, inputs: PerceptionInputs, chunk: int = 65536) -> Predictions:
    """The model's sets for every query, with the domain test applied.

    Raises
    ------
    InvalidInputError
        If the inputs' dimensions are not the model's.
    """
    cfg = model.config
    if (inputs.x.shape[1], inputs.yhat.shape[1]) != (cfg.x_dim, cfg.y_dim):
        raise InvalidInputError(
            f"{inputs.source}: the queries have x_dim={inputs.x.shape[1]}, yhat_dim={inputs.yhat.shape[1]} "
            f"but the model expects x_dim={cfg.x_dim}, y_dim={cfg.y_dim}"
        )
    centers, shapes = model.raw_arrays(inputs.x, inputs.yhat, batch_size=chunk)
    if model.calibration is not None:
        shapes = shapes / model.calibration.scale_for(inputs.x, inputs.yhat)[:, None, None]
    finite = np.asarray(np.isfinite(shapes).all(axis=(1, 2)) & np.isfinite(centers).all(axis=1))
    singular = np.asarray(~finite, dtype=np.bool_)
    if finite.any():
        sv = np.linalg.svd(shapes[finite], compute_uv=False)
        rcond = sv[:, -1] / np.maximum(sv[:, 0], np.finfo(float).tiny)
        singular[np.flatnonzero(finite)] = ~(rcond >= SINGULAR_RCOND)
    report = None
    if model.domain is None:
        distance = np.full(len(centers), np.nan)
        in_domain = np.asarray(~singular, dtype=np.bool_)
    else:
        distance = model.domain.distance(inputs.x, inputs.yhat)
        in_domain = np.asarray((distance <= model.domain.threshold) & ~singular, dtype=np.bool_)
        report = model.domain.summarize(distance)
    return Predictions(
        centers=centers,
        shapes=shapes,
        in_domain=in_domain,
        distance=distance,
        singular=singular,
        calibrated=model.calibration is not None,
        domain=report,
    )


def write_predictions(predictions: Predictions, path: str | os.PathLike[str]) -> None:
    """Write ``center``, ``shape``, ``in_domain``, ``domain_distance`` and ``singular`` to an NPZ (atomic)."""
    p = predictions
    atomic_write(
        path,
        lambda f: np.savez(
            f,
            center=p.centers,
            shape=p.shapes,
            in_domain=p.in_domain,
            domain_distance=p.distance,
            singular=p.singular,
        ),
    )
