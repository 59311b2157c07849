"""The files a command writes, checked before it reads anything: one rule for every command.

* An output that is one of the command's inputs is refused
  (:func:`ipcverify.data._files.refuse_overwriting_input`).
* An output whose extension does not fit is refused, naming the extension
  (``export --onnx notes.txt``: an ONNX graph goes to a ``.onnx`` file).
* An output that exists is refused, naming ``--force``; with ``--force`` it is replaced, atomically
  (every file is written by :func:`ipcverify.data.atomic_write`: a failed command leaves the old
  file as it was). For a command that writes into a folder (``certify --out DIR``), the files it
  would write are checked, not the folder: an existing folder without them is fine.
* A missing output folder is created (by the writer), and the command says so once it has written.

Examples
--------
>>> import tempfile
>>> from pathlib import Path
>>> d = Path(tempfile.mkdtemp())
>>> out = check_outputs([d / "new" / "model.pt"], force=False, suffixes=(".pt",), what="a model file")
>>> out.new_folders == (d / "new",)
True
>>> (d / "m.pt").write_text("an earlier model")
16
>>> check_outputs([d / "m.pt"], force=False)  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
ipcverify.errors.InvalidInputError: --out .../m.pt exists; pass --force to replace it, or choose another path
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import click

from ipcverify.cli.app import console
from ipcverify.errors import InvalidInputError

__all__ = ["MODEL_SUFFIXES", "Outputs", "check_model_output", "check_outputs", "force_option"]

#: The extension of a model file (a ``torch.save`` archive).
MODEL_SUFFIXES = (".pt",)

F = TypeVar("F", bound=Callable[..., Any])


def force_option(f: F) -> F:
    """The ``--force`` flag of a command that writes files: replace outputs that exist."""
    return click.option(
        "--force",
        is_flag=True,
        help="Replace output files that exist (atomically). Without it, an existing output is refused.",
    )(f)


@dataclass(frozen=True)
class Outputs:
    """The files a command is about to write, checked by :func:`check_outputs`.

    Attributes
    ----------
    files : tuple of Path
        The files.
    new_folders : tuple of Path
        The folders they go into that do not exist yet (the writer creates them).
    """

    files: tuple[Path, ...]
    new_folders: tuple[Path, ...]

    def announce(self) -> None:
        """Say which output folders were created (call it once the files are written)."""
        for folder in self.new_folders:
            if folder.is_dir():
                console.print(f"created the folder {folder}", markup=False, highlight=False, soft_wrap=True)


def _either(words: tuple[str, ...]) -> str:
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


def _missing_folders(files: Iterable[Path]) -> tuple[Path, ...]:
    folders: list[Path] = []
    for f in files:
        if not f.parent.exists() and f.parent not in folders:
            folders.append(f.parent)
    return tuple(folders)


def check_outputs(
    files: Iterable[str | os.PathLike[str]],
    *,
    force: bool,
    option: str = "--out",
    folder: str | os.PathLike[str] | None = None,
    suffixes: tuple[str, ...] = (),
    what: str = "",
    inputs: Mapping[str, str | os.PathLike[str] | None] | None = None,
) -> Outputs:
    """Check the files a command is about to write (see the module docstring); return them.

    Parameters
    ----------
    files : iterable of path-like
        Every file the command writes.
    force : bool
        The command's ``--force``: files that exist are to be replaced.
    option : str
        The option that names the output (``"--out"``, ``"--onnx"``), for the messages.
    folder : path-like, optional
        The folder ``option`` names, for a command that writes several files into it.
    suffixes : tuple of str
        The extensions an output file may have (lower case; empty: any). Not for ``folder``.
    what : str
        What the file holds (``"a model file"``), for the extension's message.
    inputs : mapping of str to path-like or None, optional
        The command's input files by the name the user knows them by; an output may not be one.

    Raises
    ------
    InvalidInputError
        For an extension that does not fit, an output that is an input, or outputs that exist
        (without ``force``).
    """
    from ipcverify.data._files import refuse_overwriting_input

    paths = tuple(Path(f) for f in files)
    for p in paths:  # first: the worst mistake, writing over an input
        refuse_overwriting_input(p, inputs or {}, option=option)
    if suffixes:
        for p in paths:
            if p.suffix.lower() not in suffixes:
                kind = f" ({what})" if what else ""
                raise InvalidInputError(f"{option} must end in {_either(suffixes)}{kind}; got {p.name}")
    existing = [p for p in paths if p.exists() or p.is_symlink()]
    if not existing or force:
        return Outputs(paths, _missing_folders(paths))
    them = "them" if len(existing) > 1 else "it"
    names = [p.name for p in existing]
    listed = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    if folder is not None:
        raise InvalidInputError(
            f"{option} {folder} already holds {listed}; pass --force to replace {them}, or choose another "
            "folder"
        )
    head = f"{option} {paths[0]}"
    if existing != [paths[0]]:  # also, or only, a file written beside it (a manifest)
        head += f": {listed} exist{'' if len(names) > 1 else 's'}"
    else:
        head += " exists"
    raise InvalidInputError(f"{head}; pass --force to replace {them}, or choose another path")


def check_model_output(
    out: Path, *, force: bool, inputs: Mapping[str, str | os.PathLike[str] | None]
) -> Outputs:
    """:func:`check_outputs` for the model file of ``train`` and ``calibrate`` (``--out``, ``.pt``).

    Parameters
    ----------
    out : Path
        The model file.
    force : bool
        The command's ``--force``.
    inputs : mapping of str to path-like or None
        The command's input files.
    """
    return check_outputs([out], force=force, suffixes=MODEL_SUFFIXES, what="a model file", inputs=inputs)
