"""The click group shared by every command module.

Command modules register thin wrappers over library functions with
``@app.command(...)``; they parse arguments, call one library function and
print its result. No logic lives here.
"""

from __future__ import annotations

import click
from rich.console import Console

__all__ = ["app", "console", "err_console"]


@click.group(
    name="ipcverify",
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)
@click.version_option(package_name="ipcverify")
def app() -> None:
    """Learn and certify inverse perception contracts (IPCs) for perception modules."""


console = Console()
err_console = Console(stderr=True)
