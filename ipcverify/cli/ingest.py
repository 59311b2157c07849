"""CLI commands ``ingest topics``, ``ingest bag`` and ``ingest trajectories``; registered on the shared app.

Thin wrappers over :mod:`ipcverify.io.ingest`: parse, build the samples, write the table and its
manifest, print what was kept and dropped.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from ipcverify.cli.app import OUTPUT_FILE, app, choice_option, console
from ipcverify.cli.outputs import Outputs, check_outputs, force_option
from ipcverify.errors import InvalidInputError

if TYPE_CHECKING:
    import pandas as pd

    from ipcverify.io.ingest import IngestOptions

__all__: list[str] = []

_IN = click.Path(exists=True, path_type=Path)
#: ``ipcverify.io.ingest.FORMATS`` and ``ipcverify.io.ingest.QUANTITIES``, written out
#: so that ``--help`` need not import the ingest package (pandas, SciPy); checked equal by
#: ``tests/ipcverify/cli/test_startup.py``.
_FORMAT = click.Choice(("tum", "euroc", "kitti"))
_QUANTITY = click.Choice(("displacement", "position", "pose"))


@app.group("ingest")
def ingest_group() -> None:
    """Build a perception log (x, y, yhat, run, t) from ROS bags, MCAP or trajectory files."""


def _sampling(f: Callable[..., Any]) -> Callable[..., Any]:
    """The options every ingest command shares (quantity, timing, alignment, output)."""
    opts = [
        click.option(
            "--out",
            type=OUTPUT_FILE,
            required=True,
            help="Output table (.csv or .parquet); NAME.manifest.json goes beside it.",
        ),
        force_option,
        click.option(
            "--quantity",
            type=_QUANTITY,
            default="displacement",
            show_default=True,
            help="displacement needs no alignment; position and pose take --align.",
        ),
        click.option("--horizon", type=float, default=0.5, show_default=True, help="Seconds from t0 to t1."),
        click.option(
            "--stride", type=float, default=0.25, show_default=True, help="Seconds between sample starts."
        ),
        click.option(
            "--max-gap",
            type=float,
            default=0.2,
            show_default=True,
            help="Widest gap (s) between the two stamps around an interpolated time.",
        ),
        click.option(
            "--t-offset",
            type=float,
            default=0.0,
            show_default=True,
            help="Seconds added to the truth's stamps to put them on the estimate's clock.",
        ),
        click.option(
            "--align", type=click.Choice(["none", "se3", "sim3"]), default="none", show_default=True
        ),
        click.option(
            "--align-runs",
            default=None,
            help="Comma-separated runs to fit --align on; keep them out of calibration and test.",
        ),
        click.option(
            "--up",
            type=click.Choice(["+x", "-x", "+y", "-y", "+z", "-z"]),
            default=None,
            help="The world's up axis in the estimate's frame, for the tilt columns x_2..x_4 "
            "[+z; -y for --format kitti, whose camera frame has y down].",
        ),
        click.option("--run", "runs", multiple=True, help="Run name, one per input (default: file stems)."),
        click.option("--tag", "tags", multiple=True, help="KEY=VALUE: a constant column (repeatable)."),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


def _common(sampling: dict[str, Any]) -> tuple[Path, IngestOptions, list[str] | None, dict[str, str]]:
    """The output path, the options, the run names and the tags from the shared options' values."""
    from ipcverify.io.ingest import IngestOptions

    align_runs = sampling["align_runs"]
    options = IngestOptions(
        quantity=sampling["quantity"],
        horizon=sampling["horizon"],
        stride=sampling["stride"],
        max_gap=sampling["max_gap"],
        t_offset=sampling["t_offset"],
        align=sampling["align"],
        align_runs=tuple(r.strip() for r in align_runs.split(",") if r.strip()) if align_runs else (),
        up=sampling["up"],
    )
    return sampling["out"], options, list(sampling["runs"]) or None, _tags(sampling["tags"])


def _check_outputs(out: Path, force: bool, **inputs: tuple[Path, ...] | Path | None) -> Outputs:
    """Check --out and its manifest (:func:`~ipcverify.cli.outputs.check_outputs`): not one of the input
    files (``--truth``, ``--estimate``, a bag ...), a table's extension, not there unless --force."""
    from ipcverify.io.ingest._manifest import TABLE_SUFFIXES, manifest_path

    named: dict[str, Path | None] = {}
    for label, given in inputs.items():
        paths = given if isinstance(given, tuple) else (given,)
        for i, path in enumerate(paths):
            named[label if len(paths) == 1 else f"{label} #{i + 1}"] = path
    check_outputs([out], force=force, suffixes=TABLE_SUFFIXES, what="a table", inputs=named)
    return check_outputs([out, manifest_path(out)], force=force, inputs=named)


def _tags(items: tuple[str, ...]) -> dict[str, str]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise InvalidInputError(f"--tag {item!r}: write KEY=VALUE, e.g. --tag method=vio")
        out[key.strip()] = value
    return out


