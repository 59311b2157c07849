"""The registry of calibration kinds, and rebuilding a calibration from its stored record.

A model file stores ``calibration.to_dict()``, whose ``kind`` names the class that reads
it back. A new kind registers here with one line.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ipcverify.calibration._global_scale import GlobalCalibration
from ipcverify.calibration._grouped import GroupedCalibration
from ipcverify.calibration._mondrian import MondrianCalibration
from ipcverify.calibration._protocol import Calibration
from ipcverify.errors import InvalidInputError

__all__ = ["KINDS", "calibration_from_dict"]

#: Calibration kinds by the ``kind`` stored in their records.
KINDS: dict[str, Any] = {
    cls.kind: cls for cls in (GlobalCalibration, MondrianCalibration, GroupedCalibration)
}


def calibration_from_dict(data: Mapping[str, Any]) -> Calibration:
    """Rebuild a calibration from its ``to_dict()`` form (used by :func:`ipcverify.io.load_model`).

    Raises
    ------
    InvalidInputError
        (a ``ValueError``) if the record is inconsistent or of an unknown kind; ``KeyError``
        if a field is missing.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.calibration._threshold import threshold_scores
    >>> t = threshold_scores(np.linspace(0.1, 2.0, 200), epsilon=0.1, delta=0.1, mode="marginal")
    >>> cal = GlobalCalibration(threshold=t, data_hash="d", network_hash="h")
    >>> calibration_from_dict(cal.to_dict()) == cal
    True
    """
    kind = data.get("kind")
    cls = KINDS.get(str(kind))
    if cls is None:
        known = ", ".join(repr(k) for k in KINDS)
        raise InvalidInputError(f"unknown calibration kind {kind!r} (expected one of {known})")
    cal: Calibration = cls.from_dict(data)
    return cal
