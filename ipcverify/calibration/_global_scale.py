"""Global calibration: one scale factor for every query (:class:`Global`, the default kind).

The network's score ``g = ||C (y - c)||`` is computed on ``n`` held-out calibration
samples; the calibrated contract is ``E(c, C / s)`` with ``s`` the ``k``-th smallest score
(:mod:`ipcverify.calibration._threshold`), so that ``y`` lies in it exactly when ``g <= s``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ipcverify.calibration._bounds import CalibrationMode
from ipcverify.calibration._method import CalibrationRecord, CalibrationSample, CalibrationSpec
from ipcverify.calibration._protocol import (
    AllowedRate,
    CalibrationSummary,
    FloatArray,
    GroupInfo,
    RowClaim,
    one_group,
    one_scale,
    summarize,
)
from ipcverify.calibration._threshold import ScoreThreshold, guarantee_sentence, threshold_scores
from ipcverify.errors import InvalidInputError


@dataclass(frozen=True, kw_only=True)
class GlobalCalibration(RowClaim):
    """One scale factor for every input: the calibrated IPC is ``E(c, C / scale)``.

    Attributes
    ----------
    threshold : ScoreThreshold
        Mode, epsilon, delta, n, k and scale.
    data_hash : str
        Content hash of the calibration data.
    network_hash : str
        :func:`network_fingerprint` of the network that was calibrated.

    Examples
    --------
    >>> t = threshold_scores(np.linspace(0.1, 2.0, 200), epsilon=0.1, delta=0.1, mode="marginal")
    >>> cal = GlobalCalibration(threshold=t, data_hash="d", network_hash="h")
    >>> cal.scale_for(np.zeros((2, 1)), np.zeros((2, 3))).shape
    (2,)
    >>> cal.groups()[0].label, cal.groups()[0].k
    ('all', 181)
    >>> round(cal.allowed_violation_rate().rate, 3)  # marginal: a Beta(20, 181) quantile
    0.127
    """

    threshold: ScoreThreshold
    data_hash: str
    network_hash: str
    kind: ClassVar[str] = "global"

    def __post_init__(self) -> None:
        if not isinstance(self.threshold, ScoreThreshold):
            raise InvalidInputError("a global calibration needs a ScoreThreshold")

    @property
    def mode(self) -> CalibrationMode:
        """``"pac"`` or ``"marginal"``."""
        return self.threshold.mode

    @property
    def epsilon(self) -> float:
        """Target violation rate."""
        return self.threshold.epsilon

    @property
    def delta(self) -> float:
        """Confidence parameter."""
        return self.threshold.delta

    @property
    def n(self) -> int:
        """Number of calibration samples used."""
        return self.threshold.n

    def scale_for(self, x: FloatArray, yhat: FloatArray) -> FloatArray:
        """The scale (same for every sample), shape (B,)."""
        return one_scale(x, self.threshold.scale)

    def group_index(self, x: FloatArray, yhat: FloatArray) -> NDArray[np.intp]:
        """Every query is in the one group (zeros, shape (B,))."""
        return one_group(x)

    def groups(self) -> tuple[GroupInfo, ...]:
        """One group, ``"all"``."""
        t = self.threshold
        return (GroupInfo(label="all", n=t.n, k=t.k, scale=t.scale),)

    def allowed_violation_rate(self) -> AllowedRate:
        """PAC: the certified epsilon; marginal: the ``1 - delta`` quantile of its Beta law."""
        t = self.threshold
        # the violation rate of a marginal calibration is Beta(n - k + 1, k) (continuous scores)
        reason = (
            "the PAC calibration allows a violation rate up to this value (w.p. 1 - delta)"
            if t.mode == "pac"
            else "1 - delta quantile of the marginal calibration's Beta(n - k + 1, k) violation rate"
        )
        return AllowedRate(rate=t.allowed_rate(), reason=reason)

    def summary(self) -> CalibrationSummary:
        """The typed record (``k``, ``scale`` and ``order_statistic`` as details)."""
        t = self.threshold
        return summarize(
            self,
            certified_epsilon=t.certified_epsilon,
            grouping="all samples",
            details={"k": t.k, "scale": t.scale, "order_statistic": t.order_statistic},
        )

    def guarantee(self) -> str:
        """The guarantee in one plain sentence."""
        return guarantee_sentence(self.threshold, "a new sample")

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form stored in the model file."""
        return {
            "kind": self.kind,
            **self.threshold.to_dict(),
            "data_hash": self.data_hash,
            "network_hash": self.network_hash,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> GlobalCalibration:
        """Inverse of :meth:`to_dict`."""
        return cls(
            threshold=ScoreThreshold.from_dict(data),
            data_hash=str(data["data_hash"]),
            network_hash=str(data["network_hash"]),
        )

    @classmethod
    def fit(
        cls,
        scores: FloatArray,
        epsilon: float,
        delta: float,
        mode: CalibrationMode,
        *,
        data_hash: str,
        network_hash: str,
    ) -> GlobalCalibration:
        """Calibrate one threshold on all the scores."""
        return cls(
            threshold=threshold_scores(scores, epsilon, delta, mode),
            data_hash=data_hash,
            network_hash=network_hash,
        )


@dataclass(frozen=True, kw_only=True)
class Global(CalibrationSpec):
    """Global calibration, one scale factor for every query: a spec for ``calibrate()``.

    Parameters
    ----------
    mode : {"pac", "marginal"}
        Training-conditional (PAC: with probability ``1 - delta`` over the calibration draw) or
        marginal (split conformal: on average over calibration draws) guarantee.

    Examples
    --------
    >>> sample = CalibrationSample(scores=np.linspace(0.1, 2.0, 200), data=None, epsilon=0.1, delta=0.1,
    ...                            data_hash="d", network_hash="h")
    >>> cal = Global(mode="marginal").fit(sample)
    >>> cal.kind, cal.groups()[0].k
    ('global', 181)
    >>> Global(mode="bayes")
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: mode must be 'pac' or 'marginal'; got 'bayes'
    """

    kind: ClassVar[str] = "global"
    record: ClassVar[CalibrationRecord] = GlobalCalibration

    def fit(self, sample: CalibrationSample) -> GlobalCalibration:
        """Calibrate one threshold on all the scores."""
        return GlobalCalibration.fit(sample.scores, sample.epsilon, sample.delta, self.mode, **sample.ids)
