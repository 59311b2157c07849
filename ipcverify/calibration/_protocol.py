"""What every calibration kind provides, so that no caller asks which kind it holds.

A calibration rescales an IPC's raw sets: the calibrated set of a query is
``E(c, C / s)`` with ``s = scale_for(x, yhat)``. Certificates, single queries, the
ONNX export, reports and the case study use only the :class:`Calibration` protocol:

* :meth:`~Calibration.scale_for` -- the scale of each query;
* :meth:`~Calibration.groups` / :meth:`~Calibration.group_index` -- the groups that were
  calibrated separately (one group for a global calibration), as :class:`GroupInfo`;
* :meth:`~Calibration.allowed_violation_rate` -- the violation rate the calibration allows
  with probability ``1 - delta`` (what test data may be checked against), as
  :class:`AllowedRate`;
* :meth:`~Calibration.test_counts` -- how test data checks the calibration's claim: the
  violations counted in the unit the claim is about (samples, or whole groups), as
  :class:`TestCounts`;
* :meth:`~Calibration.group_claim` -- for a claim about groups (flights, runs), their column,
  the per-group statistic and its seed, as :class:`GroupClaim` (None for a claim about rows);
* :meth:`~Calibration.summary` -- one typed record (:class:`CalibrationSummary`), the
  ``calibration`` block of ``certificate.json``;
* :meth:`~Calibration.guarantee`, :meth:`~Calibration.to_dict`.

A kind with one scale for every query answers ``scale_for`` and ``group_index`` with
:func:`one_scale` and :func:`one_group`; a kind whose claim is about a new sample (a row)
inherits ``test_counts`` and ``group_claim`` from :class:`RowClaim`.

What the user chooses is a :class:`~ipcverify.calibration.CalibrationMethod`
(:mod:`ipcverify.calibration._method`): a frozen spec of a kind's options whose ``fit`` returns
the kind's calibration. A new kind is one module that implements both protocols and a line that
registers its spec (:func:`~ipcverify.calibration.register_kind`), so that model files can read
it back.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from ipcverify.calibration._bounds import CalibrationMode
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError

FloatArray = NDArray[np.float64]
#: The statistic of one group (flight, run) that a claim about groups is checked and monitored with: any
#: of its samples violates, one random sample of it does (earlier per-sample claims), its share of rows
#: outside (a value in [0, 1]), or whether that share exceeds the claim's limit.
GroupUnit = Literal["trajectory", "sample", "share", "share-of-runs"]
#: The group statistics.
GROUP_UNITS: tuple[GroupUnit, ...] = ("trajectory", "sample", "share", "share-of-runs")


@dataclass(frozen=True, kw_only=True)
class GroupInfo:
    """One separately calibrated group: its label, calibration samples ``n``, order statistic ``k``, scale.

    Attributes
    ----------
    label : str
        The group's name (``"all"`` for a single scale, e.g. ``"run=3"`` for a Mondrian group).
    n : int
        Calibration scores the group's threshold was taken from.
    k : int
        Rank of the score used (``1 <= k <= n``); for a grouped calibration, the used rows
        with score at most the threshold.
    scale : float
        The group's calibrated scale ``s``, finite and ``> 0``: its sets are ``E(c, C / s)``.

    Examples
    --------
    >>> GroupInfo(label="all", n=100, k=96, scale=1.5).scale
    1.5
    """

    label: str
    n: int
    k: int
    scale: float

    def __post_init__(self) -> None:
        if not (1 <= self.k <= self.n) or not (math.isfinite(self.scale) and self.scale > 0):
            raise InvalidInputError(
                f"group {self.label!r}: need 1 <= k <= n and a finite scale > 0; "
                f"got n={self.n}, k={self.k}, scale={self.scale!r}"
            )

    def to_dict(self) -> dict[str, Any]:
        """Plain data ``{label, n, k, scale}``."""
        return {"label": self.label, "n": self.n, "k": self.k, "scale": self.scale}


@dataclass(frozen=True, kw_only=True)
class AllowedRate:
    """The violation rate a calibration allows, if it makes a per-draw claim.

    Attributes
    ----------
    rate : float or None
        With probability at least ``1 - delta`` over the calibration draw, the violation
        rate is at most ``rate``; None if the calibration makes no such claim.
    reason : str
        Why this is the allowed rate (or why there is none).

    Examples
    --------
    >>> AllowedRate(rate=None, reason="marginal").checkable
    False
    """

    rate: float | None
    reason: str

    def __post_init__(self) -> None:
        if self.rate is not None and not (0.0 <= self.rate <= 1.0):
            raise InvalidInputError(f"an allowed violation rate lies in [0, 1]; got {self.rate!r}")

    @property
    def checkable(self) -> bool:
        """Whether test data can be checked against a rate."""
        return self.rate is not None


@dataclass(frozen=True, kw_only=True)
class TestCounts:
    """Violations of fresh test data counted in the unit a calibration's claim is about.

    A per-sample claim over exchangeable samples is tested on rows; a claim over exchangeable
    groups (flights) on one statistic per group, since the rows of a group are correlated and
    a binomial bound on them would not be valid.

    Attributes
    ----------
    violations : int
        Units outside their sets, ``0 <= violations <= n``.
    n : int
        Units counted, ``n >= 1`` (the binomial sample size).
    unit : str
        What was counted, for reports: ``"samples"`` or a description of the groups.
    shares : tuple of float, optional
        For a claim about the expected share of a run's rows outside: each test unit's share
        (the test bounds their mean); ``violations`` then counts the units with some row outside.

    Examples
    --------
    >>> row_counts(np.array([True, False, False])).to_dict()
    {'violations': 1, 'n': 3, 'unit': 'samples'}
    """

    __test__ = False  # not a pytest test class

    violations: int
    n: int
    unit: str
    shares: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if not (0 <= self.violations <= self.n and self.n >= 1):
            raise InvalidInputError(f"need 0 <= violations <= n, n >= 1; got {self.violations}, {self.n}")
        if self.shares is not None and (
            len(self.shares) != self.n or not all(0.0 <= v <= 1.0 for v in self.shares)
        ):
            raise InvalidInputError(f"need one share in [0, 1] per unit ({self.n}); got {self.shares!r}")

    def to_dict(self) -> dict[str, Any]:
        """Plain data (with ``mean_share`` when the units are counted by their shares)."""
        out: dict[str, Any] = {"violations": self.violations, "n": self.n, "unit": self.unit}
        if self.shares is not None:
            out["mean_share"] = sum(self.shares) / self.n
        return out


@dataclass(frozen=True, kw_only=True)
class GroupClaim:
    """What a claim about groups (flights, runs) is about, so that test data can be counted alike.

    Attributes
    ----------
    column : str
        The data column naming each sample's group.
    unit : {"trajectory", "sample", "share", "share-of-runs"}
        The statistic of a group: any of its samples outside its set; one sample drawn at random
        (seeded) from it outside; its share of rows outside; or whether that share exceeds
        ``share_limit``.
    seed : int
        Seeds the choice of one sample per group (``unit="sample"``).
    share_limit : float, optional
        ``unit="share-of-runs"`` only: the share of a run's rows that may lie outside.

    Examples
    --------
    >>> GroupClaim(column="run", unit="share").unit
    'share'
    """

    column: str
    unit: GroupUnit
    seed: int = 0
    share_limit: float | None = None

    def __post_init__(self) -> None:
        if self.unit not in GROUP_UNITS or not self.column:
            raise InvalidInputError(
                f"a group claim needs a column name and a unit in {GROUP_UNITS}; got {self.column!r}, "
                f"{self.unit!r}"
            )
        if (self.unit == "share-of-runs") != (self.share_limit is not None):
            raise InvalidInputError("a share limit goes with a 'share-of-runs' group claim, and only with it")


def row_counts(violated: NDArray[np.bool_]) -> TestCounts:
    """Violations counted per test sample (the unit of a per-sample claim over exchangeable rows)."""
    v = np.asarray(violated, dtype=bool)
    return TestCounts(violations=int(v.sum()), n=int(v.size), unit="samples")


@dataclass(frozen=True, kw_only=True)
class CalibrationSummary:
    """The ``calibration`` block of ``certificate.json``, one typed record for every kind.

    Attributes
    ----------
    kind : str
        ``"global"``, ``"mondrian"``, ...
    mode : {"pac", "marginal"}
    epsilon, delta : float
        Target violation rate and confidence parameter.
    n : int
        Calibration samples whose scores were used.
    certified_epsilon : float
        The violation rate actually certified (at most ``epsilon``).
    guarantee : str
        The guarantee in one plain sentence.
    data_sha256 : str
        Content hash of the calibration data.
    groups : tuple of GroupInfo
        The separately calibrated groups (one for a global calibration).
    grouping : str
        What the groups are, in words ("all samples", "5 bins of x_0", ...).
    details : mapping
        Kind-specific fields (``k``, ``scale`` ...), written beside the common ones; a
        ``groups`` entry replaces the plain group records in :meth:`to_dict`.

    Examples
    --------
    >>> g = (GroupInfo(label="all", n=10, k=10, scale=2.0),)
    >>> s = CalibrationSummary(kind="global", mode="pac", epsilon=0.1, delta=0.1, n=10,
    ...     certified_epsilon=0.1, guarantee="...", data_sha256="d", groups=g, grouping="all samples",
    ...     details={"k": 10})
    >>> s.to_dict()["k"], s.to_dict()["groups"][0]["scale"]
    (10, 2.0)
    """

    kind: str
    mode: CalibrationMode
    epsilon: float
    delta: float
    n: int
    certified_epsilon: float
    guarantee: str
    data_sha256: str
    groups: tuple[GroupInfo, ...]
    grouping: str
    details: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        clash = set(self.details) & {f for f in self.__dataclass_fields__ if f not in ("details", "groups")}
        if clash:
            raise InvalidInputError(f"calibration details may not redefine {sorted(clash)}")
        if not self.groups or sum(g.n for g in self.groups) != self.n:
            raise InvalidInputError("a calibration summary needs its groups, whose sizes add up to n")

    def to_dict(self) -> dict[str, Any]:
        """Plain data: the common fields and the kind's details."""
        return {
            "kind": self.kind,
            "mode": self.mode,
            "epsilon": self.epsilon,
            "delta": self.delta,
            "n": self.n,
            "grouping": self.grouping,
            "groups": [g.to_dict() for g in self.groups],
            **self.details,
            "certified_epsilon": self.certified_epsilon,
            "data_sha256": self.data_sha256,
            "guarantee": self.guarantee,
        }


