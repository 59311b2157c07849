"""Command-line interface: ``ipcverify <command>``.

Each command module registers thin wrappers over library functions on the shared
:data:`app`. :func:`main` turns user errors into a one-line message and exit status 2.
"""

from __future__ import annotations

import sys

import click

from ipcverify.cli import certify as _certify  # noqa: F401  (registers commands)
from ipcverify.cli import containment as _containment  # noqa: F401
from ipcverify.cli import core as _core  # noqa: F401
from ipcverify.cli import export as _export  # noqa: F401
from ipcverify.cli.app import app, err_console
from ipcverify.errors import InvalidInputError

__all__ = ["app", "main"]


def main(argv: list[str] | None = None) -> None:
    """Run the CLI; user errors exit with status 2 and a single line on stderr."""
    try:
        rc = app.main(args=argv, prog_name="ipcverify", standalone_mode=False)
    except InvalidInputError as exc:
        err_console.print(f"error: {exc}", markup=False, highlight=False, soft_wrap=True)
        sys.exit(2)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Abort:
        err_console.print("aborted", markup=False)
        sys.exit(1)
    except FileNotFoundError as exc:
        err_console.print(f"error: no such file: {exc.filename}", markup=False, soft_wrap=True)
        sys.exit(2)
    sys.exit(rc if isinstance(rc, int) else 0)
