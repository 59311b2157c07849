"""Every parameter of a public function or class of ipcverify is documented in its docstring.

Public means a name in the ``__all__`` of ``ipcverify`` or of one of its packages. A function's
parameters must each have an entry in the numpydoc ``Parameters`` section of its docstring; a
class's ``__init__`` parameters (a dataclass's fields) must each have one under ``Parameters``
or ``Attributes`` of the class docstring (or ``Parameters`` of ``__init__``). An entry may name
several parameters (``x, yhat : array_like``); ``*args`` and ``**kwargs`` are documented as
``*args`` / ``**kwargs`` (the stars optional). ``self`` and ``cls`` need no entry.
"""

from __future__ import annotations

import dataclasses
import enum
import importlib
import inspect
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]

_ENTRY = re.compile(r"^(?P<names>\*{0,2}[A-Za-z_][\w]*(?:\s*,\s*\*{0,2}[A-Za-z_][\w]*)*)\s*(?::.*)?$")


def section_names(doc: str | None, section: str) -> set[str]:
    """The parameter names listed in one numpydoc section (``Parameters``, ``Attributes``, ...).

    Entries are the lines at the section's own indentation; the text under an entry is
    indented deeper. The section ends at the next underlined heading or at the end.
    """
    if not doc:
        return set()
    lines = inspect.cleandoc(doc).splitlines()
    names: set[str] = set()
    i = 0
    while i < len(lines) - 1:
        if lines[i].strip() == section and set(lines[i + 1].strip()) == {"-"}:
            base = len(lines[i]) - len(lines[i].lstrip())
            j = i + 2
            while j < len(lines):
                line = lines[j]
                if j + 1 < len(lines) and line.strip() and set(lines[j + 1].strip()) == {"-"}:
                    break  # the next section
                indent = len(line) - len(line.lstrip())
                if line.strip() and indent == base and (m := _ENTRY.match(line.strip())):
                    names |= {n.strip().lstrip("*") for n in m.group("names").split(",")}
                j += 1
            i = j
        else:
            i += 1
    return names


def _parameters(obj: Callable[..., Any]) -> list[str]:
    try:
        signature = inspect.signature(obj)
    except (TypeError, ValueError):  # a builtin without a signature
        return []
    return [p for p in signature.parameters if p not in {"self", "cls"}]


def _own_init(cls: type) -> Callable[..., Any] | None:
    """The class's ``__init__`` if ipcverify wrote it (or a dataclass generated it), else None."""
    for klass in cls.__mro__:
        if "__init__" in vars(klass):
            init = vars(klass)["__init__"]
            module = getattr(klass, "__module__", "") or ""
            return init if module.startswith("ipcverify") else None
    return None


def undocumented(obj: Any) -> set[str]:
    """The parameters of a public function or class that its docstring does not document."""
    if inspect.isclass(obj):
        if issubclass(obj, (enum.Enum, BaseException)) or getattr(obj, "_is_protocol", False):
            return set()
        init = _own_init(obj)
        if init is None:
            return set()
        documented = section_names(obj.__doc__, "Parameters") | section_names(obj.__doc__, "Attributes")
        documented |= section_names(init.__doc__, "Parameters")
        params = _parameters(init)
        if dataclasses.is_dataclass(obj):
            params = [f.name for f in dataclasses.fields(obj) if f.init]
        return set(params) - documented
    if inspect.isfunction(obj) or inspect.ismethod(obj) or inspect.isbuiltin(obj):
        return set(_parameters(obj)) - section_names(obj.__doc__, "Parameters")
    return set()  # a constant


def _packages() -> Iterator[str]:
    yield "ipcverify"
    for init in sorted((ROOT / "ipcverify").rglob("__init__.py")):
        yield ".".join(init.parent.relative_to(ROOT).parts)


def _public() -> list[tuple[str, str]]:
    seen: set[tuple[str, str]] = set()
    out = []
    for package in _packages():
        module = importlib.import_module(package)
        for name in getattr(module, "__all__", []):
            obj = getattr(module, name)
            key = (getattr(obj, "__module__", package), getattr(obj, "__qualname__", name))
            if key not in seen and (inspect.isclass(obj) or callable(obj)):
                seen.add(key)
                out.append((package, name))
    return out


PUBLIC = _public()


def test_the_section_reader_reads_numpydoc_entries():
    doc = """Summary.

    Parameters
    ----------
    x, yhat : array_like
        The queries; a line that looks like an entry but is indented deeper:
        z : not a parameter
    *args
        Positional.
    **kwargs : dict
        Keywords.
    seed : int, default 0

    Returns
    -------
    out : float
    """
    assert section_names(doc, "Parameters") == {"x", "yhat", "args", "kwargs", "seed"}
    assert section_names(doc, "Attributes") == set()
    assert section_names(None, "Parameters") == set()


def test_the_check_catches_an_undocumented_parameter():
    def documented(a: int, *rest: int, b: int = 0, **options: int) -> int:
        """Add.

        Parameters
        ----------
        a, b : int
            Terms.
        *rest, **options
            More.
        """
        return a + b

    def missing(a: int, b: int) -> int:
        """Add.

        Parameters
        ----------
        a : int
            A term.
        """
        return a + b

    @dataclasses.dataclass(frozen=True)
    class Record:
        """A record.

        Attributes
        ----------
        n : int
            A count.
        """

        n: int
        label: str

    Record.__module__ = "ipcverify.fake"  # as if ipcverify had written it
    assert undocumented(documented) == set()
    assert undocumented(missing) == {"b"}
    assert undocumented(Record) == {"label"}


def test_public_names_are_found():
    names = {name for _, name in PUBLIC}
    assert {"train", "calibrate", "certify", "IPCQuery", "PerceptionDataset", "DomainModel"} <= names


@pytest.mark.parametrize(("package", "name"), PUBLIC, ids=[f"{p}.{n}" for p, n in PUBLIC])
def test_every_parameter_of_a_public_name_is_documented(package, name):
    obj = getattr(importlib.import_module(package), name)
    missing = undocumented(obj)
    assert not missing, f"{package}.{name}: document {sorted(missing)} under Parameters"
