"""Command line: ``python -m case_studies.quad_landing COMMAND`` (collect, pictures, bias, reader-timing,
reproduce, summarize, sensitivity).

Thin click wrappers over :func:`.collect.collect`, :func:`.pictures.write_pictures`,
:func:`.bias.refinement_bias`, :func:`.reader_time.measure_reader_time`,
:func:`.pipeline.reproduce` and :func:`.sensitivity.run_sensitivity`. Bad input (a bad option
value, a bad config file, an output path that cannot be written) prints one
``error: ...`` line and exits with status 2.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from case_studies.quad_landing.settings import DEFAULTS_PATH, REPRODUCE_PATH, read_toml
from case_studies.quad_landing.sim.camera import MAX_BUFFER_SIZE
from case_studies.quad_landing.sim.config import SimConfig, load_config
from ipcverify.cli.app import CliGroup, run_group
from ipcverify.cli.outputs import check_outputs, force_option
from ipcverify.data._files import json_data
from ipcverify.errors import InvalidInputError

__all__ = ["quad", "main"]

console = Console()
err_console = Console(stderr=True)

#: The shipped settings, read once for the defaults shown by ``--help``.
_DEFAULTS = read_toml(DEFAULTS_PATH)
_REPRODUCE = read_toml(REPRODUCE_PATH)


def _config(path: str | None) -> SimConfig:
    return load_config(path)


#: ``--config``, shared by every command that runs the simulator.
_config_option = click.option(
    "--config",
    "config_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="TOML file overriding defaults.toml (the simulator).",
)
#: ``--seed``, shared by the commands that draw random paths or poses.
_seed_option = click.option(
    "--seed", type=click.IntRange(min=0), default=0, show_default=True, help="Random seed."
)


@click.group(
    cls=CliGroup,
    name="quad_landing",
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)
def quad() -> None:
    """Quad-landing case study: simulate, perceive with a lagged camera, collect data."""


@quad.command("collect")
@click.option(
    "--buffer-size",
    "-k",
    type=click.IntRange(0, MAX_BUFFER_SIZE),
    default=None,
    help="Camera buffer size (V4L2 buffers; k frames of lag with camera_timing.model = 'frames') "
    f"[default: [collect] buffer_size of --config or defaults.toml: {_DEFAULTS['collect']['buffer_size']}].",
)
@click.option(
    "--n",
    "n",
    type=click.IntRange(min=1),
    default=None,
    help="Samples with a detection to collect "
    f"[default: [collect] n of --config or defaults.toml: {_DEFAULTS['collect']['n']}].",
)
@_seed_option
@click.option(
    "--out",
    type=click.Path(dir_okay=False),
    required=True,
    help="Output dataset, .parquet or .csv; a <stem>.stats.json is written beside.",
)
@_config_option
@click.option(
    "--jobs",
    "-j",
    type=click.IntRange(1, 64),
    default=1,
    show_default=True,
    help="Worker processes (the data do not depend on it).",
)
@click.option("--quiet", is_flag=True, help="No progress bar.")
@force_option
def collect_command(buffer_size: int | None, n: int | None, seed: int, out: str,
                    config_path: str | None, jobs: int, quiet: bool, force: bool) -> None:  # fmt: skip
    """Fly the exploration paths and write a dataset of camera measurements."""
    from case_studies.quad_landing.data.collect import collect, write_dataset

    out_path = Path(out)
    if out_path.suffix.lower() not in (".parquet", ".csv"):
        raise InvalidInputError(f"--out must end in .parquet or .csv, got {out_path.name!r}")
    if not out_path.parent.exists():
        raise InvalidInputError(f"--out directory {out_path.parent} does not exist; create it")
    check_outputs([out_path, out_path.with_name(out_path.stem + ".stats.json")], force=force)
    cfg = _config(config_path)
    with Progress(
        TextColumn("collecting"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
        console=err_console, transient=True, disable=quiet,
    ) as bar:  # fmt: skip
        task = bar.add_task("collect", total=cfg.collect.n if n is None else n)
        data, stats = collect(n, buffer_size=buffer_size, seed=seed, config=cfg, jobs=jobs,
                              progress=lambda k: bar.advance(task, k))  # fmt: skip
    write_dataset(data, out_path, stats)
    console.print(f"wrote {out_path}: {stats.summary()}", markup=False, highlight=False,
                  soft_wrap=True)  # fmt: skip


@quad.command("pictures")
@click.option(
    "--out",
    type=click.Path(file_okay=False),
    default="docs/img",
    show_default=True,
    help="Directory for quad_camera_frame.png, quad_paths.png, quad_lag_error.png.",
)
@_seed_option
@_config_option
def pictures_command(out: str, seed: int, config_path: str | None) -> None:
    """Write the documentation pictures (a camera frame, the paths, error per buffer size)."""
    from case_studies.quad_landing.data.pictures import write_pictures

    info = write_pictures(out, seed=seed, config=_config(config_path))
    frame = info["frame"]
    console.print(
        f"wrote pictures to {out}: frame at {frame['speed']:.2f} m/s, "
        f"image {1000 * frame['age']:.0f} ms old, "
        f"error {100 * frame['error']:.1f} cm; median error by buffer size (cm): "
        + ", ".join(f"{k}: {100 * v:.2f}" for k, v in info["median_error_by_k"].items()),
        markup=False, highlight=False, soft_wrap=True,
    )  # fmt: skip


@quad.command("bias")
@click.option("--poses", type=click.IntRange(min=1), default=100, show_default=True, help="Poses per range.")
@_seed_option
@_config_option
def bias_command(poses: int, seed: int, config_path: str | None) -> None:
    """Measure the range bias and speed of each ArUco corner refinement (no lag)."""
    from case_studies.quad_landing.studies.bias import refinement_bias

    df = refinement_bias(poses=poses, seed=seed, config=_config(config_path))
    click.echo(df.to_string(index=False, float_format=lambda v: f"{v:.3f}"))


@quad.command("reader-timing")
@click.option("--frames", "n_frames", type=click.IntRange(min=10), default=400, show_default=True,
              help="Rendered frames to time.")  # fmt: skip
@click.option("--threads", type=click.IntRange(min=2), default=2, show_default=True,
              help="OpenCV threads for the parallel speed-up.")  # fmt: skip
def reader_timing_command(n_frames: int, threads: int) -> None:
    """Time the default ArUco pipeline per frame here: the [camera_timing] numbers it gives."""
    import numpy as np

    from case_studies.quad_landing.studies.reader_time import measure_reader_time, path_frames

    res = measure_reader_time(path_frames(n_frames), threads=threads)
    lines = [
        f"ArUco + pose, 320x240, 1 thread: median {np.median(res.detector):.3f} ms",
        f"at 640x480: median {np.median(res.detector_640):.3f} ms",
        f"{res.threads} threads: median {np.median(res.detector_threads):.3f} ms",
        "[camera_timing] lines:",
        res.toml_lines(),
    ]
    console.print("\n".join(lines), markup=False, highlight=False, soft_wrap=True)


@quad.command("sensitivity")
@click.option("--out", type=click.Path(file_okay=False), required=True,
              help="Output directory: sensitivity.json, .md, cached data/ and models/.")  # fmt: skip
@click.option("--quick", is_flag=True, help="The [quick.ablation] sizes.")
@click.option("--only", default=None, help="Comma-separated variant names (the reference always runs).")
@click.option(
    "--jobs", "-j", type=click.IntRange(1, 1024), default=2, show_default=True, help="Worker processes."
)
@_config_option
@click.option("--settings", "settings_path", type=click.Path(dir_okay=False), default=None,
              help="TOML file overriding reproduce.toml.")  # fmt: skip
def sensitivity_command(out: str, quick: bool, only: str | None, jobs: int, config_path: str | None,
                        settings_path: str | None) -> None:  # fmt: skip
    """Table I when one camera-timing parameter is changed at a time (the sensitivity table)."""
    from case_studies.quad_landing.reproduction.config import load_reproduce_config
    from case_studies.quad_landing.reproduction.sensitivity import run_sensitivity, study_markdown

    settings = load_reproduce_config(settings_path, quick=quick)
    names = [n.strip() for n in only.split(",")] if only else None
    study, timing = run_sensitivity(out, config=settings, sim_config=_config(config_path), only=names,
                                    n_jobs=jobs)  # fmt: skip
    console.print(study_markdown(study.rows) + f"\n{timing}", markup=False, highlight=False, soft_wrap=True)


@quad.command("summarize")
@click.argument("out", type=click.Path(file_okay=False, exists=True))
def summarize_command(out: str) -> None:
    """Print a reproduction's results (OUT/summary.json) as the Markdown tables the docs quote."""
    import json

    from case_studies.quad_landing.reproduction.markdown import results_markdown

    path = Path(out) / "summary.json"
    if not path.exists():
        raise InvalidInputError(f"{path} does not exist; run reproduce --out {out} first")
    click.echo(results_markdown(json.loads(path.read_text())))


