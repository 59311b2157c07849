"""Choosing what the paper leaves unstated: the hinge margin, the volume weight, the batch size.

The paper trains its IPC with the hinge ``max(0, t / alpha + 1)`` plus ``lambda`` times the
volume proxy, with Adam at 1e-3 for 20 epochs on 5,000 samples, but states neither
``alpha``, ``lambda`` nor the batch size. ipcverify's recipe ``"paper"`` chooses them by a rule
fixed in advance that sees **training data only** (never calibration, test or deployment
data, never the case study's Table I or landings):

1. hold out ``val_fraction`` of the training rows (seeded), or of its groups -- whole flights or
   runs -- when ``group_column`` names them: rows of one flight are correlated, and held-out rows
   of a flight the candidates were fitted on would make every miss rate look better than it is;
2. train the paper's network on the rest once per candidate of the grid
   ``alphas x lams x batch_sizes``;
3. on the held-out rows, measure each candidate's raw miss rate (share of truths outside the
   network's own, uncalibrated ellipsoid) and mean log-volume;
4. choose the smallest mean log-volume among the candidates whose raw miss rate is at most
   ``target_miss`` (default 0.2 %, the paper's reported test error); if none is, the smallest
   miss rate (then the smallest log-volume) -- and say so (:attr:`SelectionRecord.target_met`);
5. train the paper's network with the chosen values on **all** the training rows (the
   paper's ``N``): that is the model returned.

:class:`HingeSelection` is the rule, :class:`SelectionRecord` what it found (stored in the
model file's metadata and shown by ``ipcverify certify``). The loop itself is in
:func:`ipcverify.training.train` (``select=``).

Examples
--------
>>> rule = HingeSelection(alphas=(0.1, 1.0), lams=(0.01,))
>>> len(rule.grid()), rule.grid()[0]
(2, (0.1, 0.01, 64))
>>> cands = [Candidate(alpha=0.1, lam=0.01, batch_size=64, val_n=1000, val_misses=1, val_log_volume=-9.0),
...          Candidate(alpha=1.0, lam=0.01, batch_size=64, val_n=1000, val_misses=9, val_log_volume=-11.0)]
>>> rule.choose(cands).chosen.alpha    # the tighter one misses 0.9 % > 0.2 %
0.1
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from ipcverify.errors import InvalidInputError


@dataclass(frozen=True, kw_only=True)
class HingeSelection:
    """The rule that chooses the hinge margin, the volume weight and the batch size (see the module).

    Parameters
    ----------
    alphas, lams : tuple of float
        Candidate hinge margins ``alpha > 0`` and volume weights ``lambda >= 0``.
    batch_sizes : tuple of int
        Candidate mini-batch sizes.
    target_miss : float
        Largest acceptable raw miss rate on the held-out training rows (default 0.002).
    val_fraction : float
        Share of the training rows held out to compare the candidates (default 0.2); of the
        groups, with ``group_column``.
    group_column : str, optional
        A column of the training data naming its exchangeable units (flights, runs): whole
        groups are held out (:meth:`ipcverify.data.PerceptionDataset.split`).

    Examples
    --------
    >>> HingeSelection().describe()[:44]
    'smallest held-out mean log-volume among the '
    """

    alphas: tuple[float, ...] = (0.1, 0.3, 1.0)
    lams: tuple[float, ...] = (0.003, 0.01, 0.03)
    batch_sizes: tuple[int, ...] = (64,)
    target_miss: float = 0.002
    val_fraction: float = 0.2
    group_column: str | None = None

    def __post_init__(self) -> None:
        for name in ("alphas", "lams", "batch_sizes"):
            values = tuple(getattr(self, name))
            if not values:
                raise InvalidInputError(f"the selection grid needs at least one value in {name}")
            object.__setattr__(self, name, values)
        if not all(math.isfinite(a) and a > 0 for a in self.alphas):
            raise InvalidInputError(f"every alpha must be > 0; got {self.alphas}")
        if not all(math.isfinite(v) and v >= 0 for v in self.lams):
            raise InvalidInputError(f"every lambda must be >= 0; got {self.lams}")
        if not all(isinstance(b, int) and b >= 1 for b in self.batch_sizes):
            raise InvalidInputError(f"every batch size must be a positive integer; got {self.batch_sizes}")
        if not 0 <= self.target_miss < 1:
            raise InvalidInputError(f"target_miss must be in [0, 1); got {self.target_miss}")
        if not 0 < self.val_fraction < 1:
            raise InvalidInputError(f"val_fraction must be in (0, 1); got {self.val_fraction}")
        if self.group_column is not None and (
            not isinstance(self.group_column, str) or not self.group_column
        ):
            raise InvalidInputError(f"group_column must be a column name; got {self.group_column!r}")

    def grid(self) -> list[tuple[float, float, int]]:
        """The candidates ``(alpha, lam, batch_size)`` in the order they are trained."""
        return list(itertools.product(self.alphas, self.lams, self.batch_sizes))

    def describe(self) -> str:
        """The rule in one sentence."""
        held = "rows" if self.group_column is None else f"groups ({self.group_column})"
        return (
            "smallest held-out mean log-volume among the candidates whose raw held-out miss rate is at "
            f"most {self.target_miss:g} (else the smallest miss rate), on {self.val_fraction:g} of the "
            f"training {held} held out; then retrained on all the training rows"
        )

    def choose(self, candidates: Sequence[Candidate]) -> SelectionRecord:
        """Apply the rule to measured candidates."""
        if not candidates:
            raise InvalidInputError("no candidate to choose from")
        ok = [c for c in candidates if c.val_miss_rate <= self.target_miss]
        if ok:
            best = min(ok, key=lambda c: c.val_log_volume)
        else:
            best = min(candidates, key=lambda c: (c.val_miss_rate, c.val_log_volume))
        return SelectionRecord(rule=self, candidates=tuple(candidates), chosen=best, target_met=bool(ok))

    def to_dict(self) -> dict[str, Any]:
        """Plain data (model files, certificates)."""
        return {
            "alphas": list(self.alphas),
            "lams": list(self.lams),
            "batch_sizes": list(self.batch_sizes),
            "target_miss": self.target_miss,
            "val_fraction": self.val_fraction,
            "group_column": self.group_column,
            "rule": self.describe(),
        }


@dataclass(frozen=True, kw_only=True)
class Candidate:
    """One candidate of the grid, measured on the held-out training rows.

    Attributes
    ----------
    alpha, lam : float
        The hinge width and the weight of the volume term.
    batch_size : int
        Rows per Adam step while the candidate was trained.
    val_n, val_misses : int
        Held-out rows (or groups) and how many fell outside their sets.
    val_log_volume : float
        Mean log-volume of the held-out sets.
    """

    alpha: float
    lam: float
    batch_size: int
    val_n: int
    val_misses: int
    val_log_volume: float

    def __post_init__(self) -> None:
        if self.val_n < 1 or not 0 <= self.val_misses <= self.val_n:
            raise InvalidInputError(
                f"need 0 <= misses <= n and n >= 1; got {self.val_misses} of {self.val_n}"
            )

    @property
    def val_miss_rate(self) -> float:
        """Raw miss rate on the held-out rows."""
        return self.val_misses / self.val_n

    def to_dict(self) -> dict[str, Any]:
        """Plain data."""
        return {
            "alpha": self.alpha,
            "lam": self.lam,
            "batch_size": self.batch_size,
            "val_n": self.val_n,
            "val_misses": self.val_misses,
            "val_miss_rate": self.val_miss_rate,
            "val_log_volume": self.val_log_volume,
        }


@dataclass(frozen=True, kw_only=True)
class SelectionRecord:
    """What :class:`HingeSelection` found: every candidate, the chosen one, whether the target was met.

    Attributes
    ----------
    rule : HingeSelection
        The rule applied: its grid, ``target_miss`` and held-out share.
    candidates : tuple of Candidate
        Every candidate of the grid, measured on the held-out rows, in the order trained.
    chosen : Candidate
        The candidate of smallest mean log-volume among those within ``target_miss``; if none
        is, the one of smallest miss rate (then log-volume).
    target_met : bool
        Whether any candidate's held-out miss rate was within ``target_miss`` (False: the
        chosen one misses more often than the rule asks).
    seconds : float
        Wall time of the whole selection (every candidate's training and measurement), in
        seconds; not compared and rounded to 0.01 s in :meth:`to_dict`.
    """

    rule: HingeSelection
    candidates: tuple[Candidate, ...]
    chosen: Candidate
    target_met: bool
    seconds: float = field(default=0.0, compare=False)

    def summary(self) -> str:
        """One line: the chosen values and the evidence."""
        c = self.chosen
        met = "" if self.target_met else f" (no candidate met the target {self.rule.target_miss:g})"
        return (
            f"alpha = {c.alpha:g}, lambda = {c.lam:g}, batch size {c.batch_size}: held-out raw miss "
            f"{c.val_misses}/{c.val_n}, mean log-volume {c.val_log_volume:.3f}, chosen from "
            f"{len(self.candidates)} candidates{met}"
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data (stored in the model file's metadata as ``selection``)."""
        return {
            "rule": self.rule.to_dict(),
            "chosen": self.chosen.to_dict(),
            "target_met": self.target_met,
            "candidates": [c.to_dict() for c in self.candidates],
            "seconds": round(self.seconds, 2),
            "summary": self.summary(),
        }
