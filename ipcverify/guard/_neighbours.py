"""Leave-one-group-out neighbour distances: the scores of the domain test fitted on groups (flights, runs).

A calibration input's score is its distance to the ``k``-th nearest calibration input of
*another* group (``proofs/domain.md``, section on groups), so that a flight's own samples,
correlated with it, do not make its score small.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

FloatArray = NDArray[np.float64]


def other_group_distances(tree: cKDTree, points: FloatArray, codes: NDArray[np.intp], k: int) -> FloatArray:
    """Distance from each of the tree's points to its ``k``-th nearest point of another group.

    ``points`` are the tree's data and ``codes`` their groups. Neighbours are fetched in
    growing batches until ``k`` of another group are among them, so small groups cost one
    query and a point deep inside a large group a few more.

    Parameters
    ----------
    tree : scipy.spatial.cKDTree
        A tree over ``points``.
    points : ndarray, shape (N, D)
        The tree's data.
    codes : ndarray of int, shape (N,)
        The group of each point.
    k : int
        The neighbour rank.

    Examples
    --------
    >>> pts = np.array([[0.0], [0.1], [1.0], [3.0]])
    >>> other_group_distances(cKDTree(pts), pts, np.array([0, 0, 1, 1]), 1).tolist()
    [1.0, 0.9, 0.9, 2.9]
    """
    n = len(points)
    out = np.full(n, np.inf)
    todo = np.arange(n)
    m = min(n, k + 1 + int(np.bincount(codes).min()))
    while todo.size:
        dist, idx = tree.query(points[todo], k=m)
        dist, idx = dist.reshape(len(todo), m), idx.reshape(len(todo), m)
        other = codes[idx] != codes[todo][:, None]
        found = np.cumsum(other, axis=1) >= k
        done = found.any(axis=1)
        first = np.argmax(found, axis=1)
        out[todo[done]] = dist[done, first[done]]
        if m == n:  # fewer than k points of other groups: no finite distance
            break
        todo, m = todo[~done], min(n, 2 * m)
    return out
