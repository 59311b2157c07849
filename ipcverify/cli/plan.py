"""CLI command ``plan``: what a number of runs can certify, and how many runs a target needs.

A thin wrapper over :func:`ipcverify.calibration._run_plan.plan_runs`; with a data file it counts
the file's runs first. The library is imported inside the command, so that ``--help`` stays fast.
"""

from __future__ import annotations

import json
from pathlib import Path

import click
from rich.table import Table

from ipcverify.cli.app import app, choice_option, console
from ipcverify.errors import InvalidInputError

__all__: list[str] = []


@app.command("plan")
@click.argument("data", type=click.Path(exists=True, dir_okay=False, path_type=Path), required=False)
@click.option(
    "--group-column", default=None, help="The column of DATA that names the runs [its one run column]."
)
@click.option(
    "--runs", "n_runs", type=int, default=None, help="The number of independent runs (instead of DATA)."
)
@click.option("--delta", type=float, required=True, help="Confidence parameter, e.g. 0.01.")
@click.option("--epsilon", type=float, default=None, help="A target: the share of a run's rows outside.")
@click.option("--gamma", type=float, default=None, help="A target share of runs above epsilon [epsilon].")
@choice_option("--mode", choices=["pac", "marginal"], default="pac", help="The claims' mode.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a table.")
def plan_cmd(
    data: Path | None,
    group_column: str | None,
    n_runs: int | None,
    delta: float,
    epsilon: float | None,
    gamma: float | None,
    mode: str,
    as_json: bool,
) -> None:
    """What DATA's runs (or --runs G runs) can certify at --delta, and the runs a target needs.

    When the runs (flights, drives) of a log are its independent units, no distribution-free claim
    about a new run goes below 1 - delta^(1/G) from G runs, however many rows each holds. For each
    claim about runs this prints the smallest rate G runs can certify and, with --epsilon, the runs
    that target needs (with no violation at all; tight sets need more).
    """
    from ipcverify.calibration._run_plan import plan_runs
    from ipcverify.data._checks import group_like_counts
    from ipcverify.data._dataset import load_dataset
    from ipcverify.data._split import group_codes

    if (data is None) == (n_runs is None):
        raise InvalidInputError("plan needs either a data file or --runs G, not both")
    source = f"{n_runs} runs"
    if data is not None:
        ds = load_dataset(data)
        if group_column is None:
            runs = group_like_counts(ds)
            if len(runs) != 1:
                found = ", ".join(runs) if runs else "none"
                raise InvalidInputError(
                    f"{data}: name the column of its runs with --group-column (columns that could: {found})"
                )
            group_column = next(iter(runs))
        n_runs = len(group_codes(ds.column(group_column), f"{data.name}: group column {group_column!r}")[1])
        source = f"{data.name}: {n_runs} runs of {group_column!r}"
    plan = plan_runs(n_runs, delta, epsilon=epsilon, gamma=gamma, mode=mode)  # type: ignore[arg-type]
    if as_json:
        click.echo(json.dumps({"source": source, **plan.to_dict()}))
        return
    table = Table(title=f"{source}, delta = {delta:g} ({mode})")
    table.add_column("claim about a new run")
    table.add_column("bounds")
    table.add_column("smallest certifiable", justify="right")
    if epsilon is not None:
        table.add_column(
            f"runs needed for {epsilon:g}" + ("" if gamma is None else f" (gamma {gamma:g})"), justify="right"
        )
    for c in plan.claims:
        row = [c.guarantee, c.rate.split(":")[0], "-" if c.smallest is None else f"{c.smallest:g}"]
        if epsilon is not None:
            row.append(str(c.runs_needed))
        table.add_row(*row)
    console.print(table)
    console.print(plan.sentence(), soft_wrap=True, markup=False)
