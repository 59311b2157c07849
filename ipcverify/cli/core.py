"""Core CLI commands: ``train``, ``evaluate``, ``predict`` and ``demo``.

Each command parses its arguments, calls one library function and prints the
result; nothing else happens here. The library is imported inside each command, so that
``ipcverify --help`` does not load torch, Numba or pandas (docs/develop.md).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click
import numpy as np
from rich.table import Table

from ipcverify.cli.app import (
    EXISTING_FILE,
    EXIT_VERDICT,
    OUTPUT_FILE,
    app,
    choice_option,
    console,
    err_console,
    given,
    out_dir_option,
)
from ipcverify.cli.outputs import check_model_output, check_outputs, force_option
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import DEFAULT_RECIPE, RECIPES
from ipcverify.training._threads import DEFAULT_THREADS, THREADS_VARIABLE, check_threads

if TYPE_CHECKING:
    from ipcverify.certification._evaluation import Evaluation
    from ipcverify.guard._domain_report import DomainReport

__all__ = ["parse_hidden"]


def parse_hidden(text: str) -> tuple[int, ...]:
    """Parse ``"64,128"`` into ``(64, 128)``.

    Examples
    --------
    >>> parse_hidden("64, 128")
    (64, 128)
    """
    try:
        sizes = tuple(int(t) for t in text.split(",") if t.strip())
    except ValueError:
        raise InvalidInputError(
            f"--hidden must be comma-separated positive integers such as 64,128; got {text!r}"
        ) from None
    if not sizes or any(s < 1 for s in sizes):
        raise InvalidInputError(
            f"--hidden must be comma-separated positive integers such as 64,128; got {text!r}"
        )
    return sizes


def _columns(text: str | None) -> list[str] | None:
    return [c.strip() for c in text.split(",") if c.strip()] if text else None


def _print_evaluation(ev: Evaluation, title: str) -> None:
    table = Table(title=title, show_header=False)
    table.add_row("samples", str(ev.n))
    table.add_row("violations (y outside its set)", f"{ev.violations} ({100 * ev.violation_rate:.2f} %)")
    table.add_row("log-volume mean / median", f"{ev.log_volume_mean:.3f} / {ev.log_volume_median:.3f}")
    table.add_row("mean extent per dim", ", ".join(f"{e:.4g}" for e in ev.mean_extent))
    table.add_row("sets", "calibrated" if ev.calibrated else "raw network (uncalibrated)")
    d = ev.domain
    if d is None:
        table.add_row("domain of validity", "none in this model (calibrate it to fit one)")
    else:
        inside = d.n - d.outside
        table.add_row("outside the domain of validity", f"{d.outside} ({100 * d.outside_fraction:.2f} %)")
        table.add_row(
            "violations inside / outside",
            f"{d.violations_inside} of {inside} / {d.violations_outside} of {d.outside}",
        )
    console.print(table)
    if ev.by_run is not None:
        r = ev.by_run
        rt = Table(title=f"per run of {r.column} (the unit of a claim about runs)", show_header=False)
        rt.add_row("runs", f"{r.n_runs} ({r.runs_with_violation} with some row outside)")
        rt.add_row(
            "mean share of a run's rows outside",
            f"{100 * r.share.empirical_rate:.2f} % (bounds {100 * r.share.lower_bound:.2f} to "
            f"{100 * r.share.upper_bound:.2f} % at confidence {1 - r.share.delta:g} each; largest run "
            f"{100 * r.max_share:.1f} %)",
        )
        if r.outside_domain is not None:
            rt.add_row("mean share outside the domain", f"{100 * r.outside_domain:.2f} %")
        console.print(rt)
    if ev.by_bin is not None:
        bt = Table(title=f"violation rate by {ev.by_bin.column}")
        bt.add_column("bin")
        bt.add_column("n", justify="right")
        bt.add_column("violations", justify="right")
        bt.add_column("rate", justify="right")
        for name, c, v in zip(ev.by_bin.bin_names(), ev.by_bin.counts, ev.by_bin.violations, strict=True):
            bt.add_row(name, str(c), str(v), f"{100 * v / c:.2f} %" if c else "-")
        console.print(bt)


def _warn_domain(report: DomainReport | None) -> None:
    """A shifted batch (far more queries outside the domain than false alarms explain) is a warning."""
    if report is not None and report.well_above_flag_rate:
        err_console.print(f"[bold yellow]warning:[/] {report.sentence()}", soft_wrap=True, highlight=False)


def _given(**values: object) -> dict[str, object]:
    """The options the user set (None means: take the recipe's value)."""
    return {k: v for k, v in values.items() if v is not None}


@app.command("train")
@click.argument("data", type=EXISTING_FILE)
@click.option("--out", type=OUTPUT_FILE, required=True, help="Model file (.pt).")
@force_option
@choice_option(
    "--recipe",
    choices=list(RECIPES),
    default=DEFAULT_RECIPE,
    help="Architecture and training settings by name: tight (ensemble of low-rank heads, likelihood), "
    "v1 (ipcverify's earlier default), paper (the paper's head and loss). The options below override it.",
)
@click.option("--hidden", default=None, help="Hidden layer widths, e.g. 64,64 [recipe's].")
@click.option("--epochs", default=None, type=int, help="Epochs (at most, with early stopping) [recipe's].")
@click.option("--lr", default=None, type=float, help="Adam learning rate [recipe's].")
@click.option("--alpha", default=None, type=float, help="Hinge margin [recipe's].")
@click.option("--lam", default=None, type=float, help="Volume penalty weight [recipe's].")
@click.option("--batch-size", default=None, type=int, help="Mini-batch size [recipe's].")
@click.option(
    "--loss",
    type=click.Choice(["hinge", "likelihood"]),
    default=None,
    help="Training objective: the paper's hinge + volume loss, or Gaussian likelihood [recipe's].",
)
@click.option(
    "--center-warm-start/--no-center-warm-start",
    default=None,
    help="Initialise the centre head by least squares before training (paper's heads only) [off].",
)
@click.option("--param", type=click.Choice(["lowrank", "cholesky", "full"]), default=None, help="Shape head.")
@click.option("--center", type=click.Choice(["offset", "raw"]), default=None, help="Centre head.")
@click.option("--members", default=None, type=int, help="Ensemble size (low-rank head) [recipe's].")
@click.option(
    "--linear-center/--no-linear-center",
    default=None,
    help="Closed-form linear centre stage (low-rank head) [recipe's].",
)
@click.option(
    "--schedule", type=click.Choice(["cosine", "constant"]), default=None, help="Step size [recipe's]."
)
@click.option("--seed", default=0, show_default=True, type=int)
@click.option("--val-fraction", default=None, type=float, help="Hold out for validation [recipe's].")
@click.option(
    "--group-column",
    default=None,
    help="With --recipe paper: hold out whole groups of this column (flights, runs) when choosing "
    "alpha, lambda and the batch size.",
)
@click.option(
    "--patience", default=None, type=int, help="Early stopping patience (needs --val-fraction) [recipe's]."
)
@click.option("--x-columns", default=None, help="Comma-separated state columns (default x_0, x_1, ...).")
@click.option("--y-columns", default=None, help="Comma-separated truth columns (default y_0, ...).")
@click.option("--yhat-columns", default=None, help="Comma-separated estimate columns (default yhat_0, ...).")
@click.option(
    "--threads",
    default=None,
    type=int,
    help=f"torch threads to train on [{THREADS_VARIABLE} if set, else {DEFAULT_THREADS}: more threads "
    "do not train these small networks faster, and beside busy processes they are much slower].",
)
def train_cmd(
    data: Path,
    out: Path,
    force: bool,
    recipe: str,
    hidden: str | None,
    epochs: int | None,
    lr: float | None,
    alpha: float | None,
    lam: float | None,
    batch_size: int | None,
    loss: str | None,
    center_warm_start: bool | None,
    param: str | None,
    center: str | None,
    members: int | None,
    linear_center: bool | None,
    schedule: str | None,
    seed: int,
    val_fraction: float | None,
    group_column: str | None,
    patience: int | None,
    x_columns: str | None,
    y_columns: str | None,
    yhat_columns: str | None,
    threads: int | None,
) -> None:
    """Train an IPC on DATA (CSV, Parquet or NPZ) and save it to --out.

    The default recipe "tight" gives the smallest calibrated sets; "v1" is ipcverify's earlier
    default; "paper" is the paper's network and loss (12 outputs, hinge, Adam 1e-3, 20 epochs),
    whose unstated alpha, lambda and batch size are chosen on held-out training rows unless
    --alpha, --lam or --batch-size is given. Every recipe stores the statistics Theorem 1
    needs in the model file.
    """
    from ipcverify.data._dataset import load_dataset
    from ipcverify.io._modelio import save_model
    from ipcverify.network._architecture import ModelConfig
    from ipcverify.training._train import HingeSelection, TrainConfig, train

    outputs = check_model_output(out, force=force, inputs={"DATA": data})
    if threads is not None:
        check_threads(threads)  # before the data are read
    ds = load_dataset(data, _columns(x_columns), _columns(y_columns), _columns(yhat_columns))
    mc = ModelConfig.recipe(
        recipe,
        x_dim=ds.x_dim,
        y_dim=ds.y_dim,
        **_given(
            hidden=None if hidden is None else parse_hidden(hidden),
            param=param,
            center=center,
            members=members,
            linear_center=linear_center,
        ),
    )
    tc = TrainConfig.recipe(
        recipe,
        seed=seed,
        **_given(
            epochs=epochs,
            lr=lr,
            alpha=alpha,
            lam=lam,
            batch_size=batch_size,
            val_fraction=val_fraction,
            patience=patience,
            loss=loss,
            center_warm_start=center_warm_start,
            schedule=schedule,
        ),
    )
    hinge_only = [name for name, v in (("--alpha", alpha), ("--lam", lam)) if v is not None]
    if hinge_only and tc.loss != "hinge":
        which = f"--loss {tc.loss}" if loss is not None else f"recipe {recipe}'s {tc.loss} loss"
        names, them = " and ".join(hinge_only), "them" if len(hinge_only) > 1 else "it"
        raise InvalidInputError(
            f"{names} {'belong' if len(hinge_only) > 1 else 'belongs'} to the hinge loss, but this run "
            f"trains with {which} and would ignore {them}: add --loss hinge, or leave {them} out"
        )
    chosen_by_hand = alpha is not None or lam is not None or batch_size is not None
    if group_column is not None and (recipe != "paper" or chosen_by_hand):
        raise InvalidInputError(
            "--group-column only chooses the paper recipe's alpha, lambda and batch size: use it with "
            "--recipe paper and without --alpha, --lam and --batch-size"
        )
    select = HingeSelection(group_column=group_column) if recipe == "paper" and not chosen_by_hand else None
    result = train(ds, mc, tc, progress=True, select=select, threads=threads)
    save_model(result.model, out)
    last = result.history[-1]
    what = f"{mc.members} networks" if mc.members > 1 else "1 network"
    console.print(
        f"trained {what} ({mc.param} head, recipe {recipe}, p = {result.model.n_parameters:,} parameters) on "
        f"{len(ds)} samples for {len(result.history)} epochs: final training loss {last['train_loss']:.4f} "
        f"-> {out}; calibrate it before use",
        markup=False,
    )
    outputs.announce()
    if "selection" in result.model.metadata:
        console.print(f"chosen on held-out training rows: {result.model.metadata['selection']['summary']}",
                      markup=False)  # fmt: skip


@app.command("evaluate")
@click.argument("model", type=EXISTING_FILE)
@click.argument("data", type=EXISTING_FILE)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of tables.")
@click.option("--bin-column", default=None, help="Report the violation rate per bin of this column.")
@click.option(
    "--bins",
    default=10,
    show_default=True,
    type=int,
    help="With --bin-column: quantile bins of a numeric column (a text column has one bin per value).",
)
@click.option(
    "--group-column",
    default=None,
    help="Count per run of this column [default: the calibration's run column, or the data's one "
    "column that names runs].",
)
def evaluate_cmd(
    model: Path, data: Path, as_json: bool, bin_column: str | None, bins: int, group_column: str | None
) -> None:
    """Empirical violation rate and set sizes of MODEL on labelled DATA (per run too, for data with runs)."""
    from ipcverify.certification._evaluation import evaluate
    from ipcverify.data._files import json_data
    from ipcverify.io._modelio import load_data_for_model, load_model

    if given("bins") and bin_column is None:
        raise InvalidInputError(
            "--bins sets the number of bins of --bin-column COL; give the column, or leave --bins out"
        )
    m = load_model(model)
    ds = load_data_for_model(data, m)
    ev = evaluate(m, ds, bin_column=bin_column, bins=bins, group_column=group_column)
    if given("bins") and ev.by_bin is not None and ev.by_bin.labels:
        raise InvalidInputError(
            f"--bins does not apply to the text column {bin_column!r} (one bin per value); leave --bins out"
        )
    if as_json:
        click.echo(json.dumps(json_data(ev.to_dict())))
    else:
        _print_evaluation(ev, f"{model.name} on {data.name}")
    _warn_domain(ev.domain)


@app.command("predict")
@click.argument("model", type=EXISTING_FILE)
@click.argument("data", type=EXISTING_FILE)
@click.option("--out", type=OUTPUT_FILE, required=True, help="Output .npz.")
@force_option
def predict_cmd(model: Path, data: Path, out: Path, force: bool) -> None:
    """Write the IPC's sets for the queries in DATA to an NPZ.

    Arrays: `center` (B, n), `shape` (B, n, n) with E_i = {y : ||shape_i (y - center_i)|| <= 1},
    `in_domain` (B,) -- the calibration certificate covers only these queries --,
    `domain_distance` (B,) and `singular` (B,). DATA needs only the state and estimate columns.
    """
    from ipcverify.contract._prediction import predict_sets, write_predictions
    from ipcverify.io._modelio import load_inputs_for_model, load_model

    outputs = check_outputs([out], force=force, suffixes=(".npz",), inputs={"MODEL": model, "DATA": data})
    m = load_model(model)
    pred = predict_sets(m, load_inputs_for_model(data, m))
    write_predictions(pred, out)
    kind = "calibrated" if pred.calibrated else "raw (uncalibrated)"
    console.print(f"wrote {len(pred.centers)} {kind} ellipsoids to {out}", markup=False)
    report = pred.domain
    if report is None:
        console.print("no domain-of-validity test in this model: every query is in_domain", markup=False)
    elif report.outside:
        target = err_console if report.well_above_flag_rate else console
        prefix = "[bold yellow]warning:[/] " if report.well_above_flag_rate else ""
        target.print(prefix + report.sentence(), soft_wrap=True, highlight=False)
    if pred.singular.any():
        console.print(
            f"{int(pred.singular.sum())} queries have a degenerate set (far outside the training data); "
            "they are marked in_domain = False",
            markup=False,
        )
    outputs.announce()


@app.command("monitor")
@click.argument("model", type=EXISTING_FILE)
@click.argument("log", type=EXISTING_FILE)
@out_dir_option("monitor", help="Directory for monitor.json and monitor.png.")
@force_option
@click.option(
    "--delta", type=float, default=None, help="False-alarm bound (default: the calibration's delta)."
)
@click.option(
    "--group-column",
    default=None,
    help="The column of LOG that names its runs: one observation per run, taken at its last row. "
    "Default: a run-level calibration's column; otherwise one observation per row.",
)
def monitor_cmd(
    model: Path, log: Path, out: Path, force: bool, delta: float | None, group_column: str | None
) -> None:
    """Replay a labelled deployment LOG (rows in time order) through the online monitor.

    An anytime-valid test of "the violation rate is at most the calibrated rate": it raises an
    alarm at the first observation where the violations so far refute the certificate, with a
    false-alarm probability of at most --delta. A run-level model is monitored one run at a time,
    with its claim as the null, and, with a domain test fitted by runs, the runs' shares outside
    the domain are tested too. Exits with status 1 on an alarm of either test.
    """
    from ipcverify.certification._report_plots import figure_to_png
    from ipcverify.contract._prediction import monitor_log
    from ipcverify.data._checks import warn_correlated_rows, warn_out_of_time_order
    from ipcverify.data._files import atomic_write, write_json
    from ipcverify.guard._monitor import plot_monitor
    from ipcverify.io._modelio import load_data_for_model, load_model

    json_path, png_path = out / "monitor.json", out / "monitor.png"
    outputs = check_outputs(
        [json_path, png_path], force=force, folder=out, inputs={"MODEL": model, "LOG": log}
    )
    m = load_model(model)
    data = load_data_for_model(log, m)
    res = monitor_log(m, data, delta=delta, group_column=group_column)
    warn_out_of_time_order(data, "the monitor replays")
    if not res.labels:
        warn_correlated_rows(data, "monitoring", "to monitor one observation per group")
    png = figure_to_png(plot_monitor(res.result, title=f"{log.name}: anytime-valid test of the certificate"))
    write_json(json_path, res)
    atomic_write(png_path, lambda f: f.write(png))
    alarm = res.alarm_index is not None or res.domain_alarm_index is not None
    target, style = (err_console, "bold red") if alarm else (console, "bold green")
    # an alarm's sentence starts with "ALARM at ..." or "DOMAIN ALARM at ..."; "No alarm ..." gets an "OK"
    sentence = res.sentence()
    head = next((h for h in ("ALARM", "DOMAIN ALARM") if sentence.startswith(h)), None)
    head, rest = (head, sentence.removeprefix(head)) if head else ("OK", " " + sentence)
    target.print(f"[{style}]{head}[/]{rest}", soft_wrap=True)
    console.print(f"wrote {json_path} and {png_path}", markup=False)
    outputs.announce()
    if alarm:
        sys.exit(EXIT_VERDICT)


@app.command("demo")
@out_dir_option("ipcverify-demo", help="Directory for the example data and model.")
@force_option
@click.option(
    "--n",
    "n_samples",
    default=5000,
    show_default=True,
    type=int,
    help="Training samples (100 to 10,000,000).",
)
@click.option("--seed", default=0, show_default=True, type=int)
def demo_cmd(out: Path, force: bool, n_samples: int, seed: int) -> None:
    """Generate synthetic lagged-perception data, train an IPC, calibrate it, evaluate it.

    The six files go into --out; a folder that already holds one of them (an earlier demo's) is
    refused unless --force is given.
    """
    from ipcverify.demo import DEMO_FILES, run_demo

    outputs = check_outputs([out / name for name in DEMO_FILES], force=force, folder=out)
    s = run_demo(out, n_train=n_samples, seed=seed, progress=True)
    table = Table(title=f"on {s.calibrated.n} fresh test samples")
    table.add_column("sets")
    table.add_column("violations", justify="right")
    table.add_column("mean log-volume", justify="right")
    rows = (
        ("trained IPC, raw (no guarantee)", s.raw.violations, s.raw.log_volume_mean),
        ("IPC calibrated (PAC)", s.calibrated.violations, s.calibrated.log_volume_mean),
        ("global Mahalanobis ellipsoid (PAC)", s.global_violations, s.global_log_volume),
    )
    for name, v, lv in rows:
        table.add_row(name, f"{v} ({100 * v / s.calibrated.n:.2f} %)", f"{lv:.3f}")
    console.print(table)
    console.print(f"guarantee: {s.guarantee}")
    console.print(
        f"the calibrated IPC's sets are {np.exp(s.global_log_volume - s.calibrated.log_volume_mean):.1f}x "
        "smaller than the global ellipsoid's (geometric mean of volumes), at the same certified level"
    )
    console.print(f"files in {out}/: {', '.join(DEMO_FILES)}", markup=False)
    outputs.announce()