class Calibration(Protocol):
    """What a calibration provides to the rest of ipcverify (see the module docstring)."""

    @property
    def kind(self) -> str:
        """The kind's name, stored in model files (``"global"``, ``"mondrian"``, ...)."""
        ...

    @property
    def mode(self) -> CalibrationMode:
        """``"pac"`` or ``"marginal"``."""
        ...

    @property
    def epsilon(self) -> float:
        """Target violation rate."""
        ...

    @property
    def delta(self) -> float:
        """Confidence parameter."""
        ...

    @property
    def n(self) -> int:
        """Calibration samples whose scores were used."""
        ...

    @property
    def data_hash(self) -> str:
        """Content hash of the calibration data."""
        ...

    @property
    def network_hash(self) -> str:
        """Fingerprint of the calibrated network."""
        ...

    def scale_for(self, x: FloatArray, yhat: FloatArray) -> FloatArray:
        """Per-query scale factors ``s`` (B,): the calibrated set is ``E(c, C / s)``."""
        ...

    def group_index(self, x: FloatArray, yhat: FloatArray) -> NDArray[np.intp]:
        """Index into :meth:`groups` of every query (B,)."""
        ...

    def groups(self) -> tuple[GroupInfo, ...]:
        """The separately calibrated groups (one for a global calibration)."""
        ...

    def allowed_violation_rate(self) -> AllowedRate:
        """The rate test data may be checked against (w.p. ``1 - delta``), if any."""
        ...

    def test_counts(self, violated: NDArray[np.bool_], test_data: PerceptionDataset) -> TestCounts:
        """The test data's violations counted in the unit of this calibration's claim."""
        ...

    def group_claim(self) -> GroupClaim | None:
        """The groups this calibration's claim is about (None: the claim is about rows)."""
        ...

    def summary(self) -> CalibrationSummary:
        """One typed record of the calibration."""
        ...

    def guarantee(self) -> str:
        """The guarantee in one plain sentence."""
        ...

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form stored in the model file (``kind`` included)."""
        ...


def one_scale(x: FloatArray, scale: float) -> FloatArray:
    """The scale of a kind with one scale for every query, shape (B,)."""
    return np.full(len(np.asarray(x)), scale)


def one_group(x: FloatArray) -> NDArray[np.intp]:
    """The group index of a kind with one group: zeros, shape (B,)."""
    return np.zeros(len(np.asarray(x)), dtype=np.intp)


class RowClaim:
    """The claim half of :class:`Calibration` for a kind whose claim is about a new sample (a row).

    A kind whose guarantee is per sample over exchangeable rows (one scale, or one per group of
    a column known at predict time) counts test data by rows and names no group column.

    Examples
    --------
    >>> RowClaim().test_counts(np.array([False, True]), None).to_dict()
    {'violations': 1, 'n': 2, 'unit': 'samples'}
    >>> RowClaim().group_claim() is None
    True
    """

    def test_counts(self, violated: NDArray[np.bool_], test_data: PerceptionDataset) -> TestCounts:
        """Rows: the claim is about a new sample."""
        return row_counts(violated)

    def group_claim(self) -> None:
        """None: the claim is about a new sample (a row), not about groups of rows."""
        return None


def summarize(
    cal: Calibration, *, certified_epsilon: float, grouping: str, details: Mapping[str, Any]
) -> CalibrationSummary:
    """The :class:`CalibrationSummary` of a calibration: the common fields from the protocol, and its own.

    Parameters
    ----------
    cal : Calibration
        The calibration summarised (its kind, mode, epsilon, delta, n, guarantee, data hash and
        groups are read from it).
    certified_epsilon : float
        The violation rate it certifies.
    grouping : str
        What its groups are, in words.
    details : mapping
        Its kind-specific fields.
    """
    return CalibrationSummary(
        kind=cal.kind,
        mode=cal.mode,
        epsilon=cal.epsilon,
        delta=cal.delta,
        n=cal.n,
        certified_epsilon=certified_epsilon,
        guarantee=cal.guarantee(),
        data_sha256=cal.data_hash,
        groups=cal.groups(),
        grouping=grouping,
        details=details,
    )
