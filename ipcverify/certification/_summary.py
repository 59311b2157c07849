"""The executive summary of a certificate: the records a reviewer reads first (and signs).

:class:`CertificateSummary` holds the claim in one sentence, its target ``epsilon``, ``delta``
and unit (rows, or groups such as flights), one :class:`Check` per piece of evidence with its
verdict, the date (UTC, ISO 8601), the ipcverify version, the SHA-256 of the model and the
data, and the units and labels of the perceived quantity ``y``. It is the ``summary`` block of
``certificate.json`` and the top of ``report.html``; :func:`ipcverify.certification.summarize`
builds it from a :class:`~ipcverify.certification.Certificate`.

A **weak target** (``epsilon >= 0.1``, :data:`WEAK_EPSILON`) is said so in the verdict line:
a contract that lets half the truths fall outside their sets is certified as such, not as a
strong certificate.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Literal

from ipcverify._wording._spelling import option
from ipcverify.errors import InvalidInputError

#: A calibration target ``epsilon`` at or above this is a weak target.
WEAK_EPSILON = 0.1
#: What the page says for the units of ``y`` when the user named none.
DEFAULT_UNITS = "units of the data"

CheckLevel = Literal["pass", "warn", "fail", "info"]
Strength = Literal["strong", "weak", "none"]
_LEVELS = ("pass", "warn", "fail", "info")
_DATE_FORMAT = "%Y-%m-%dT%H:%M:%SZ"


def target_strength(epsilon: float | None) -> Strength:
    """``"none"`` without a calibration target, ``"weak"`` if ``epsilon >= WEAK_EPSILON``, else ``"strong"``.

    Parameters
    ----------
    epsilon : float or None
        The calibration's target violation rate.

    Examples
    --------
    >>> target_strength(0.01), target_strength(0.1), target_strength(0.5), target_strength(None)
    ('strong', 'weak', 'weak', 'none')
    """
    if epsilon is None:
        return "none"
    return "weak" if epsilon >= WEAK_EPSILON else "strong"


def weak_target_phrase(epsilon: float, unit_statistic: str | None = None, symbol: str = "epsilon") -> str:
    """What a weak target lets through, in words: ``"epsilon = 0.5: up to half the truths may lie outside"``.

    ``unit_statistic="trajectory"`` (a claim about whole groups) speaks of groups leaving their
    sets instead of truths.

    Parameters
    ----------
    epsilon : float
        The target violation rate.
    unit_statistic : str, optional
        The statistic of a claim about groups (``"trajectory"``, ``"sample"``).
    symbol : str
        How to write epsilon.

    Examples
    --------
    >>> weak_target_phrase(0.5, symbol="ε")
    'ε = 0.5: up to half the truths may lie outside'
    >>> weak_target_phrase(0.2, "trajectory")
    'epsilon = 0.2: up to 20 % of new groups may leave their sets somewhere'
    """
    share = "half" if epsilon == 0.5 else f"{100 * epsilon:.3g} %"
    if unit_statistic == "trajectory":
        what = f"up to {share} of new groups may leave their sets somewhere"
    elif unit_statistic == "share":
        article = "the" if share == "half" else "of the"
        what = f"up to {share} {article} truths of a new run may lie outside, on average"
    else:
        what = f"up to {share} {'the' if share == 'half' else 'of the'} truths may lie outside"
    return f"{symbol} = {epsilon:g}: {what}"


def utc_now() -> str:
    """The current time, UTC, ISO 8601 to the second (``2025-01-31T12:00:00Z``).

    Examples
    --------
    >>> len(utc_now()), utc_now().endswith("Z")
    (20, True)
    """
    return datetime.now(UTC).strftime(_DATE_FORMAT)


@dataclass(frozen=True, kw_only=True)
class Check:
    """One line of the summary: a piece of evidence, its verdict, and the numbers behind it.

    Attributes
    ----------
    name : str
        What was checked ("calibration certificate", "held-out test", ...).
    verdict : str
        The outcome in a few words ("consistent", "CONTRADICTS the calibration", "vacuous", "not run").
    level : {"pass", "warn", "fail", "info"}
        How the page colours it; ``info`` is neither good nor bad news (not run, reported only).
    detail : str
        The numbers behind the verdict, in one or two sentences.

    Examples
    --------
    >>> Check(name="Theorem 1", verdict="vacuous", level="info", detail="bound 1e16 >= 1").to_dict()["level"]
    'info'
    """

    name: str
    verdict: str
    level: CheckLevel
    detail: str

    def __post_init__(self) -> None:
        if self.level not in _LEVELS:
            raise InvalidInputError(f"a check's level must be one of {_LEVELS}; got {self.level!r}")
        if not (self.name.strip() and self.verdict.strip()):
            raise InvalidInputError("a check needs a name and a verdict")

    def to_dict(self) -> dict[str, Any]:
        """``{check, verdict, level, detail}``."""
        return {"check": self.name, "verdict": self.verdict, "level": self.level, "detail": self.detail}


@dataclass(frozen=True, kw_only=True)
class CertificateSummary:
    """The summary block: what is claimed, how strongly, what each check found, and provenance.

    Attributes
    ----------
    status : str
        The certificate's status name (``CERTIFIED``, ``CONTRADICTED``, ...).
    status_detail : str
        What the status means, without repeating its name.
    claim : str
        What is guaranteed, in one sentence.
    epsilon, certified_epsilon : float or None
        The calibration's target violation rate and the rate it certifies (None: not calibrated).
    delta : float or None
        The confidence parameter (of the calibration, or of the test bound without one; None:
        neither, so nothing is claimed).
    unit : {"row", "group"}
        What the claim counts: rows, or groups of ``unit_column`` (flights, runs).
    unit_column : str or None
        The group column of a claim about groups.
    unit_statistic : {"share", "share-of-runs", "trajectory", "sample"} or None
        For a claim about groups: one random row of each, or any violation in it.
    checks : tuple of Check
        One per piece of evidence, in the order the page shows them.
    date_utc : str
        When the certificate was made, UTC, ISO 8601 (``YYYY-MM-DDTHH:MM:SSZ``).
    ipcverify_version : str
    model_sha256 : str
        SHA-256 of the model file (or of the network's weights, ``model_sha256_of="network"``,
        when no file was given).
    model_sha256_of : {"model file", "network"}
    data_sha256 : mapping of str to str
        SHA-256 of the data, by what was hashed (``"test data file"``, ``"test data content"``,
        ``"calibration data content"``, ``"training data file"``, ...).
    units : str or None
        The units of ``y`` the user named (None: :data:`DEFAULT_UNITS`).
    labels : tuple of str
        One label per coordinate of ``y``.

    Examples
    --------
    >>> s = CertificateSummary(status="CERTIFIED", status_detail="test data consistent", claim="...",
    ...     epsilon=0.5, certified_epsilon=0.45, delta=0.1, unit="row", checks=(),
    ...     date_utc="2025-01-31T12:00:00Z", ipcverify_version="0.1.0", model_sha256="ab" * 32,
    ...     model_sha256_of="model file", labels=("forward", "left", "up"), units="m")
    >>> s.strength
    'weak'
    >>> s.verdict_text()
    'CERTIFIED, WEAK TARGET (epsilon = 0.5: up to half the truths may lie outside): test data consistent'
    >>> s.axis_label(0)
    'forward [m]'
    """

    status: str
    status_detail: str
    claim: str
    epsilon: float | None
    certified_epsilon: float | None
    delta: float | None
    unit: Literal["row", "group"]
    unit_column: str | None = None
    unit_statistic: Literal["share", "share-of-runs", "trajectory", "sample"] | None = None
    checks: tuple[Check, ...]
    date_utc: str
    ipcverify_version: str
    model_sha256: str
    model_sha256_of: Literal["model file", "network"]
    data_sha256: Mapping[str, str] = field(default_factory=dict)
    units: str | None = None
    labels: tuple[str, ...]

    def __post_init__(self) -> None:
        try:
            datetime.strptime(self.date_utc, _DATE_FORMAT)
        except ValueError:
            raise InvalidInputError(
                f"the summary's date must be UTC in ISO 8601, YYYY-MM-DDTHH:MM:SSZ; got {self.date_utc!r}"
            ) from None
        if self.unit not in ("row", "group") or (self.unit == "group") != (self.unit_column is not None):
            raise InvalidInputError(
                f"the unit is 'row', or 'group' with its column; got {self.unit!r}, {self.unit_column!r}"
            )
        if self.delta is not None and not (0 < self.delta < 1):
            raise InvalidInputError(f"delta must lie strictly between 0 and 1; got {self.delta!r}")
        if self.units is not None and not self.units.strip():
            raise InvalidInputError(
                f"the units of y, if given, must not be empty; e.g. {option('units', 'm')}"
            )
        if not self.labels or any(not lab.strip() for lab in self.labels):
            raise InvalidInputError(f"every coordinate of y needs a non-empty label; got {list(self.labels)}")

    @property
    def strength(self) -> Strength:
        """The target's strength (:func:`target_strength` of ``epsilon``)."""
        return target_strength(self.epsilon)

    @property
    def certified(self) -> bool:
        """True if the status says the contract is certified (by calibration, tested or not)."""
        return self.status in ("CERTIFIED", "UNTESTED", "UNCHECKED")

    def verdict_text(self, symbol: str = "epsilon") -> str:
        """The one-line verdict: the status (``WEAK TARGET (...)`` for a certified weak one), its meaning."""
        title = self.status
        if self.certified and self.strength == "weak" and self.epsilon is not None:
            phrase = weak_target_phrase(self.epsilon, self.unit_statistic, symbol)
            title += f", WEAK TARGET ({phrase})"
        return f"{title}: {self.status_detail}"

    def unit_text(self) -> str:
        """The unit of the claim in words."""
        if self.unit == "row":
            return "row (every row counts once; the rows are assumed independent)"
        each = {
            "trajectory": "any violation in it",
            "share": "its share of rows outside",
            "share-of-runs": "whether its share of rows outside exceeds the claim's",
        }.get(str(self.unit_statistic), "one random row of it")
        return f"group of {self.unit_column!r} (a flight or run; counted by {each})"

    @property
    def units_text(self) -> str:
        """The units of ``y``: the user's, or :data:`DEFAULT_UNITS`."""
        return DEFAULT_UNITS if self.units is None else self.units

    def axis_label(self, i: int) -> str:
        """Label of an axis along coordinate ``i`` of ``y``: ``forward [m]``, ``y_0 (units of the data)``."""
        return (
            f"{self.labels[i]} [{self.units}]"
            if self.units is not None
            else f"{self.labels[i]} ({DEFAULT_UNITS})"
        )

    def to_dict(self) -> dict[str, Any]:
        """The ``summary`` block of ``certificate.json``."""
        return {
            "verdict": self.verdict_text(),
            "status": self.status,
            "strength": self.strength,
            "weak_target_threshold": WEAK_EPSILON,
            "claim": self.claim,
            "epsilon": self.epsilon,
            "certified_epsilon": self.certified_epsilon,
            "delta": self.delta,
            "unit": self.unit,
            "unit_column": self.unit_column,
            "unit_statistic": self.unit_statistic,
            "checks": [c.to_dict() for c in self.checks],
            "date_utc": self.date_utc,
            "ipcverify_version": self.ipcverify_version,
            "model_sha256": self.model_sha256,
            "model_sha256_of": self.model_sha256_of,
            "data_sha256": dict(self.data_sha256),
            "units": self.units,
            "labels": list(self.labels),
        }
