"""The registry of calibration kinds: their specs by name, and rebuilding a calibration from its record.

A kind is a spec (:class:`~ipcverify.calibration.CalibrationMethod`: what the user chooses,
with its own ``fit``) and the calibration it fits (:class:`~ipcverify.calibration.Calibration`,
stored in model files by ``to_dict()``, whose ``kind`` names the class that reads it back). A
new kind registers its spec here with one line, or from its own module with
:func:`register_kind`; :func:`ipcverify.contract.calibrate` fits only registered kinds, so
that every calibrated model can be read back.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

from ipcverify.calibration._global_scale import Global
from ipcverify.calibration._grouped_spec import Grouped
from ipcverify.calibration._method import CalibrationMethod, CalibrationRecord
from ipcverify.calibration._mondrian import Mondrian
from ipcverify.calibration._protocol import Calibration
from ipcverify.errors import InvalidInputError

M = TypeVar("M", bound=type[CalibrationMethod])

#: Calibration specs by kind name (``"global"``, ``"mondrian"``, ``"grouped"``, ...).
METHODS: dict[str, type[CalibrationMethod]] = {}
#: Calibration classes by the ``kind`` stored in their records.
KINDS: dict[str, CalibrationRecord] = {}


def register_kind(method: M) -> M:
    """Register a calibration kind by its spec class (usable as a class decorator); returns it.

    Parameters
    ----------
    method : type of CalibrationMethod
        The spec class; its ``kind`` names the kind and its ``record`` (a calibration class
        with the same ``kind`` and a ``from_dict``) reads calibrations of that kind back.
        Registering the same class twice is a no-op.

    Raises
    ------
    InvalidInputError
        If the spec's ``kind`` differs from its calibration class's, or another spec is
        registered under that name.

    Examples
    --------
    >>> register_kind(Global) is Global and METHODS["global"] is Global
    True
    """
    kind, record = method.kind, method.record
    if getattr(record, "kind", None) != kind:
        raise InvalidInputError(
            f"spec {method.__name__} fits kind {kind!r} but its record class is of kind "
            f"{getattr(record, 'kind', None)!r}; give both the same kind"
        )
    if METHODS.get(kind, method) is not method:
        raise InvalidInputError(
            f"calibration kind {kind!r} is already registered (by {METHODS[kind].__name__}); "
            "choose another name"
        )
    METHODS[kind] = method
    KINDS[kind] = record
    return method


register_kind(Global)
register_kind(Mondrian)
register_kind(Grouped)


def check_registered(method: CalibrationMethod) -> None:
    """Refuse a spec whose kind is not registered (a model calibrated with it could not be read back).

    Raises
    ------
    InvalidInputError
        If ``method`` is not a calibration spec, or its kind is not registered.
    """
    kind = getattr(method, "kind", None)
    if not (isinstance(kind, str) and callable(getattr(method, "fit", None))):
        known = ", ".join(f"{m.__name__}(...)" for m in METHODS.values())
        raise InvalidInputError(
            f"method must be a calibration spec ({known}, from ipcverify.calibration); got {method!r}"
        )
    if METHODS.get(kind) is not type(method):
        raise InvalidInputError(
            f"calibration kind {kind!r} ({type(method).__name__}) is not registered, so a model calibrated "
            "with it could not be read back; register its spec with "
            "ipcverify.calibration.register_kind(...) first"
        )


def calibration_from_dict(data: Mapping[str, Any]) -> Calibration:
    """Rebuild a calibration from its ``to_dict()`` form (used by :func:`ipcverify.io.load_model`).

    Parameters
    ----------
    data : Mapping
        A calibration's ``to_dict()`` record; its ``"kind"`` picks the registered class whose
        ``from_dict`` reads the rest.

    Returns
    -------
    Calibration
        The calibration, equal to the one that wrote ``data``.

    Raises
    ------
    InvalidInputError
        (a ``ValueError``) if the record is inconsistent or of an unknown kind; ``KeyError``
        if a field is missing.

    Examples
    --------
    >>> from ipcverify import calibrate, example
    >>> ex = example(200)
    >>> cal = calibrate(ex.model, ex.data, 0.1, 0.1, domain=None).calibration
    >>> calibration_from_dict(cal.to_dict()) == cal
    True
    """
    kind = data.get("kind")
    record = KINDS.get(str(kind))
    if record is None:
        known = ", ".join(repr(k) for k in KINDS)
        raise InvalidInputError(f"unknown calibration kind {kind!r} (expected one of {known})")
    return record.from_dict(data)
