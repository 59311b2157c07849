"""A timed pose sequence, and its poses at chosen times (linear positions, slerp rotations).

:class:`Trajectory` holds stamps (seconds, strictly increasing), positions and unit
quaternions (``x, y, z, w``, the ROS and SciPy order). :meth:`Trajectory.at` interpolates it
at query times and says, for every query, whether the two stamps around it are close enough
to trust the interpolation.

The bracketing rule is half-open: a query time ``t`` is bracketed by the stamps
``t_i <= t < t_{i+1}``. A query before the first stamp, or at or after the last, has no
bracket and is refused; a query whose bracket is wider than ``max_gap`` is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation, Slerp

from ipcverify.errors import DataError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Poses of one body at increasing times.

    Parameters
    ----------
    t : array_like, shape (N,)
        Stamps in seconds, strictly increasing.
    p : array_like, shape (N, 3)
        Positions.
    q : array_like, shape (N, 4)
        Orientations as quaternions ``x, y, z, w`` (body to world); normalised here.
    source : str
        Where the poses came from (used in error messages).

    Raises
    ------
    DataError
        If the shapes disagree, a value is not finite, a quaternion has zero length, or
        the stamps do not increase (use :meth:`from_unsorted` for a log that needs sorting).

    Examples
    --------
    >>> tr = Trajectory([0.0, 1.0], [[0, 0, 0], [1, 0, 0]], [[0, 0, 0, 1], [0, 0, 0, 2]])
    >>> len(tr), tr.q[1].tolist(), tr.span
    (2, [0.0, 0.0, 0.0, 1.0], (0.0, 1.0))
    """

    t: FloatArray
    p: FloatArray
    q: FloatArray
    source: str = "<memory>"

    def __post_init__(self) -> None:
        t = np.array(self.t, dtype=np.float64).reshape(-1)
        p = np.array(self.p, dtype=np.float64)
        q = np.array(self.q, dtype=np.float64)
        n = t.shape[0]
        if p.shape != (n, 3) or q.shape != (n, 4):
            raise DataError(
                f"{self.source}: need stamps (N,), positions (N, 3) and quaternions (N, 4); "
                f"got {t.shape}, {p.shape}, {q.shape}"
            )
        if n < 2:
            raise DataError(f"{self.source}: {n} pose(s); a trajectory needs at least 2 to interpolate")
        for name, a in (("stamp", t), ("position", p), ("quaternion", q)):
            bad = ~np.isfinite(a)
            if bad.any():
                row = int(np.argwhere(bad)[0][0])
                raise DataError(
                    f"{self.source}: pose {row} (0-based): non-finite {name}; drop or repair that pose"
                )
        norm = np.linalg.norm(q, axis=1)
        if (norm == 0).any():
            row = int(np.flatnonzero(norm == 0)[0])
            raise DataError(
                f"{self.source}: pose {row} (0-based): quaternion of length 0; drop or repair that pose"
            )
        back = np.flatnonzero(np.diff(t) <= 0)
        if back.size:
            i = int(back[0]) + 1
            raise DataError(
                f"{self.source}: pose {i} (0-based): stamp {float(t[i])!r} does not follow "
                f"{float(t[i - 1])!r}; stamps must increase (Trajectory.from_unsorted sorts and drops "
                "repeated stamps)"
            )
        q = q / norm[:, None]
        for a in (t, p, q):
            a.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "p", p)
        object.__setattr__(self, "q", q)

    @classmethod
    def from_unsorted(
        cls, t: ArrayLike, p: ArrayLike, q: ArrayLike, source: str = "<memory>"
    ) -> tuple[Trajectory, int]:
        """The poses sorted by stamp, the first of each repeated stamp kept; and how many were dropped.

        Examples
        --------
        >>> tr, dropped = Trajectory.from_unsorted([1.0, 0.0, 1.0], [[1, 0, 0], [0, 0, 0], [2, 0, 0]],
        ...                                        [[0, 0, 0, 1]] * 3)
        >>> tr.t.tolist(), tr.p[:, 0].tolist(), dropped
        ([0.0, 1.0], [0.0, 1.0], 1)
        """
        ta = np.asarray(t, dtype=np.float64).reshape(-1)
        order = np.argsort(ta, kind="stable")
        ts = ta[order]
        keep = np.ones(ts.shape[0], dtype=bool)
        keep[1:] = ts[1:] != ts[:-1]
        idx = order[keep]
        pa = np.asarray(p, dtype=np.float64).reshape(-1, 3)
        qa = np.asarray(q, dtype=np.float64).reshape(-1, 4)
        return cls(ta[idx], pa[idx], qa[idx], source), int(ts.shape[0] - idx.shape[0])

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def span(self) -> tuple[float, float]:
        """First and last stamp."""
        return float(self.t[0]), float(self.t[-1])

    @property
    def largest_gap(self) -> float:
        """The longest time between two consecutive stamps."""
        return float(np.diff(self.t).max())

    def shifted(self, offset: float) -> Trajectory:
        """The same poses with ``offset`` seconds added to every stamp."""
        return Trajectory(self.t + offset, self.p, self.q, self.source)

    def at(self, times: ArrayLike, max_gap: float) -> PosesAt:
        """Poses at ``times``: positions linearly, rotations by slerp, between the bracketing stamps.

        Parameters
        ----------
        times : array_like, shape (M,)
            Query times (seconds, on this trajectory's clock).
        max_gap : float
            The widest bracket (seconds between the two stamps around a query) that is trusted.

        Returns
        -------
        PosesAt
            Poses at every query (the nearest valid bracket's where a query is refused), and
            for each query whether it is ``inside`` the stamps and its ``bracket`` width.

        Examples
        --------
        >>> tr = Trajectory([0.0, 1.0, 5.0], [[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 0, 0, 1]] * 3)
        >>> at = tr.at([0.5, 3.0, 5.0], max_gap=2.0)
        >>> at.p[:, 0].tolist(), at.ok.tolist(), at.inside.tolist(), at.bracket.tolist()
        ([0.5, 1.5, 2.0], [True, False, False], [True, True, False], [1.0, 4.0, inf])
        """
        tq = np.asarray(times, dtype=np.float64).reshape(-1)
        t = self.t
        i = np.searchsorted(t, tq, side="right")  # t[i - 1] <= tq < t[i]
        inside = (i >= 1) & (i < t.shape[0])
        lo = np.clip(i - 1, 0, t.shape[0] - 2)
        width = t[lo + 1] - t[lo]
        bracket = np.where(inside, width, np.inf)
        w = np.clip((tq - t[lo]) / width, 0.0, 1.0)
        p = self.p[lo] + (self.p[lo + 1] - self.p[lo]) * w[:, None]
        rot = Slerp(t, Rotation.from_quat(self.q))(t[lo] + w * width)
        return PosesAt(p=p, rotation=rot, inside=inside, bracket=bracket, ok=inside & (bracket <= max_gap))


@dataclass(frozen=True, eq=False)
class PosesAt:
    """Interpolated poses at query times (see :meth:`Trajectory.at`).

    Attributes
    ----------
    p : ndarray, shape (M, 3)
        Positions.
    rotation : scipy.spatial.transform.Rotation
        M body-to-world rotations.
    inside : ndarray of bool, shape (M,)
        The query lies in ``[first stamp, last stamp)``.
    bracket : ndarray, shape (M,)
        Seconds between the stamps around the query (``inf`` outside).
    ok : ndarray of bool, shape (M,)
        Inside, and the bracket is at most ``max_gap``.
    """

    p: FloatArray
    rotation: Rotation
    inside: NDArray[np.bool_]
    bracket: FloatArray
    ok: NDArray[np.bool_]
