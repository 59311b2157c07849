"""Data CLI command: ``split``, a log into train, calibration and test files.

A thin wrapper over :func:`ipcverify.data._split_files.split_file`; the library is imported
inside the command, so that ``ipcverify --help`` does not load pandas.
"""

from __future__ import annotations

from pathlib import Path

import click
from rich.table import Table

from ipcverify.cli.app import EXISTING_FILE, app, choice_option, console, err_console, out_dir_option
from ipcverify.cli.outputs import check_outputs, force_option
from ipcverify.errors import InvalidInputError

__all__ = ["parse_fractions"]


def parse_fractions(text: str) -> tuple[float, float, float]:
    """Parse ``"0.6,0.2,0.2"`` into three shares (their sum is checked by the split).

    Examples
    --------
    >>> parse_fractions("0.5, 0.25, 0.25")
    (0.5, 0.25, 0.25)
    """
    try:
        values = tuple(float(t) for t in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3:
        raise InvalidInputError(
            f"--fractions must be three comma-separated shares of train, calibration and test, "
            f"such as 0.6,0.2,0.2; got {text!r}"
        )
    return values[0], values[1], values[2]


def _row_split_hint(other_columns: tuple[str, ...]) -> str:
    """The ways to keep correlated rows together that the log's other columns allow, for the row-split hint.

    Examples
    --------
    >>> for part in _row_split_hint(("run", "t")).split("; ")[1:]:
    ...     print(part)
    if run names runs or flights, split by it with --by
    or keep stretches of time whole with --block SECONDS (blocks of t)
    >>> _row_split_hint(("t",))
    '; keep stretches of time whole with --block SECONDS (blocks of t)'
    """
    from ipcverify.data._checks import TIME_NAMES

    times = [c for c in other_columns if c.strip().lower() in TIME_NAMES]
    others = [c for c in other_columns if c not in times]
    hint = ""
    if others:
        which = ("one of " if len(others) > 1 else "") + ", ".join(others)
        hint += f"; if {which} names runs or flights, split by it with --by"
    if times:
        hint += "; or" if others else ";"
        hint += f" keep stretches of time whole with --block SECONDS (blocks of {times[0]})"
    return hint


@app.command("split")
@click.argument("data", type=EXISTING_FILE)
@out_dir_option("split", help="Directory for train, calibration and test files and split.json.")
@force_option
@click.option(
    "--by",
    "group_column",
    default=None,
    help="Column naming the run, flight or sequence (or several, comma-separated, that name it "
    "together, e.g. method,run): whole groups go to one part each (rows of one run are "
    "correlated). Default: rows are split at random.",
)
@click.option(
    "--block",
    type=float,
    default=None,
    metavar="SECONDS",
    help="Keep contiguous stretches of time whole: blocks of this many seconds of the time column "
    "are the groups (within each --by group, counted from its first time; without --by, the same "
    "times of every run are one block). For logs of one or a few long runs.",
)
@click.option(
    "--time-column",
    default=None,
    help="Column of times in seconds that --block cuts (default: t, time, timestamp or stamp).",
)
@click.option(
    "--fractions",
    default="0.6,0.2,0.2",
    show_default=True,
    help="Shares of train, calibration and test (of groups with --by); a share may be 0.",
)
@click.option(
    "--name-groups",
    "group_name",
    default=None,
    help="Add a column of this name to the parts holding each row's group (the --by values and "
    "the --block number joined by ':'), for calibrate and certify --group-column.",
)
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the random draw.")
@choice_option(
    "--format",
    "fmt",
    choices=["same", "csv", "parquet", "npz"],
    default="same",
    help="Format of the parts: the input's, or csv, parquet or npz (npz keeps only x, y, yhat).",
)
def split_cmd(
    data: Path,
    out: Path,
    force: bool,
    group_column: str | None,
    group_name: str | None,
    block: float | None,
    time_column: str | None,
    fractions: str,
    seed: int,
    fmt: str,
) -> None:
    """Split DATA into train, calibration and test files in --out, and record the split.

    Calibrate and certify on parts that training never saw. Use --by with the column that
    names runs or flights: rows of one run are correlated, and a row split puts neighbours of
    a training row into the test part. A log of one or a few long runs splits into time
    blocks with --block. --out/split.json names the source and every part by SHA-256.
    """
    from ipcverify.data._split_files import split_file, split_outputs

    suffix = None if fmt == "same" else f".{fmt}"
    outputs = check_outputs(split_outputs(data, out, suffix), force=force, folder=out, inputs={"DATA": data})
    columns = None if group_column is None else [c.strip() for c in group_column.split(",") if c.strip()]
    result = split_file(
        data, out, parse_fractions(fractions), seed, columns, suffix, group_name, block, time_column
    )
    units = list(result.group_columns)
    if result.block_seconds is not None:
        units.append(f"{result.block_seconds:g} s block")
    by_groups = bool(units)
    table = Table(title=f"{data} split (seed {result.seed})")
    table.add_column("part")
    table.add_column("rows", justify="right")
    if by_groups:
        table.add_column(f"{'+'.join(units)} groups", justify="right")
    table.add_column("file")
    for p in result.parts:
        cells = [p.name, f"{p.rows:,}"] + ([str(p.groups)] if by_groups else [])
        table.add_row(*cells, "-" if p.path is None else str(p.path))
    console.print(table)
    if not by_groups:
        hint = _row_split_hint(result.other_columns)
        err_console.print(f"hint: rows were split at random, which assumes independent rows{hint}")
    if result.dropped_columns:
        dropped = ", ".join(result.dropped_columns)
        err_console.print(f"warning: the npz parts hold x, y and yhat only; not written: {dropped}")
    console.print(f"record: {result.record}", markup=False)
    outputs.announce()
