"""The click group shared by every command module.

Command modules register thin wrappers over library functions with
``@app.command(...)``; they parse arguments, call one library function and
print its result. No logic lives here.
"""

from __future__ import annotations

import sys

import click
from rich.console import Console

from ipcverify.errors import InvalidInputError

__all__ = ["app", "console", "err_console", "run_group"]


@click.group(
    name="ipcverify",
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)
@click.version_option(package_name="ipcverify")
def app() -> None:
    """Learn and certify inverse perception contracts (IPCs) for perception modules."""


console = Console()
err_console = Console(stderr=True)


def run_group(group: click.Group, argv: list[str] | None, prog_name: str) -> None:
    """Run a click group as a program and exit; user errors exit 2 with one ``error:`` line.

    Shared by ``ipcverify`` and ``python -m case_studies.quad_landing``: an
    :class:`~ipcverify.errors.InvalidInputError`, a usage error (bad option or value) or a
    missing file prints a single line on stderr and exits with status 2; Ctrl-C exits 1.
    """
    try:
        rc = group.main(args=argv, prog_name=prog_name, standalone_mode=False)
    except InvalidInputError as exc:
        _fail(str(exc), 2)
    except click.UsageError as exc:
        _fail(exc.format_message(), 2)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Abort:
        err_console.print("aborted", markup=False)
        sys.exit(1)
    except FileNotFoundError as exc:
        _fail(f"no such file: {exc.filename}", 2)
    sys.exit(rc if isinstance(rc, int) else 0)


def _fail(message: str, code: int) -> None:
    err_console.print(f"error: {message}", markup=False, highlight=False, soft_wrap=True)
    sys.exit(code)