def _report(frame: pd.DataFrame, out: Path, manifest: Path) -> None:
    from ipcverify.io.ingest._samples import MANIFEST_KEY

    account = frame.attrs[MANIFEST_KEY]
    for run in account["runs"]:
        dropped = ", ".join(f"{k} {v}" for k, v in run["dropped"].items() if v) or "none"
        console.print(
            f"run {run['run']}: {run['rows']} of {run['sample_starts']} samples kept; dropped: {dropped}",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
    if account["alignment"]:
        a = account["alignment"]
        console.print(
            f"alignment {a['kind']} fitted on runs {', '.join(a['fitted_on_runs'])} "
            f"({a['pairs']} pairs, rmse {a['rmse']:.4g}); keep those runs out of calibration and test",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
    console.print(
        f"wrote {len(frame)} rows to {out} and the manifest {manifest}",
        markup=False,
        highlight=False,
        soft_wrap=True,
    )


@ingest_group.command("topics")
@click.argument("path", type=_IN)
@click.option(
    "--typestore", default=None, help="Message definitions for a bag without them, e.g. ros2_humble."
)
def topics_cmd(path: Path, typestore: str | None) -> None:
    """List the topics of a bag or MCAP file: type, message count and time span (receive times)."""
    from ipcverify.io.ingest import list_topics

    topics = list_topics(path, typestore)
    if not topics:
        raise InvalidInputError(f"{path}: no topic in it (the recording is empty)")
    for info in topics:
        console.print(info.describe(), markup=False, highlight=False, soft_wrap=True)


@ingest_group.command("bag")
@click.argument("paths", nargs=-1, required=True, type=_IN)
@click.option("--truth", "truth_topic", required=True, help="Ground-truth pose topic.")
@click.option("--estimate", "estimate_topic", required=True, help="Estimated pose topic.")
@click.option("--child-frame", default=None, help="The body's frame on a /tf topic.")
@click.option("--truth-child-frame", default=None, help="--child-frame for the truth topic only.")
@click.option("--estimate-child-frame", default=None, help="--child-frame for the estimate topic only.")
@choice_option(
    "--stamp",
    choices=["header", "receive"],
    default="header",
    help="Time messages by their header stamps or by the recorder's receive times.",
)
@click.option(
    "--state", "state_topic", default=None, help="A topic whose fields are appended to x (held causally)."
)
@click.option(
    "--state-fields",
    default=None,
    help="Comma-separated numeric fields of --state, e.g. twist.twist.linear.x.",
)
@click.option(
    "--typestore", default=None, help="Message definitions for bags without them, e.g. ros2_humble."
)
@_sampling
def bag_cmd(
    paths: tuple[Path, ...],
    truth_topic: str,
    estimate_topic: str,
    child_frame: str | None,
    truth_child_frame: str | None,
    estimate_child_frame: str | None,
    stamp: str,
    state_topic: str | None,
    state_fields: str | None,
    typestore: str | None,
    **sampling: Any,
) -> None:
    """Build samples from ROS 1 bags, ROS 2 bags (.db3 or .mcap) or raw MCAP files; each PATH is a run."""
    from ipcverify.io.ingest import ingest_bags, write_ingested

    out, options, runs, tags = _common(sampling)
    outputs = _check_outputs(out, sampling["force"], PATH=paths)
    if state_fields and state_topic is None:
        raise InvalidInputError("--state-fields names fields of the --state topic; give --state TOPIC too")
    if child_frame is not None and truth_child_frame is not None and estimate_child_frame is not None:
        raise InvalidInputError(
            "--child-frame is overridden by both --truth-child-frame and --estimate-child-frame; leave it out"
        )
    frame = ingest_bags(
        list(paths),
        truth_topic=truth_topic,
        estimate_topic=estimate_topic,
        child_frame=child_frame,
        truth_child_frame=truth_child_frame,
        estimate_child_frame=estimate_child_frame,
        stamp=stamp,  # type: ignore[arg-type]
        state_topic=state_topic,
        state_fields=[f.strip() for f in (state_fields or "").split(",") if f.strip()],
        typestore=typestore,
        runs=runs,
        tags=tags,
        options=options,
    )
    _report(frame, out, write_ingested(frame, out))
    outputs.announce()


@ingest_group.command("trajectories")
@click.option(
    "--truth",
    "truth",
    required=True,
    multiple=True,
    type=_IN,
    help="Ground-truth file: one for every run, or one per --estimate.",
)
@click.option(
    "--estimate",
    "estimates",
    required=True,
    multiple=True,
    type=_IN,
    help="Estimated trajectory file; each is a run (repeatable).",
)
@click.option("--format", "fmt", type=_FORMAT, default=None, help="Layout of both files [tum].")
@click.option("--truth-format", type=_FORMAT, default=None, help="Layout of the truth file(s).")
@click.option("--estimate-format", type=_FORMAT, default=None, help="Layout of the estimate file(s).")
@click.option("--times", type=_IN, default=None, help="KITTI: times file, one time (s) a line.")
@_sampling
def trajectories_cmd(
    truth: tuple[Path, ...],
    estimates: tuple[Path, ...],
    fmt: str | None,
    truth_format: str | None,
    estimate_format: str | None,
    times: Path | None,
    **sampling: Any,
) -> None:
    """Build samples from TUM, EuRoC or KITTI trajectory files; each --estimate is a run."""
    from ipcverify.io.ingest import ingest_trajectories, write_ingested

    out, options, runs, tags = _common(sampling)
    inputs = {"--truth": truth, "--estimate": estimates, "--times": times}
    outputs = _check_outputs(out, sampling["force"], **inputs)
    if fmt is not None and truth_format is not None and estimate_format is not None:
        raise InvalidInputError(
            "--format is overridden by both --truth-format and --estimate-format; leave it out"
        )
    frame = ingest_trajectories(
        list(truth),
        list(estimates),
        truth_format=truth_format or fmt or "tum",  # type: ignore[arg-type]
        estimate_format=estimate_format or fmt or "tum",  # type: ignore[arg-type]
        times=times,
        runs=runs,
        tags=tags,
        options=options,
    )
    _report(frame, out, write_ingested(frame, out))
    outputs.announce()
