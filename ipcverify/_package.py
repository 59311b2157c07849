"""What the package is: its version, and its package-level names, imported when first used (PEP 562).

:data:`VERSION` lives here, at the bottom of the import graph, so that a module that writes
it into a file (a certificate, a manifest, an ONNX graph) need not import the package top.

Every stage package lists its public names once, as imports under ``if TYPE_CHECKING:``
in its ``__init__.py`` (what a type checker and a reader see), and hands its ``__file__`` to
:func:`lazy_exports`, which reads that block and imports a name's private module only when
the name is first asked for. So ``import ipcverify`` stays light (numpy, no torch), and
``from ipcverify import train`` imports torch only then.

Examples
--------
>>> import ipcverify.sets
>>> ipcverify.sets.Box.__name__
'Box'
"""

from __future__ import annotations

import ast
import importlib
import sys
from collections.abc import Callable
from typing import Any

#: The version of ipcverify (also ``ipcverify.__version__``; pyproject.toml holds the same).
VERSION = "0.1.0"


def exported_names(init_file: str) -> dict[str, tuple[str, str]]:
    """Map each name imported under ``if TYPE_CHECKING:`` in a file to (module, name there).

    Parameters
    ----------
    init_file : str
        Path of a package's ``__init__.py``.

    Returns
    -------
    dict
        ``{exported name: (absolute module, attribute in that module)}``.

    Examples
    --------
    >>> import ipcverify.sets
    >>> exported_names(ipcverify.sets.__file__)["Box"]
    ('ipcverify.sets._box', 'Box')
    """
    with open(init_file, encoding="utf-8") as fh:
        tree = ast.parse(fh.read())
    table: dict[str, tuple[str, str]] = {}
    for node in tree.body:
        if not (
            isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"
        ):
            continue
        for stmt in node.body:
            if isinstance(stmt, ast.ImportFrom) and stmt.module and stmt.level == 0:
                for alias in stmt.names:
                    table[alias.asname or alias.name] = (stmt.module, alias.name)
    return table


def lazy_exports(package: str, init_file: str) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package whose names are imported on first use.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    init_file : str
        The package's ``__file__``; its ``if TYPE_CHECKING:`` imports are the exported names.

    Returns
    -------
    tuple
        ``(__getattr__, __dir__)`` to assign at the package's top level.

    Examples
    --------
    >>> import ipcverify.calibration
    >>> "Grouped" in dir(ipcverify.calibration)
    True
    """
    table: dict[str, tuple[str, str]] | None = None

    def names() -> dict[str, tuple[str, str]]:
        nonlocal table
        if table is None:
            table = exported_names(init_file)
        return table

    def getattr_(name: str) -> Any:
        if name.startswith("__") or name not in names():
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, attribute = names()[name]
        value = getattr(importlib.import_module(module), attribute)
        setattr(sys.modules[package], name, value)
        return value

    def dir_() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names()))

    return getattr_, dir_
