"""Every parameter a library message may name, with its Python and its CLI spelling, and the renderers.

Library code states facts and typed remedies (:class:`Remedy`: which parameter, what value); it
never spells a command-line flag. This module is the one place that knows both spellings of a
parameter (:data:`PARAMETERS`) and renders them for the audience of the running code: Python
(``flag_rate=0.0173``) by default, the command line (``--domain-flag-rate 0.0173``) while a CLI
command runs (:func:`~ipcverify._wording._audience.speaking`, entered by the CLI's click group).

Examples
--------
>>> option("flag_rate", 0.0173)
'flag_rate=0.0173'
>>> with speaking(Audience.CLI):
...     option("flag_rate", 0.0173)
'--domain-flag-rate 0.0173'
>>> render(Remedy("epsilon", 0.2))
'epsilon=0.2'
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ipcverify._wording._audience import Audience, audience, speaking

__all__ = [
    "COMMANDS",
    "PARAMETERS",
    "Remedy",
    "Spelling",
    "command",
    "either",
    "flag_rate_floor",
    "option",
    "options",
    "regroup_domain",
    "render",
    "speaking",
]


@dataclass(frozen=True)
class Spelling:
    """One parameter as a Python caller and a CLI user spell it.

    Attributes
    ----------
    python : str
        The keyword argument (``"flag_rate"``), or a call with ``{}`` where the value goes
        (``"DomainSpec(group_column={})"``), or a whole call that needs no value (``"Global()"``).
    cli : str
        The command-line flag (``"--domain-flag-rate"``), possibly with a fixed value
        (``"--unit row"``).
    """

    python: str
    cli: str

    def __post_init__(self) -> None:
        if not self.python or not self.cli.startswith("-"):
            raise ValueError(f"a spelling needs a Python name and a CLI flag; got {self!r}")


def _s(python: str, cli: str) -> Spelling:
    return Spelling(python, cli)


#: Every parameter a library message may name, by its library name.
PARAMETERS: dict[str, Spelling] = {
    # the domain test
    "flag_rate": _s("flag_rate", "--domain-flag-rate"),
    "domain_group_column": _s("DomainSpec(group_column={})", "--domain-group-column"),
    # calibration and claims
    "epsilon": _s("epsilon", "--epsilon"),
    "delta": _s("delta", "--delta"),
    "gamma": _s("gamma", "--gamma"),
    "mode": _s("mode", "--mode"),
    "group_column": _s("group_column", "--group-column"),
    "grouped": _s("Grouped(column={})", "--group-column"),
    "unit_row": _s("Global()", "--unit row"),
    "unit_run": _s("Grouped(column={})", "--unit run"),
    "mondrian_column": _s("Mondrian(column={})", "--mondrian-column"),
    "mondrian_bins": _s("Mondrian(column=..., bins={})", "--bins"),
    "recalibrate": _s("recalibrate=True", "--recalibrate"),
    "seed": _s("seed", "--seed"),
    "threads": _s("threads", "--threads"),
    # certification and its report
    "test_data": _s("test_data", "--data"),
    "train_data": _s("train_data", "--train-data"),
    "bins": _s("bins", "--bins"),
    "units": _s("units", "--units"),
    "labels": _s("labels", "--labels"),
    # data
    "x_columns": _s("x_columns", "--x-columns"),
    "y_columns": _s("y_columns", "--y-columns"),
    "yhat_columns": _s("yhat_columns", "--yhat-columns"),
    "n": _s("n", "--n"),
    "n_train": _s("n_train", "--n"),
    "split_by": _s("group_column", "--by"),
    "block": _s("block", "--block"),
    "time_column": _s("time_column", "--time-column"),
    "group_name": _s("group_name", "--name-groups"),
    "out_dir": _s("out_dir", "--out"),
    "out": _s("the output", "--out"),
    # training and the network
    "epochs": _s("epochs", "--epochs"),
    "lr": _s("lr", "--lr"),
    "batch_size": _s("batch_size", "--batch-size"),
    "alpha": _s("alpha", "--alpha"),
    "lam": _s("lam", "--lam"),
    "val_fraction": _s("val_fraction", "--val-fraction"),
    "patience": _s("patience", "--patience"),
    "param": _s("param", "--param"),
    "hidden": _s("hidden", "--hidden"),
    "members": _s("members", "--members"),
    # export
    "dtype": _s("dtype", "--dtype"),
    "without_domain": _s("without_domain=True", "--no-domain"),
    # ingest
    "truth": _s("truth", "--truth"),
    "estimates": _s("estimates", "--estimate"),
    "times": _s("times", "--times"),
    "format": _s("estimate_format", "--format"),
    "runs": _s("runs", "--run"),
    "state_fields": _s("state_fields", "--state-fields"),
    "typestore": _s("typestore", "--typestore"),
    "stamp": _s("stamp", "--stamp"),
    "child_frame": _s("child_frame", "--child-frame"),
    "quantity": _s("quantity", "--quantity"),
    "horizon": _s("horizon", "--horizon"),
    "stride": _s("stride", "--stride"),
    "max_gap": _s("max_gap", "--max-gap"),
    "t_offset": _s("t_offset", "--t-offset"),
    "align": _s("align", "--align"),
    "align_runs": _s("align_runs", "--align-runs"),
    "up": _s("up", "--up"),
}


def _shown(value: object, cli: bool) -> str:
    """A value as the audience writes it: floats with ``:g``; in Python, strings quoted (not PLACEHOLDERS)."""
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, tuple):
        return ",".join(map(str, value)) if cli else repr(value)
    if isinstance(value, str) and not cli and not value.isupper():
        return repr(value)
    return str(value)


def option(name: str, value: object = None) -> str:
    """``name`` (with ``value``) as the current audience writes it.

    Parameters
    ----------
    name : str
        A key of :data:`PARAMETERS`.
    value : object, optional
        The value to show; floats are written with ``:g``.

    Raises
    ------
    KeyError
        If ``name`` is not a known parameter (a bug: add its spelling to :data:`PARAMETERS`).
    """
    spelled = PARAMETERS[name]
    cli = audience() is Audience.CLI
    fixed = spelled.cli if cli else spelled.python  # a spelling that holds its value: "--unit row"
    if (
        value is None
        or value is True
        and cli
        or (" " in fixed if cli else ("{}" not in fixed and ("=" in fixed or "(" in fixed)))
    ):
        return fixed.replace("{}", "...")
    shown = _shown(value, cli)
    if cli:
        return f"{spelled.cli} {shown}"
    if "{}" in spelled.python:
        return spelled.python.replace("{}", shown)
    return f"{spelled.python}={shown}"


def options(*names: str, last: str = "and") -> str:
    """Several parameters named as the current audience writes them: ``"--a, --b and --c"``.

    Examples
    --------
    >>> options("alpha", "lam", "batch_size")
    'alpha, lam and batch_size'
    >>> with speaking(Audience.CLI):
    ...     options("epsilon", "delta", last="or")
    '--epsilon or --delta'
    """
    said = [option(n) for n in names]
    return said[0] if len(said) == 1 else f"{', '.join(said[:-1])} {last} {said[-1]}"


def either(python: str, cli: str) -> str:
    """``python`` or ``cli``, whichever the current audience reads: for a phrase that names no parameter.

    Examples
    --------
    >>> either("pass the file", "give --data")
    'pass the file'
    """
    return cli if audience() is Audience.CLI else python


#: Every command a library message may name: the CLI subcommand and the Python function.
COMMANDS: dict[str, tuple[str, str]] = {
    "split": ("ipcverify split", "split_file"),
    "calibrate": ("ipcverify calibrate", "calibrate"),
    "certify": ("ipcverify certify", "certify"),
    "predict": ("ipcverify predict", "IPCModel.predict"),
}


def command(name: str, args: Sequence[tuple[str, str]] = (), **values: object) -> str:
    """A call of command ``name`` as the current audience writes it.

    Parameters
    ----------
    name : str
        A key of :data:`COMMANDS`.
    args : sequence of (python, cli) pairs
        The positional arguments as each audience writes them (``("model", "MODEL")``); an empty
        spelling leaves the argument out for that audience.
    **values
        Parameters (keys of :data:`PARAMETERS`) and their values (None: the bare option).

    Examples
    --------
    >>> command("certify", [("model", "MODEL"), ("test_data", "TEST")])
    'certify(model, test_data)'
    >>> with speaking(Audience.CLI):
    ...     command("split", [("", "DATA")], block="SECONDS", group_name="segment")
    'ipcverify split DATA --block SECONDS --name-groups segment'
    """
    cli_name, python_name = COMMANDS[name]
    cli = audience() is Audience.CLI
    said = [a[1] if cli else a[0] for a in args]
    said = [a for a in said if a] + [option(k, v) for k, v in values.items()]
    return " ".join([cli_name, *said]) if cli else f"{python_name}({', '.join(said)})"


def regroup_domain(column: str, flag_rate: float | None = None) -> str:
    """The ``calibrate`` call that fits the domain test by ``column`` (at ``flag_rate``, if given).

    The remedy for a domain test fitted row by row on rows that come in runs: the caller states
    the facts (the column, and the smallest flag rate its groups allow when the current one is
    below it).

    Examples
    --------
    >>> regroup_domain("run", 0.091)
    "calibrate(..., domain=DomainSpec(group_column='run', flag_rate=0.091))"
    >>> with speaking(Audience.CLI):
    ...     regroup_domain("run")
    'calibrate --domain-group-column run'
    """
    if audience() is Audience.CLI:
        rate = "" if flag_rate is None else f" {option('flag_rate', flag_rate)}"
        return f"calibrate {option('domain_group_column', column)}{rate}"
    rate = "" if flag_rate is None else f", flag_rate={flag_rate:g}"
    return f"calibrate(..., domain=DomainSpec(group_column={column!r}{rate}))"


@dataclass(frozen=True)
class Remedy:
    """What would meet a refused requirement: a parameter and the value to give it.

    Attributes
    ----------
    parameter : str
        A key of :data:`PARAMETERS`.
    value : float, int, str or None
        The value that works (None: the parameter itself is the remedy).
    """

    parameter: str
    value: float | int | str | None = None

    def __post_init__(self) -> None:
        if self.parameter not in PARAMETERS:
            raise ValueError(f"unknown parameter {self.parameter!r}: add its spelling to PARAMETERS")


def render(remedy: Remedy) -> str:
    """The remedy as the current audience writes it (see :func:`option`)."""
    return option(remedy.parameter, remedy.value)


def flag_rate_floor(n: int, units: str, smallest: float) -> str:
    """What ``n`` calibration inputs (or groups) allow the domain test's flag rate.

    Examples
    --------
    >>> flag_rate_floor(57, "inputs", 0.0173)
    'with 57 inputs the flag rate must be at least 1/58: flag_rate=0.0173 works'
    """
    return f"with {n} {units} the flag rate must be at least 1/{n + 1}: {option('flag_rate', smallest)} works"
