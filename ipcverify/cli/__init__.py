"""Command-line interface: ``ipcverify <command>``.

Each command module registers thin wrappers over library functions on the shared
:data:`app`. :func:`main` turns user errors into a one-line message and exit status 2.
"""

from __future__ import annotations

from ipcverify.cli import certify as _certify  # noqa: F401  (registers commands)
from ipcverify.cli import containment as _containment  # noqa: F401
from ipcverify.cli import core as _core  # noqa: F401
from ipcverify.cli import data as _data  # noqa: F401
from ipcverify.cli import export as _export  # noqa: F401
from ipcverify.cli import ingest as _ingest  # noqa: F401
from ipcverify.cli import plan as _plan  # noqa: F401
from ipcverify.cli.app import app, run_group

__all__ = ["app", "main"]


def main(argv: list[str] | None = None) -> None:
    """Run the CLI; user errors exit with status 2 and a single line on stderr.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: ``sys.argv[1:]``).
    """
    run_group(app, argv, "ipcverify")
