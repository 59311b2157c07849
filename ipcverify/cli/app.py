"""The click group shared by every command module, and the exit-status contract.

Command modules register thin wrappers over library functions with
``@app.command(...)``; they parse arguments, call one library function and
print its result. No logic lives here.

Exit status (every command, ``docs/cli.md``):

* 0 -- success (``certify``: CERTIFIED, or any status but CONTRADICTED);
* 1 -- a verdict against the model: ``certify`` CONTRADICTED, a ``monitor`` ALARM, a
  ``check-certificate`` failure;
* 2 -- a user error: bad option, missing or unreadable file, bad data, out of memory; one ``error:`` line;
* 3 -- an internal error (a bug): one ``error:`` line, and the traceback with ``--debug``;
* 130 -- interrupted (Ctrl-C).
"""

from __future__ import annotations

import sys
import traceback
import warnings
from pathlib import Path
from typing import Any, NoReturn, TextIO

import click
from click.core import ParameterSource
from rich.console import Console

from ipcverify._wording._audience import Audience, speaking
from ipcverify.errors import Hint, InvalidInputError

__all__ = [
    "app",
    "choice_option",
    "given",
    "out_dir_option",
    "console",
    "err_console",
    "run_group",
    "EXIT_VERDICT",
    "EXIT_USER",
    "EXIT_INTERNAL",
    "EXISTING_FILE",
    "OUTPUT_FILE",
]

#: A verdict against the model (CONTRADICTED, ALARM, a failed re-check).
EXIT_VERDICT = 1
#: A user error (the ``error:`` line says what to fix).
EXIT_USER = 2
#: An internal error (a bug in ipcverify or a library it calls).
EXIT_INTERNAL = 3
EXIT_INTERRUPTED = 130

#: The parameter type of an input file: it must exist and not be a folder (a Path is passed on).
EXISTING_FILE = click.Path(exists=True, dir_okay=False, path_type=Path)
#: The parameter type of a file the command writes: not a folder (a Path is passed on).
OUTPUT_FILE = click.Path(dir_okay=False, path_type=Path)

_DEBUG = [False]  # set by the global --debug option of the running command line
_HINTS: list[str] = []  # the running command's hints, printed when it ends


class CliGroup(click.Group):
    """A click group whose commands speak CLI: library messages name flags, not parameters.

    Every run (:func:`run_group`, or click's test runner calling :meth:`main`) happens inside
    :func:`ipcverify._wording._audience.speaking` for the command line, and the audience is restored after.
    """

    def main(self, *args: Any, **kwargs: Any) -> Any:  # noqa: D102 - as click.Group.main
        with speaking(Audience.CLI):
            return super().main(*args, **kwargs)


@click.group(
    cls=CliGroup,
    name="ipcverify",
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)
@click.version_option(package_name="ipcverify")
def app() -> None:
    """Learn and certify inverse perception contracts (IPCs) for perception modules.

    Exit status: 0 success (certify: not CONTRADICTED), 1 CONTRADICTED or an alarm, 2 a user
    error, 3 an internal error (rerun with --debug for its traceback).
    """


console = Console()
err_console = Console(stderr=True)


def choice_option(*param_decls: str, choices: list[str], default: str, help: str) -> Any:
    """A ``click.option`` taking one of ``choices``, with its default shown in ``--help``.

    Parameters
    ----------
    *param_decls : str
        The option's names (``"--mode"``), as for ``click.option``.
    choices : list of str
        The values accepted.
    default : str
        The value when the option is not given.
    help : str
        The option's help text.

    Examples
    --------
    >>> @click.command()
    ... @choice_option("--mode", choices=["a", "b"], default="a", help="The mode.")
    ... def cmd(mode: str) -> None:
    ...     click.echo(mode)
    >>> from click.testing import CliRunner
    >>> CliRunner().invoke(cmd, ["--mode", "b"]).output.strip()
    'b'
    """
    return click.option(
        *param_decls, type=click.Choice(choices), default=default, show_default=True, help=help
    )


def given(name: str) -> bool:
    """Whether the running command's option ``name`` was set on the command line (not left at its default).

    Parameters
    ----------
    name : str
        The option's parameter name (``"bins"`` for ``--bins``).

    Examples
    --------
    >>> @click.command()
    ... @click.option("--bins", default=10)
    ... def cmd(bins: int) -> None:
    ...     click.echo(f"{bins} {given('bins')}")
    >>> from click.testing import CliRunner
    >>> CliRunner().invoke(cmd, []).output.strip(), CliRunner().invoke(cmd, ["--bins", "10"]).output.strip()
    ('10 False', '10 True')
    """
    source = click.get_current_context().get_parameter_source(name)
    return source is not None and source not in (ParameterSource.DEFAULT, ParameterSource.DEFAULT_MAP)


