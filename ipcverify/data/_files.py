"""Writing files safely: atomic writes, content hashes, and the one JSON encoder.

Every file ipcverify writes (datasets, model files, certificates, reports, summaries)
goes through :func:`atomic_write`: a crash or an error leaves the previous file intact.

Every JSON document ipcverify writes goes through :func:`json_data` (and
:func:`dumps_json` / :func:`write_json`), so that one rule holds everywhere:

* objects with a ``to_dict()`` method (the result dataclasses) are written as that dict;
  other dataclasses field by field; enumerations as their ``value``; paths as strings;
  NumPy scalars and arrays as plain numbers and lists; mapping keys as strings;
* **non-finite floats**: JSON has no infinity and no NaN, so ``+inf`` is written as the
  string ``"inf"``, ``-inf`` as ``"-inf"`` and NaN as ``null``. A vacuous bound stays
  visibly infinite rather than turning into "unknown"; :func:`json_float` reads the
  strings back.

Examples
--------
>>> dumps_json({"bound": float("inf"), "rate": 0.25, "missing": float("nan")})
'{"bound": "inf", "rate": 0.25, "missing": null}'
>>> json_float("inf"), json_float(0.5), json_float(None)
(inf, 0.5, nan)
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import math
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

from ipcverify._wording._spelling import option as spell
from ipcverify.errors import InvalidInputError


def _umask() -> int:
    """The process umask (read by setting and restoring it)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path: str | os.PathLike[str], write: Callable[[IO[Any]], Any], mode: str = "wb") -> None:
    """Write a file atomically: ``write(fileobj)`` to a temp file, then rename over ``path``.

    A crash or error leaves any existing file at ``path`` untouched. The new file gets
    the permissions an ordinary ``open(path, "w")`` would give (``0o666`` minus the
    umask), not the private ``0o600`` of the temporary file.

    Parameters
    ----------
    path : path-like
        The file.
    write : callable
        Writes the content to the open temporary file it is given.
    mode : str
        Mode of the temporary file (``"wb"`` or ``"w"``).

    Examples
    --------
    >>> import os, tempfile
    >>> p = os.path.join(tempfile.mkdtemp(), "a.txt")
    >>> atomic_write(p, lambda f: f.write("hello"), mode="w")
    >>> open(p).read()
    'hello'
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    except OSError as exc:  # name the file the caller asked for, not the temporary one
        raise type(exc)(exc.errno, exc.strerror, str(p)) from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, mode) as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def refuse_overwriting_input(
    out: str | os.PathLike[str],
    inputs: Mapping[str, str | os.PathLike[str] | None],
    option: str | None = None,
) -> None:
    """Refuse an output path that is one of the command's input files (writing would destroy it).

    Two paths are the same file if they name one existing file (hard links and symbolic links
    included) or, for a file not written yet, resolve to the same absolute path.

    Parameters
    ----------
    out : path-like
        The file about to be written.
    inputs : mapping of str to path-like or None
        The inputs by the name the user knows them by (``"DATA"``, ``"--truth"``); None is skipped.
    option : str, optional
        The output's option name, for the message (default: the ``out`` parameter's spelling).

    Raises
    ------
    InvalidInputError
        Naming the input and the option.

    Examples
    --------
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> data = os.path.join(d, "log.csv")
    >>> atomic_write(data, lambda f: f.write("x_0\\n1\\n"), mode="w")
    >>> refuse_overwriting_input(os.path.join(d, "model.pt"), {"DATA": data})  # a different file: fine
    >>> refuse_overwriting_input(os.path.join(d, ".", "log.csv"), {"DATA": data})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: the output .../log.csv is also the input DATA; ...
    """
    o = Path(out)
    for name, given in inputs.items():
        if given is None:
            continue
        i = Path(given)
        try:
            same = os.path.samefile(o, i)
        except OSError:  # one of them does not exist (yet)
            same = o.resolve() == i.resolve()
        if same:
            said = option if option is not None else spell("out")
            raise InvalidInputError(
                f"{said} {o} is also the input {name}; writing it would destroy that input -- "
                f"choose another path for {said}"
            )


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 hex digest of a file's bytes.

    Parameters
    ----------
    path : path-like
        The file.

    Examples
    --------
    >>> import os, tempfile
    >>> p = os.path.join(tempfile.mkdtemp(), "a.txt")
    >>> atomic_write(p, lambda f: f.write(b""))
    >>> file_sha256(p)[:12]
    'e3b0c44298fc'
    """
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _float(v: float) -> float | str | None:
    if math.isnan(v):
        return None
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return v


def json_data(obj: Any) -> Any:
    """Plain JSON data for ``obj`` under the module's one rule (see the module docstring).

    Parameters
    ----------
    obj : object
        Numbers, NumPy scalars and arrays, strings, mappings and sequences of them.

    Examples
    --------
    >>> import numpy as np
    >>> json_data({1: np.float64(-np.inf), "a": np.arange(2), "b": (True, np.bool_(False))})
    {'1': '-inf', 'a': [0, 1], 'b': [True, False]}
    """
    if obj is None or isinstance(obj, (str, bool)):
        return obj
    if isinstance(obj, int) and not isinstance(obj, bool):
        return obj
    if isinstance(obj, float):
        return _float(obj)
    if isinstance(obj, np.generic):
        return json_data(obj.item())
    if isinstance(obj, np.ndarray):
        return json_data(obj.tolist())
    if isinstance(obj, enum.Enum):
        return json_data(obj.value)
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    to_dict = getattr(obj, "to_dict", None)
    if callable(to_dict) and not isinstance(obj, type):
        return json_data(to_dict())
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: json_data(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, Mapping):
        return {str(k): json_data(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        items = sorted(obj) if isinstance(obj, (set, frozenset)) else obj
        return [json_data(v) for v in items]
    raise TypeError(f"cannot write an object of type {type(obj).__name__} as JSON")


def json_float(value: Any) -> float:
    """Read back a float written by :func:`json_data` (``"inf"``, ``"-inf"``, ``null`` -> NaN).

    Parameters
    ----------
    value : float, str or None
        A value :func:`json_data` wrote for a float.

    Examples
    --------
    >>> json_float("-inf")
    -inf
    """
    if value is None:
        return math.nan
    if value == "inf":
        return math.inf
    if value == "-inf":
        return -math.inf
    return float(value)


def dumps_json(obj: Any, indent: int | None = None) -> str:
    """``json.dumps`` of :func:`json_data` (never writes the non-standard ``Infinity`` / ``NaN``).

    Parameters
    ----------
    obj : object
        Anything :func:`json_data` takes.
    indent : int, optional
        As for ``json.dumps``.
    """
    return json.dumps(json_data(obj), indent=indent, allow_nan=False)


def write_json(path: str | os.PathLike[str], obj: Any, indent: int | None = 2) -> None:
    """Write ``obj`` as JSON (one rule for non-finite floats), atomically, ending in a newline.

    Parameters
    ----------
    path : path-like
        The file.
    obj : object
        Anything :func:`json_data` takes.
    indent : int, optional
        As for ``json.dumps``.

    Examples
    --------
    >>> import os, tempfile
    >>> p = os.path.join(tempfile.mkdtemp(), "r.json")
    >>> write_json(p, {"bound": float("inf")}, indent=None)
    >>> open(p).read()
    '{"bound": "inf"}\\n'
    """
    text = dumps_json(obj, indent=indent) + "\n"
    atomic_write(path, lambda f: f.write(text), mode="w")
