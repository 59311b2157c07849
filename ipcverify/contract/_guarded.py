"""The contract's sets with the domain verdict: what :meth:`IPCModel.predict` returns.

:func:`predict_sets` needs only the queries ``(x, yhat)`` -- a deployment log has no ground
truth. Every query gets its calibrated ellipsoid, its distance to the calibration inputs (on
demand) and an ``in_domain`` flag (:mod:`ipcverify.guard._domain`); a query whose set degenerates
(singular shape matrix, which happens far from the training data) is kept, marked
``in_domain = False`` and counted, instead of stopping the batch. :func:`mark_row_level` and
:func:`mark_runs` add to a domain report what the model file records about the calibration data's
runs. The module sees a model only through :class:`ContractParts`, so that
:class:`~ipcverify.contract._model.IPCModel` itself can offer the guarded predict.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ipcverify.calibration._group_counts import group_shares
from ipcverify.calibration._protocol import Calibration
from ipcverify.contract._runs import RUNS_KEY
from ipcverify.data._checks import group_like_counts
from ipcverify.data._dataset import PerceptionDataset, PerceptionInputs
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.guard._domain import DomainModel
from ipcverify.guard._domain_report import DomainReport
from ipcverify.guard._index import one_blas_thread
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._nonsingular import nonsingular
from ipcverify.sets._ellipsoid import Ellipsoid

FloatArray = NDArray[np.float64]

#: Model metadata of a row-level calibration whose data had columns naming runs or flights
#: (:func:`ipcverify.data._checks.group_like_counts`): ``{column: number of groups}``.
CALIBRATION_GROUPS_KEY = "calibration_group_like_columns"


class ContractParts(Protocol):
    """What the guarded predict reads of a model (:class:`~ipcverify.contract._model.IPCModel`)."""

    @property
    def config(self) -> ModelConfig: ...

    @property
    def calibration(self) -> Calibration | None: ...

    @property
    def domain(self) -> DomainModel | None: ...

    @property
    def metadata(self) -> Mapping[str, Any]: ...

    def raw_arrays(
        self, x: Any, yhat: Any, batch_size: int | None = None
    ) -> tuple[FloatArray, FloatArray]: ...


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
    singular : bool ndarray (B,)
        The set is degenerate (singular or non-finite shape matrix).
    calibrated : bool
        Whether the model's calibration was applied.
    domain : DomainReport or None
        How many queries the domain test flags (None without a domain model).
    distances : callable or None
        Computes the queries' distances to the calibration inputs on demand (:attr:`distance`;
        None without a domain model).
    """

    centers: FloatArray
    shapes: FloatArray
    in_domain: NDArray[np.bool_]
    singular: NDArray[np.bool_]
    calibrated: bool
    domain: DomainReport | None = None
    distances: Callable[[], FloatArray] | None = field(default=None, repr=False)

    @cached_property
    def distance(self) -> FloatArray:
        """Each query's distance to the calibration inputs (B,), computed on first access.

        :meth:`ipcverify.guard.DomainModel.distance` (the ``k``-th neighbour distance; at most the
        threshold exactly where the domain test says inside). ``in_domain`` does not need it:
        the distance costs a search over every reference per query (a float32 BLAS product),
        the domain test alone about one leaf of a k-d tree. NaN without a domain model.
        """
        if self.distances is None:
            return np.full(len(self.centers), np.nan)
        return self.distances()

    @property
    def sets(self) -> Ellipsoid:
        """The sets as one :class:`~ipcverify.Ellipsoid` batch (B queries), aligned with ``in_domain``.

        Raises
        ------
        SetError
            If a query's set is degenerate (``singular``): read ``centers`` and ``shapes``, and keep
            only the queries ``in_domain`` says are inside.
        """
        if self.singular.any():
            bad = np.flatnonzero(self.singular)
            raise SetError(
                f"{len(bad)} of {len(self.singular)} sets are degenerate (first at query {int(bad[0])}); "
                "they are marked outside the domain: read centers and shapes, or keep the queries in_domain"
            )
        return Ellipsoid(self.centers, self.shapes)

    @property
    def outside(self) -> int:
        """Queries outside the domain (or with a degenerate set)."""
        return int((~self.in_domain).sum())


