"""Conformal risk control over groups: the threshold behind grouped marginal calibration and the domain test.

Groups of correlated samples (flights, runs) are the exchangeable units; the loss of a group
at threshold ``t`` is the share of its samples with a score above ``t``. Used by
:class:`~ipcverify.calibration.GroupedCalibration` (``guarantee="sample"``, marginal) and by the
group-aware domain test (:class:`~ipcverify.guard.DomainModel`). Proofs:
``proofs/group_calibration.md``.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from numpy.typing import ArrayLike

from ipcverify.calibration._bounds import count_text, min_calibration_size
from ipcverify.data._split import group_codes
from ipcverify.errors import InvalidInputError, SampleSizeError


def risk_control_threshold(scores: ArrayLike, groups: ArrayLike, epsilon: float) -> tuple[float, float]:
    """Conformal risk control over groups: the smallest ``t`` with ``(sum_g V_g(t) + 1) / (G + 1) <= eps``.

    ``V_g(t)`` is the fraction of group ``g``'s samples with score ``> t`` (a loss in
    ``[0, 1]``, non-increasing and right-continuous in ``t``). If the ``G`` calibration groups
    and a new group are exchangeable, ``E[V_new(t)] <= epsilon`` (proofs/group_calibration.md).
    The candidate is found in floating point and then settled in exact rational arithmetic,
    so the result is the exact infimum (always one of the scores).

    Parameters
    ----------
    scores : array_like of float, shape (N,)
        Nonconformity score of every calibration sample.
    groups : array_like, shape (N,)
        Each sample's group label (flight, run; numbers or strings, none missing).
    epsilon : float
        Allowed expected violation fraction of a new group, ``0 < epsilon < 1``.

    Returns
    -------
    t : float
        The threshold (one of the scores).
    risk : float
        ``mean_g V_g(t)`` over the ``G`` calibration groups, in ``[0, 1]``.

    Raises
    ------
    SampleSizeError
        If ``G < 1 / epsilon - 1`` (no ``t`` satisfies the condition).
    InvalidInputError
        If ``scores`` and ``groups`` differ in length or a label is missing.

    Examples
    --------
    >>> s = np.array([0.1, 0.2, 0.3, 0.4, 1.0, 2.0, 3.0, 4.0])
    >>> risk_control_threshold(s, [0, 0, 1, 1, 2, 2, 3, 3], 0.5)
    (1.0, 0.375)
    """
    s = np.asarray(scores, dtype=np.float64).ravel()
    codes, labels = group_codes(groups, "risk control groups")
    G = len(labels)
    if len(codes) != len(s):
        raise InvalidInputError(f"{len(s)} scores but {len(codes)} group labels; give one label per score")
    eps = Fraction(epsilon)
    if eps * (G + 1) < 1:
        need = min_calibration_size(epsilon, 0.5, "marginal")
        raise SampleSizeError(
            f"{G} groups are too few for conformal risk control at epsilon={epsilon:g}: at least "
            f"{count_text(need)} groups are needed (G >= 1/epsilon - 1)"
        )
    sizes = np.bincount(codes, minlength=G)
    order = np.argsort(s, kind="stable")
    sorted_s = s[order]
    last = np.flatnonzero(np.concatenate([sorted_s[1:] != sorted_s[:-1], [True]]))
    risk_sum = G - np.cumsum(1.0 / sizes[codes[order]])[last]  # sum_g V_g at each distinct score
    budget = eps * (G + 1) - 1
    distinct_sizes = np.unique(sizes)

    def exact_risk_sum(j: int) -> Fraction:
        over = np.bincount(codes[s > sorted_s[last[j]]], minlength=G)
        return sum((Fraction(int(over[sizes == m].sum()), int(m)) for m in distinct_sizes), Fraction(0))

    # float candidate, then the exact infimum: the exact sum is decreasing in j, so step forward
    # while it fails and back while the previous one passes (a few steps at most)
    ok = np.flatnonzero(risk_sum <= float(budget))
    j = int(ok[0]) if ok.size else len(last) - 1
    while exact_risk_sum(j) > budget:  # at the largest score the sum is 0 <= budget
        j += 1
    while j > 0 and exact_risk_sum(j - 1) <= budget:
        j -= 1
    return float(sorted_s[last[j]]), float(exact_risk_sum(j) / G)
