"""Least-squares alignment of estimated positions to true ones (rigid, or rigid with scale).

The fit is the closed-form solution of Umeyama (1991), "Least-squares estimation of
transformation parameters between two point patterns": it minimises
``sum_i || p_true_i - (s R p_est_i + t) ||^2`` over rotations ``R``, translations ``t``
and, for ``sim3``, a scale ``s > 0``.

An alignment fitted on rows that later calibrate or test a contract makes those rows depend
on each other (each aligned estimate depends on every other row's truth): fit it on runs
kept for training only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from ipcverify.errors import DataError

AlignKind = Literal["se3", "sim3"]


@dataclass(frozen=True, eq=False)
class Alignment:
    """``p -> scale * R p + t`` mapping the estimate's world frame onto the truth's.

    Attributes
    ----------
    kind : {"se3", "sim3"}
    rotation : ndarray, shape (3, 3)
    translation : ndarray, shape (3,)
    scale : float
    runs : tuple of str
        The runs the alignment was fitted on.
    pairs : int
        How many position pairs it was fitted on.
    rmse : float
        Root-mean-square residual of the fit (metres).
    """

    kind: AlignKind
    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]
    scale: float
    runs: tuple[str, ...]
    pairs: int
    rmse: float

    @property
    def as_rotation(self) -> Rotation:
        """The rotation as a SciPy Rotation."""
        return Rotation.from_matrix(self.rotation)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the manifest."""
        return {
            "kind": self.kind,
            "rotation": self.rotation.tolist(),
            "translation": self.translation.tolist(),
            "scale": self.scale,
            "fitted_on_runs": list(self.runs),
            "pairs": self.pairs,
            "rmse": self.rmse,
        }


def fit_alignment(
    estimate: ArrayLike, truth: ArrayLike, kind: AlignKind, runs: tuple[str, ...] = ()
) -> Alignment:
    """The alignment of ``estimate`` positions (N, 3) onto ``truth`` positions (N, 3).

    Parameters
    ----------
    estimate, truth : array_like, shape (N, 3)
        Positions at the same times.
    kind : {"se3", "sim3"}
        A rigid motion, or a rigid motion and a scale.
    runs : tuple of str
        The runs the positions come from (recorded in the alignment).

    Raises
    ------
    DataError
        If fewer than 3 pairs are given, or the points are degenerate (all on one line).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> p = rng.standard_normal((20, 3))
    >>> R = Rotation.from_euler("z", 30, degrees=True)
    >>> a = fit_alignment(p, 2.0 * R.apply(p) + [1, 2, 3], "sim3")
    >>> round(a.scale, 9), np.round(a.translation, 9).tolist(), a.rmse < 1e-9
    (2.0, [1.0, 2.0, 3.0], True)
    """
    x = np.asarray(estimate, dtype=np.float64).reshape(-1, 3)
    y = np.asarray(truth, dtype=np.float64).reshape(-1, 3)
    if x.shape != y.shape or x.shape[0] < 3:
        raise DataError(
            f"an alignment needs at least 3 position pairs in the runs named to fit it on; got {x.shape[0]}"
        )
    mx, my = x.mean(axis=0), y.mean(axis=0)
    xc, yc = x - mx, y - my
    cov = yc.T @ xc / x.shape[0]
    U, d, Vt = np.linalg.svd(cov)
    if d[1] <= 1e-12 * max(d[0], 1e-300):
        raise DataError(
            "the positions to align lie on a line (or a point); an alignment is not determined -- fit it on "
            "runs that move in more than one direction"
        )
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1.0
    R = U @ S @ Vt
    var_x = float((xc**2).sum() / x.shape[0])
    scale = float(np.trace(np.diag(d) @ S) / var_x) if kind == "sim3" else 1.0
    t = my - scale * R @ mx
    resid = y - (scale * x @ R.T + t)
    rmse = float(np.sqrt((resid**2).sum(axis=1).mean()))
    return Alignment(kind, R, t, scale, tuple(runs), int(x.shape[0]), rmse)