@quad.command("paper-ablation")
@click.argument("out", type=click.Path(file_okay=False, exists=True))
@click.option("--runs", type=click.IntRange(min=1), default=30, show_default=True,
              help="Monte Carlo landings per flown variant.")  # fmt: skip
@click.option(
    "--jobs", "-j", type=click.IntRange(1, 1024), default=2, show_default=True, help="Worker processes."
)
@_config_option
@click.option("--settings", "settings_path", type=click.Path(dir_okay=False), default=None,
              help="The TOML file the reproduction in OUT ran with, if any.")  # fmt: skip
def paper_ablation_command(
    out: str, runs: int, jobs: int, config_path: str | None, settings_path: str | None
) -> None:
    """Why the paper's IPC does not land: its method changed one part at a time, on OUT's data."""
    from case_studies.quad_landing.reproduction.config import load_reproduce_config
    from case_studies.quad_landing.reproduction.paper_ablation import ablation_markdown, run_paper_ablation

    result = run_paper_ablation(out, runs=runs, config=load_reproduce_config(settings_path),
                                sim_config=_config(config_path), jobs=jobs)  # fmt: skip
    done = f"{result['seconds']} s; wrote {out}/paper_ablation.json, .md and .png"
    console.print(ablation_markdown(result) + "\n" + done, markup=False, highlight=False, soft_wrap=True)