def predict_sets(model: ContractParts, inputs: PerceptionInputs, chunk: int | None = None) -> Predictions:
    """The model's sets for every query, with the domain test applied.

    The sets come from :meth:`IPCModel.raw_arrays` (``chunk`` rows at a time; default: the engine's
    cache-sized chunk), scaled by the calibration in place; the singular test is
    :func:`ipcverify.network.nonsingular` (the SVD test, settled cheaply where it can be);
    ``in_domain`` comes from :meth:`DomainModel.contains <ipcverify.guard.DomainModel.contains>`
    (the exact test's answer, about one k-d tree leaf per in-distribution query). The distances
    themselves are computed only when ``Predictions.distance`` is read. NumPy's BLAS runs on one
    thread meanwhile (:func:`ipcverify.guard.one_blas_thread`): every product here is a
    block sized to the cache, which a second thread only slows down.

    Parameters
    ----------
    model : IPCModel
        The model.
    inputs : PerceptionInputs
        The queries.
    chunk : int, optional
        Rows per batch.

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
    with one_blas_thread():
        return _predict_sets(model, inputs, chunk)


def _predict_sets(model: ContractParts, inputs: PerceptionInputs, chunk: int | None) -> Predictions:
    centers, shapes = model.raw_arrays(inputs.x, inputs.yhat, batch_size=chunk)
    if model.calibration is not None:
        shapes /= model.calibration.scale_for(inputs.x, inputs.yhat)[:, None, None]
    finite = np.asarray(np.isfinite(shapes).all(axis=(1, 2)) & np.isfinite(centers).all(axis=1))
    singular = np.asarray(~finite, dtype=np.bool_)
    if finite.any():  # the SVD test of Ellipsoid, with an SVD only where a cheap bound does not settle it
        singular[np.flatnonzero(finite)] = ~nonsingular(shapes[finite])[0]
    report = None
    domain = model.domain
    if domain is None:
        in_domain = np.asarray(~singular, dtype=np.bool_)
    else:
        inside = domain.contains(inputs.x, inputs.yhat)
        in_domain = np.asarray(inside & ~singular, dtype=np.bool_)
        report = mark_runs(model, mark_row_level(model, domain.summarize_outside(~inside)), inputs, ~inside)
    return Predictions(
        centers=centers,
        shapes=shapes,
        in_domain=in_domain,
        singular=singular,
        calibrated=model.calibration is not None,
        domain=report,
        distances=None if domain is None else (lambda: _distances(domain, inputs)),
    )


def _distances(domain: DomainModel, inputs: PerceptionInputs) -> FloatArray:
    with one_blas_thread():
        return domain.distance(inputs.x, inputs.yhat)


def mark_row_level(model: ContractParts, report: DomainReport | None) -> DomainReport | None:
    """``report`` with the run-like column of a row-level domain test's calibration data, if recorded.

    A domain test fitted row by row on calibration data whose model file records a column naming
    runs (:data:`CALIBRATION_GROUPS_KEY`) flags the rows of a new run too often; the report then
    names that column and its groups, so that every statement of a shift (certify, evaluate,
    predict) also gives that explanation and the command that tells the two apart.

    Parameters
    ----------
    model : IPCModel
        The model whose domain test made ``report``.
    report : DomainReport or None
        What the test found on a batch (None: the model has no domain test).
    """
    if report is None or model.domain is None or model.domain.n_groups is not None:
        return report
    recorded = dict(model.metadata.get(CALIBRATION_GROUPS_KEY) or {})
    if not recorded:
        return report
    column = next(iter(recorded))
    return replace(report, row_level_column=column, row_level_groups=int(recorded[column]))


def mark_runs(
    model: ContractParts,
    report: DomainReport | None,
    data: PerceptionDataset | PerceptionInputs,
    outside: NDArray[np.bool_],
) -> DomainReport | None:
    """``report`` counted by the queries' runs, when they come in runs (see :class:`DomainReport`).

    The runs' column is the calibration's run column if the queries have it, else the queries' one
    column that names runs (:func:`~ipcverify.data._checks.group_like_counts`); None keeps the
    report as it is.

    Parameters
    ----------
    model : IPCModel
        The model whose domain test made ``report``.
    report : DomainReport or None
        What the test found on the queries.
    data : PerceptionDataset or PerceptionInputs
        The queries (their extra columns name the runs).
    outside : ndarray of bool, shape (N,)
        Whether each query lies outside the domain.
    """
    if report is None:
        return None
    record = model.metadata.get(RUNS_KEY) or {}
    claim = None if model.calibration is None else model.calibration.group_claim()
    known = [c for c in (None if claim is None else claim.column, record.get("column")) if c]
    column = next((c for c in known if c in data.extra), None)
    if column is None:
        runs = group_like_counts(data)  # type: ignore[arg-type]
        column = next(iter(runs)) if len(runs) == 1 else None
    if column is None:
        return report
    shares, _, _ = group_shares(outside, data.extra[column], f"{data.source}: run column {column!r}")
    return replace(report, run_column=column, run_shares=tuple(float(v) for v in shares))
