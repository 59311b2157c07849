"""CLI commands ``calibrate`` and ``certify``; registered on the shared app.

Both are thin wrappers: parse, call :func:`ipcverify.contract.calibrate` or
:func:`ipcverify.certification.certify_files`, print a short summary. The library is imported inside
each command, so that ``--help`` stays fast.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import click
from rich.table import Table

from ipcverify._wording._verdicts import NOT_RUN, held_out_remedy, theorem1_verdict
from ipcverify.cli.app import (
    EXISTING_FILE,
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
from ipcverify.network._lipschitz_ball import DEFAULT_RADIUS

if TYPE_CHECKING:
    from ipcverify.calibration._bounds import CalibrationMode
    from ipcverify.calibration._group_counts import GuaranteeKind
    from ipcverify.calibration._method import CalibrationMethod

__all__: list[str] = []

#: The files ``certify`` writes into its folder (by ``ipcverify.certification.write_certificate``).
CERTIFY_FILES = ("certificate.json", "report.html")
#: ``ipcverify.guard.DEFAULT_FLAG_RATE``, written out so that ``--help`` need not import the domain
#: test (SciPy, Numba); ``tests/ipcverify/cli/test_startup.py`` checks that the two agree.
_DOMAIN_FLAG_RATE = 0.01


def renamed_option(old: str, new: str) -> Any:
    """A hidden option under an earlier name that refuses itself, naming the option that replaced it."""

    def refuse(ctx: click.Context, param: click.Parameter, value: object) -> None:
        if value is not None:
            raise click.UsageError(
                f"{old} is now {new} (alpha names only the hinge margin of the paper's loss)"
            )

    return click.option(old, hidden=True, expose_value=False, default=None, callback=refuse)


def calibration_method(
    mode: str,
    mondrian_column: str | None,
    bins: int | None,
    group_column: str | None,
    guarantee: str | None,
    seed: int,
    unit: str | None = None,
    gamma: float | None = None,
    run_columns: tuple[str, ...] = (),
) -> CalibrationMethod | None:
    """The calibration spec that the ``calibrate`` command's options name (None: let the data decide).

    ``--mondrian-column`` (with ``--bins``) gives :class:`~ipcverify.calibration.Mondrian`,
    ``--group-column`` (with ``--guarantee`` and ``--gamma``) :class:`~ipcverify.calibration.Grouped`,
    ``--unit row`` :class:`~ipcverify.calibration.Global`, ``--unit run`` ``Grouped`` by the data's
    one run column (``run_columns``); with none of them the library chooses by the data (by runs
    when they name them). ``--mode`` and ``--seed`` go to the one chosen.

    Raises
    ------
    InvalidInputError
        If ``--bins`` comes without ``--mondrian-column``, both column options are given, the
        unit contradicts the columns, ``--unit run`` finds no single run column, or
        ``--guarantee``/``--gamma`` come without runs.
    """
    from ipcverify.calibration._global_scale import Global
    from ipcverify.calibration._grouped_spec import Grouped
    from ipcverify.calibration._mondrian import Mondrian

    if bins is not None and mondrian_column is None:
        raise InvalidInputError("bins needs a group column (CLI: --mondrian-column COL --bins K)")
    if mondrian_column is not None and group_column is not None:
        raise InvalidInputError(
            "choose one of a Mondrian column (one scale per group of an x/yhat column) and a group column "
            "(flights or runs as the exchangeable units); they cannot be combined"
        )
    if unit == "row" and group_column is not None:
        raise InvalidInputError(
            "--unit row makes a claim about rows, --group-column one about runs: give one of them"
        )
    if unit == "run" and mondrian_column is not None:
        raise InvalidInputError("--mondrian-column makes a row-level claim: use it with --unit row, not run")
    if unit == "run" and group_column is None:
        if len(run_columns) != 1:
            found = ", ".join(run_columns) if run_columns else "none"
            raise InvalidInputError(
                f"--unit run needs the column that names the runs: the data have {len(run_columns)} such "
                f"columns ({found}); name it with --group-column COL"
            )
        group_column = run_columns[0]
    kind = cast("CalibrationMode", mode)  # the specs check it
    if group_column is not None:
        return Grouped(
            column=group_column,
            guarantee=cast("GuaranteeKind", guarantee or "expected-share"),
            gamma=gamma,
            seed=seed,
            mode=kind,
        )
    if guarantee is not None or gamma is not None:
        raise InvalidInputError(
            "--guarantee and --gamma choose a claim about runs: give the runs' column with --group-column "
            "(or --unit run)"
        )
    if mondrian_column is not None:
        return Mondrian(column=mondrian_column, bins=bins, seed=seed, mode=kind)
    if unit == "row":
        return Global(mode=kind)
    if mode == "pac":
        return None  # the library chooses by the data
    if len(run_columns) == 1:  # the library's choice, in marginal mode
        return Grouped(column=run_columns[0], seed=seed, mode=kind)
    return None if run_columns else Global(mode=kind)


@app.command("calibrate")
@click.argument("model", type=EXISTING_FILE)
@click.argument("data", type=EXISTING_FILE)
@click.option("--epsilon", type=float, required=True, help="Target violation probability, e.g. 0.01.")
@click.option("--delta", type=float, required=True, help="Confidence parameter, e.g. 0.001.")
@choice_option(
    "--mode",
    choices=["pac", "marginal"],
    default="pac",
    help="pac: holds w.p. 1-delta over the calibration draw; marginal: on average (split conformal).",
)
@click.option(
    "--mondrian-column", default=None, help="Mondrian: one scale per group of this x or yhat column."
)
@click.option(
    "--bins", default=None, type=int, help="With --mondrian-column: quantile bins of a continuous column."
)
@click.option(
    "--unit",
    type=click.Choice(["row", "run"]),
    default=None,
    help="What the claim is about: runs (flights; the default when the data have one column that names "
    "them) or rows (assumes independent rows; the default when the data name no runs).",
)
@click.option(
    "--group-column",
    default=None,
    help="The column that names the runs (flights): calibrate with whole runs as the exchangeable units.",
)
@click.option(
    "--guarantee",
    type=click.Choice(["expected-share", "share-of-runs", "trajectory"]),
    default=None,
    help="A claim about runs: a new run's expected share of rows outside [default], the share of new runs "
    "with more than --epsilon of their rows outside (with --gamma), or any row outside.",
)
@click.option(
    "--gamma",
    type=float,
    default=None,
    help="With --guarantee share-of-runs: the share of new runs allowed more than --epsilon outside.",
)
@click.option(
    "--domain-flag-rate",
    type=float,
    default=None,
    help=f"The rate at which the domain-of-validity test flags in-distribution queries [default: "
    f"{_DOMAIN_FLAG_RATE:g}, or the smallest the runs allow when fitted by runs].",
)
@renamed_option("--domain-alpha", "--domain-flag-rate")
@click.option(
    "--domain-group-column",
    default=None,
    help="Fit the domain test with whole groups of this column as the units (default: --group-column).",
)
@click.option(
    "--recalibrate", is_flag=True, help="Replace an existing calibration (calibrates the raw network)."
)
@click.option(
    "--seed",
    default=0,
    show_default=True,
    type=int,
    help="Seed for the bin-edge samples (--bins), the one random row per group (--group-column) "
    "and the domain test's reference subsample of large data.",
)
@click.option("--out", type=OUTPUT_FILE, required=True, help="Calibrated model (.pt).")
@force_option
def calibrate_cmd(
    model: Path,
    data: Path,
    epsilon: float,
    delta: float,
    mode: str,
    mondrian_column: str | None,
    bins: int | None,
    unit: str | None,
    group_column: str | None,
    guarantee: str | None,
    gamma: float | None,
    domain_flag_rate: float | None,
    domain_group_column: str | None,
    recalibrate: bool,
    seed: int,
    out: Path,
    force: bool,
) -> None:
    """Calibrate MODEL on DATA and write the calibrated model to --out.

    DATA must be held-out data that was NOT used for training (nor for choosing the
    model), drawn like the data the contract will meet in deployment. The domain-of-validity
    test is fitted on its inputs and stored with the model.
    """
    from ipcverify.contract._calibrate import calibrate
    from ipcverify.data._checks import group_like_counts
    from ipcverify.guard._domain_spec import DomainSpec
    from ipcverify.io._modelio import load_data_for_model, load_model, save_model

    outputs = check_model_output(out, force=force, inputs={"MODEL": model, "DATA": data})
    domain = DomainSpec(flag_rate=domain_flag_rate, group_column=domain_group_column, seed=seed)
    m = load_model(model)
    ds = load_data_for_model(data, m)
    runs = tuple(group_like_counts(ds))
    method = calibration_method(mode, mondrian_column, bins, group_column, guarantee, seed, unit, gamma, runs)
    cal_model = calibrate(m, ds, epsilon, delta, method, domain=domain, recalibrate=recalibrate)
    save_model(cal_model, out)
    cal = cal_model.calibration
    if cal is None:  # calibrate() always attaches one; guard the contract anyway
        raise InvalidInputError("calibration produced no calibration record; please report this")
    table = Table(title=f"calibration of {model.name} on {data.name} ({mode})")
    table.add_column("group")
    table.add_column("n", justify="right")
    table.add_column("k", justify="right")
    table.add_column("scale s", justify="right")
    for g in cal.groups():
        table.add_row(g.label, str(g.n), str(g.k), f"{g.scale:.5g}")
    console.print(table)
    console.print(cal.guarantee(), soft_wrap=True, markup=False)
    record = cal_model.metadata.get("calibration_runs")
    if record:
        console.print(record["plan"]["statement"], soft_wrap=True, markup=False)
        console.print(
            f"Within-run dependence: {record['dependence']['statement']}.", soft_wrap=True, markup=False
        )
    if cal_model.domain is not None:
        console.print(cal_model.domain.describe().sentence(), soft_wrap=True, markup=False)
    console.print(f"calibrated model -> {out}", markup=False)
    outputs.announce()


@app.command("certify")
@click.argument("model", type=EXISTING_FILE)
@click.option(
    "--data",
    "test",
    type=EXISTING_FILE,
    default=None,
    help="Fresh test data (not used so far). Without it: what the model file alone certifies.",
)
@click.option("--train-data", type=EXISTING_FILE, default=None, help="The training data (for Theorem 1).")
@out_dir_option("certificate", help="Directory for certificate.json and report.html.")
@force_option
@click.option("--delta", type=float, default=None, help="Confidence (default: the calibration's; 0.001).")
@click.option(
    "--bin-column",
    default=None,
    help="With --data: column for conditional coverage (default: first x column).",
)
@click.option(
    "--bins", default=10, show_default=True, type=int, help="With --data: quantile bins per column."
)
@click.option(
    "--group-column",
    default=None,
    help="Column of the test data naming flights/runs: also count the test per group (valid for "
    "correlated rows). Default: a flight-level calibration's column.",
)
@click.option(
    "--lipschitz-radius",
    default=DEFAULT_RADIUS,
    show_default=True,
    type=click.FloatRange(min=0.0, min_open=True),
    help="Parameter-ball radius of the sound Lipschitz bound (Theorem 1). Fix it before seeing data.",
)
@click.option(
    "--units",
    default=None,
    help="Units of the perceived quantity y (e.g. m), shown on every plot axis along y. "
    "Default: 'units of the data'.",
)
@click.option(
    "--labels",
    default=None,
    help="Comma-separated labels of the coordinates of y, e.g. 'forward,left,up'. "
    "Default: the data's y column names.",
)
def certify_cmd(
    model: Path,
    test: Path | None,
    train_data: Path | None,
    out: Path,
    force: bool,
    delta: float | None,
    bin_column: str | None,
    bins: int,
    group_column: str | None,
    lipschitz_radius: float,
    units: str | None,
    labels: str | None,
) -> None:
    """Certify MODEL on fresh test data: write DIR/certificate.json and DIR/report.html.

    With --group-column COL the test is also counted per group of COL (flights, runs): the
    row-level bound assumes independent rows, the per-group one only i.i.d. groups.
    Exits with status 1 if the test data contradicts the calibration's claim.
    """
    from ipcverify.certification._certificate import CertificateStatus
    from ipcverify.certification._certify import certify_files

    unused = [o for o, name in (("--bin-column", "bin_column"), ("--bins", "bins")) if given(name)]
    if test is None and unused:
        many = len(unused) > 1
        raise InvalidInputError(
            f"{' and '.join(unused)} {'are' if many else 'is'} for binning the test data's coverage; without "
            f"--data TEST there is no test data -- give --data, or leave {'them' if many else 'it'} out"
        )
    files = [out / name for name in CERTIFY_FILES]
    inputs = {"MODEL": model, "--data": test, "--train-data": train_data}
    outputs = check_outputs(files, force=force, folder=out, inputs=inputs)

    style_of = {
        CertificateStatus.CERTIFIED: "bold green",
        CertificateStatus.UNCHECKED: "bold cyan",
        CertificateStatus.NOT_CALIBRATED: "bold yellow",
        CertificateStatus.ROWS_ASSUMED: "bold yellow",
        CertificateStatus.CONTRADICTED: "bold red",
        CertificateStatus.UNTESTED: "bold cyan",
    }
    res = certify_files(
        model,
        test,
        out,
        train_path=train_data,
        delta=delta,
        bin_column=bin_column,
        bins=bins,
        group_column=group_column,
        lipschitz_radius=lipschitz_radius,
        units=units,
        labels=None if labels is None else labels.split(","),
    )
    cert = res.certificate
    summary = cert.summary
    if summary is None:  # certify() always attaches one; guard the contract anyway
        raise InvalidInputError("the certificate has no summary; please report this")
    title, detail = summary.verdict_text().split(": ", 1)
    style = "bold yellow" if summary.certified and summary.strength == "weak" else style_of[cert.status]
    console.print(f"{title}:", style=style, markup=False, highlight=False, end=" ", soft_wrap=True)
    console.print(detail, markup=False, highlight=False, soft_wrap=True)
    console.print(cert.statement, soft_wrap=True, markup=False)
    table = Table(show_header=False)
    table.add_row("parameters p", f"{cert.model.n_parameters:,}")
    if cert.model.selection is not None:
        table.add_row("unstated settings chosen", str(cert.model.selection.get("summary", "")))
    if cert.calibration is not None:
        c = cert.calibration
        table.add_row("calibration", f"{c.mode}, epsilon={c.epsilon:g}, delta={c.delta:g}, n={c.n}")
    else:
        table.add_row("calibration", "ABSENT (no calibration certificate)")
    t = cert.test
    if t is None:
        table.add_row("test data", f"none given ({held_out_remedy()} for an independent check)")
    else:
        table.add_row(
            "test violations",
            f"{t.counted()} = {t.empirical_rate:.4%}; upper bound {t.bound_text('.4%')} "
            f"(confidence {1 - t.delta:g})",
        )
    g = cert.group_test
    if g is not None:
        rows = [("share of rows outside", g.share), ("any violation", g.trajectory)]
        if g.compared_unit == "sample":
            rows.insert(1, ("one random row", g.sample))
        if g.share_of_runs is not None:
            rows.insert(1, ("above the claim's share", g.share_of_runs))
        for label, r in rows:
            if r is not None:
                table.add_row(f"per {g.column}: {label}", f"{r.counted()}; upper bound {r.bound_text('.4%')}")
    if cert.runs:
        plan = cert.runs["plan"]
        share = next(c for c in plan["claims"] if c["guarantee"] == "expected-share")
        table.add_row(
            f"calibration runs ({cert.runs['column']})",
            f"{cert.runs['n_runs']} runs: claim about {cert.runs['unit']}s; smallest certifiable expected "
            "share "
            f"{share['smallest']:g} (floor {plan['floor']:.3g}); epsilon={plan['epsilon']:g} needs "
            f"{share['runs_needed']} runs",
        )
        dependence = cert.runs.get("dependence") or {}
        if dependence.get("effective_rows") is not None:
            table.add_row(
                "within-run dependence",
                f"{dependence['n_rows']:,} rows worth about {dependence['effective_rows']:,.0f} independent "
                "rows "
                f"(design effect {dependence['design_effect']:.3g})",
            )
    if cert.volume is not None:
        table.add_row("mean log-volume", f"{cert.volume.mean_log:.4g}")
        if cert.volume.size_text():
            table.add_row("set size", cert.volume.size_text(unit=units))
    if cert.domain is not None:
        d = cert.domain
        verdict = d.verdict
        table.add_row(
            "domain of validity",
            f"{verdict}: {d.outside}/{d.n} test queries outside (flag rate {d.flag_rate:g})"
            if d.n
            else f"{verdict}: fitted (flag rate {d.flag_rate:g}); {NOT_RUN}",
        )
    if cert.theorem1 is None:
        table.add_row("Theorem 1", cert.theorem1_reason)
    else:
        t1 = cert.theorem1
        verdict = theorem1_verdict(t1.sound.vacuous)
        need = "no N" if t1.sound.n_needed is None else f"N >= {t1.sound.n_needed:.3g}"
        table.add_row(
            "Theorem 1",
            f"{verdict}: bound {t1.sound.bound:.3g} (sound L_g {t1.sound.lipschitz:.3g}, p = "
            f"{t1.n_parameters:,}, N = {t1.n_train:,}; below 1 needs {need}); "
            f"{t1.optimistic.bound:.3g} with empirical L_g {t1.optimistic.lipschitz:.3g} (not a guarantee)",
        )
    console.print(table)
    if cert.test_bound_note:
        console.print(cert.test_bound_note, soft_wrap=True, markup=False)
    if cert.domain is not None and cert.domain.well_above_flag_rate:
        err_console.print(
            f"[bold yellow]warning:[/] {cert.domain.sentence()}", soft_wrap=True, highlight=False
        )
    console.print(f"wrote {files[0]} and {files[1]}", markup=False)
    outputs.announce()
    if cert.status is CertificateStatus.CONTRADICTED:
        sys.exit(1)