@quad.command("reproduce")
@click.option(
    "--out",
    type=click.Path(file_okay=False),
    required=True,
    help="Output directory: report.html, summary.json, figures/, cached data/ and models/.",
)
@click.option("--quick", is_flag=True, help="Smaller sizes, same pipeline (about 2-3 minutes).")
@click.option(
    "--jobs",
    "-j",
    type=click.IntRange(1, 1024),
    default=None,
    help="Parallel workers for the landing campaigns [default: all cores].",
)
@click.option(
    "--backend",
    type=click.Choice(["loky", "sequential", "ray"]),
    default="loky",
    show_default=True,
    help="joblib backend of the campaigns; 'ray' needs pip install 'ipcverify[ray]'.",
)
@click.option(
    "--mc-runs",
    type=click.IntRange(min=1),
    default=None,
    help="Monte Carlo runs per contract [default: [sizes] mc_runs of --settings or reproduce.toml: "
    f"{_REPRODUCE['sizes']['mc_runs']}, with --quick {_REPRODUCE['quick']['sizes']['mc_runs']}].",
)
@_config_option
@click.option(
    "--settings",
    "settings_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="TOML file overriding reproduce.toml (sizes, landing, IPC recipe).",
)
@click.option(
    "--fly-uncalibrated",
    is_flag=True,
    help="Also fly paper_raw, the paper's IPC as trained: NO guarantee (the paper's own protocol).",
)
@click.option("--quiet", is_flag=True, help="No progress bars.")
def reproduce_command(out: str, quick: bool, jobs: int | None, backend: str, mc_runs: int | None,
                      config_path: str | None, settings_path: str | None, fly_uncalibrated: bool,
                      quiet: bool) -> None:  # fmt: skip
    """Reproduce the paper's application study: Table I, safe landing, certified vs empirical."""
    from case_studies.quad_landing.reproduction.config import load_reproduce_config
    from case_studies.quad_landing.reproduction.markdown import contracts_markdown
    from case_studies.quad_landing.reproduction.pipeline import reproduce
    from case_studies.quad_landing.reproduction.table1 import table1_text

    overrides: dict[str, dict[str, Any]] = {}
    if mc_runs is not None:
        overrides["sizes"] = {"mc_runs": mc_runs}
    if fly_uncalibrated:
        overrides["paper"] = {"fly_uncalibrated": True}
    settings = load_reproduce_config(settings_path, overrides or None, quick=quick)
    result = reproduce(out, config=settings, sim_config=_config(config_path), n_jobs=jobs, backend=backend,
                       progress=not quiet, console=err_console)  # fmt: skip
    s = result.summary
    land = s.landing
    ipc, base = land.ipc.monte_carlo, land.baseline.monte_carlo
    paper_ipc, paper_base = land.ipc.paper, land.baseline.paper
    bound = land.ipc.certified
    if bound is None:  # pragma: no cover - LandingExperiment requires it
        raise InvalidInputError("the landing results carry no certified bound")
    raw = s.contracts["paper_raw"]
    lines = [
        "the three contracts (paper_raw: the paper's IPC as trained, uncalibrated -- NO guarantee):",
        contracts_markdown(json_data(s)),
        "" if raw.monte_carlo is not None else "paper_raw was not flown: pass --fly-uncalibrated to fly it",
        "default_calibrated, Table I:",
        table1_text(s.table1),
        f"landing at buffer size {land.buffer_size} ({ipc.runs} Monte Carlo runs each): "
        f"default_calibrated {ipc.safe} safe / {ipc.unsafe} unsafe / {ipc.aborted} aborted; "
        f"baseline {base.safe} safe / {base.unsafe} unsafe / {base.aborted} aborted",
        f"paper-style runs: default_calibrated {paper_ipc.safe}/{paper_ipc.runs} safe, baseline "
        f"{paper_base.unsafe}/{paper_base.runs} unsafe",
        f"certified P(unsafe) <= {bound.union_bound:.4g} "
        f"(refined {bound.refined_bound:.4g}) vs empirical {ipc.unsafe}/{ipc.runs}; "
        f"coverage shift: {land.shift_detected}",
        f"wrote {result.report} and {result.summary_path} in {s.runtime_seconds} s",
    ]
    console.print("\n".join(lines), markup=False, highlight=False, soft_wrap=True)


def main(argv: list[str] | None = None) -> None:
    """Run the CLI; bad input exits with status 2 and a single ``error:`` line on stderr."""
    run_group(quad, argv, "python -m case_studies.quad_landing")