def _set_debug(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    _DEBUG[0] = bool(value)


def _debug_option() -> click.Option:
    return click.Option(
        ["--debug"],
        is_flag=True,
        expose_value=False,
        is_eager=True,
        callback=_set_debug,
        help="On an error, print the full traceback as well (for bug reports).",
    )


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    if issubclass(category, Hint):  # advice: after the command's output, or its error
        _HINTS.append(f"hint: {_one_line(str(message))}")
        return
    err_console.print(f"warning: {_one_line(str(message))}", markup=False, highlight=False, soft_wrap=True)


def _print_hints() -> None:
    while _HINTS:
        err_console.print(_HINTS.pop(0), markup=False, highlight=False, soft_wrap=True)


def run_group(group: click.Group, argv: list[str] | None, prog_name: str) -> NoReturn:
    """Run a click group as a program and exit with the status contract of this module.

    Shared by ``ipcverify`` and ``python -m case_studies.quad_landing``. A user error -- an
    :class:`~ipcverify.errors.InvalidInputError`, a usage error (bad option or value), a file
    that is missing, a directory, unreadable or unwritable -- prints one ``error:`` line on
    stderr and exits with 2; so does running out of memory (a ``MemoryError``: the input or an option
    asks for more than the machine has). Anything else is a bug: one ``error:`` line naming it, exit 3,
    and the traceback only with the global ``--debug`` flag. Python warnings are printed as one
    ``warning:`` line each, when they are raised; hints (:class:`~ipcverify.errors.Hint`) as one
    ``hint:`` line each when the command ends -- after its output, or after its ``error:`` line.
    Ctrl-C exits 130.
    """
    if not any(p.name == "debug" for p in group.params):
        group.params.append(_debug_option())
    _DEBUG[0] = False
    _HINTS.clear()
    with warnings.catch_warnings():  # the filters stay as they are; only the display changes
        warnings.showwarning = _show_warning
        try:
            rc = _main(group, argv, prog_name)
        finally:  # also after an error line, or a verdict's sys.exit inside the command
            _print_hints()
    sys.exit(rc)


def _main(group: click.Group, argv: list[str] | None, prog_name: str) -> int:
    """Run the group; a user error or a bug prints its one line and exits (see :func:`run_group`)."""
    try:
        rc: Any = group.main(args=argv, prog_name=prog_name, standalone_mode=False)
    except InvalidInputError as exc:
        _fail(str(exc), EXIT_USER, exc)
    except click.exceptions.NoArgsIsHelpError as exc:  # the bare program name: its help, as --help does
        click.echo(exc.ctx.get_help() if exc.ctx is not None else exc.format_message())
        sys.exit(0)
    except click.UsageError as exc:
        _fail(exc.format_message(), EXIT_USER, exc)
    except click.ClickException as exc:  # FileError, BadParameter outside parsing, ...
        _fail(exc.format_message(), EXIT_USER, exc)
    except click.exceptions.Abort as exc:
        _fail("interrupted", EXIT_INTERRUPTED, exc)
    except OSError as exc:
        if exc.filename is None:
            _fail(_internal(exc), EXIT_INTERNAL, exc)
        _fail(_os_message(exc), EXIT_USER, exc)
    except MemoryError as exc:  # the input or an option asks for more than the machine has
        _fail(_memory_message(exc), EXIT_USER, exc)
    except Exception as exc:  # noqa: BLE001 -- the last resort of the exit-status contract
        _fail(_internal(exc), EXIT_INTERNAL, exc)
    return rc if isinstance(rc, int) else 0


def _os_message(exc: OSError) -> str:
    name = exc.filename if exc.filename2 is None else f"{exc.filename} -> {exc.filename2}"
    if isinstance(exc, FileNotFoundError):
        return f"no such file: {name}"
    if isinstance(exc, IsADirectoryError):
        return f"{name} is a directory; give a file"
    if isinstance(exc, NotADirectoryError):
        return f"{name}: a part of this path is a file, not a directory"
    if isinstance(exc, FileExistsError):
        return f"{name} exists and is not a directory; choose another output path"
    if isinstance(exc, PermissionError):
        return f"permission denied: {name} (choose a path you can read and write)"
    return f"{name}: {exc.strerror or exc}"


def _memory_message(exc: MemoryError) -> str:
    what = f" ({exc})" if str(exc) else ""
    return (
        f"out of memory{what}: the data or an option (a sample count, --hidden, --batch-size, --bins, "
        "--stride) asks for more memory than this machine has; use smaller inputs or settings"
    )


def _internal(exc: BaseException) -> str:
    return (
        f"internal error ({type(exc).__name__}: {exc}); this is a bug in ipcverify -- please report it, "
        "with the output of the same command run with --debug (e.g. ipcverify --debug COMMAND ...)"
    )


def _fail(message: str, code: int, exc: BaseException) -> NoReturn:
    if _DEBUG[0]:
        traceback.print_exception(exc, file=sys.stderr)
    err_console.print(f"error: {_one_line(message)}", markup=False, highlight=False, soft_wrap=True)
    sys.exit(code)


def out_dir_option(default: str, help: str) -> Any:
    """The ``--out`` option of a command that writes a directory of results.

    Parameters
    ----------
    default : str
        The directory when ``--out`` is not given (shown in ``--help``).
    help : str
        The option's help text.
    """
    return click.option(
        "--out",
        type=click.Path(file_okay=False, path_type=Path),
        default=Path(default),
        show_default=True,
        help=help,
    )
