"""The examples' data and model (:func:`example`), and the ``ipcverify demo`` job: synthetic data ->
trained IPC -> calibrated IPC -> evaluation."""

from __future__ import annotations

import numbers
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ipcverify._wording._spelling import option
from ipcverify.calibration._bounds import min_calibration_size
from ipcverify.calibration._global_scale import Global
from ipcverify.certification._baselines import fit_global_mahalanobis
from ipcverify.certification._evaluation import Evaluation, evaluate
from ipcverify.certification._report import figure_to_png
from ipcverify.certification._report_plots import ellipse_outline
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import PerceptionDataset, save_dataset
from ipcverify.data._files import atomic_write
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.io._modelio import save_model
from ipcverify.network._architecture import ModelConfig
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.training._train import TrainConfig, train

__all__ = ["DemoSummary", "Example", "example", "run_demo", "plot_demo_sets"]

#: Calibration target of the demo: PAC, at most 1 % violations with confidence 99.9 %.
DEMO_EPSILON = 0.01
DEMO_DELTA = 0.001
#: Fewest training samples the demo accepts (the default recipe holds 15 % out for early stopping).
DEMO_MIN_TRAIN = 100
#: Most samples of one kind the demo generates (its data are made and trained on in memory).
DEMO_MAX_SAMPLES = 10_000_000
#: The files the demo writes into its folder.
DEMO_FILES = ("train.csv", "calibration.csv", "test.csv", "model.pt", "calibrated.pt", "sets.png")


#: The example model's architecture: a small paper-style network (Cholesky head) for the example data.
EXAMPLE_CONFIG = ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")


@dataclass(frozen=True, eq=False)
class Example:
    """A small perception log and an untrained IPC for it (:func:`example`).

    Attributes
    ----------
    data : PerceptionDataset
        The log: an observer whose camera image lags its state, ``x`` (n, 6) = position and
        velocity, ``y`` and ``yhat`` (n, 3) = the target's true and perceived position; with
        ``runs``, an extra ``run`` column.
    model : IPCModel
        An untrained IPC for it (weights drawn from the example's seed; train it with
        :func:`~ipcverify.train`, or calibrate it as it is).
    """

    data: PerceptionDataset
    model: IPCModel


def example(
    n: int = 1000, *, seed: int = 0, runs: int | None = None, config: ModelConfig | None = None
) -> Example:
    """Example data and an untrained IPC for it: what the documentation's examples and the tests use.

    The data are the demo's synthetic lagged perception (``make_lagged_perception``: the error
    grows with speed and range); the model is the architecture ``config`` with weights drawn from
    ``seed``, so that an example gives the same numbers every time. It is not trained: calibration
    makes its sets valid whatever they are, and :func:`~ipcverify.train` trains one.

    Parameters
    ----------
    n : int
        Rows of the log.
    seed : int
        Seeds the data and the model's weights.
    runs : int, optional
        Cut the rows into this many consecutive runs of equal length (``n`` a multiple of it),
        named by a ``run`` column: the log then comes in runs, as a robot log does.
    config : ModelConfig, optional
        The model's architecture; default: a small Cholesky network for the data's 6 state columns
        and 3 outputs. Another one (other dimensions too) gives a model for examples of its own.

    Examples
    --------
    >>> ex = example(200, seed=1)
    >>> ex.data.x.shape, ex.data.y.shape, ex.model.config.param
    ((200, 6), (200, 3), 'cholesky')
    >>> sorted(set(example(100, runs=4).data.extra["run"].tolist()))
    [0, 1, 2, 3]
    """
    import torch

    from ipcverify.network._modules import build_network

    if runs is not None and (isinstance(runs, bool) or not isinstance(runs, int) or runs < 1 or n % runs):
        raise InvalidInputError(f"runs must be a positive integer that divides n = {n}; got {runs!r}")
    cfg = EXAMPLE_CONFIG if config is None else config
    data = make_lagged_perception(n, seed=seed)
    if runs is not None:
        data = PerceptionDataset(
            data.x,
            data.y,
            data.yhat,
            source=data.source,
            extra={"run": np.repeat(np.arange(runs), n // runs)},
        )
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        network = build_network(cfg)
    return Example(data=data, model=IPCModel(network))


@dataclass(frozen=True)
class DemoSummary:
    """What the demo produced.

    Attributes
    ----------
    out_dir : Path
        Directory holding ``train.csv``, ``calibration.csv``, ``test.csv``, ``model.pt``,
        ``calibrated.pt`` and the picture ``sets.png``.
    raw : Evaluation
        The trained (uncalibrated) IPC on the test data.
    calibrated : Evaluation
        The calibrated IPC on the test data.
    guarantee : str
        The calibration's guarantee in one sentence.
    global_log_volume : float
        Log-volume of the global Mahalanobis ellipsoid calibrated on the same data at
        the same ``(epsilon, delta)``.
    global_violations : int
        Its violations on the test data.
    """

    out_dir: Path
    raw: Evaluation
    calibrated: Evaluation
    guarantee: str
    global_log_volume: float
    global_violations: int


def run_demo(
    out_dir: str | os.PathLike[str],
    n_train: int = 5000,
    n_calibration: int = 5000,
    seed: int = 0,
    progress: bool = False,
) -> DemoSummary:
    """Generate synthetic data, train an IPC, calibrate it on held-out data, evaluate it.

    The global Mahalanobis ellipsoid (one set shape for every input), fitted on the
    same training data and calibrated on the same calibration data at the same
    ``(epsilon, delta)``, is evaluated alongside for comparison.

    Parameters
    ----------
    out_dir : path-like
        Created if missing; receives the three CSV files, the two model files and the picture,
        all written once every step has succeeded (a failed run leaves no partial output).
    n_train, n_calibration : int
        Training samples (:data:`DEMO_MIN_TRAIN` to :data:`DEMO_MAX_SAMPLES`) and calibration
        samples (at least the minimum for the demo's ``(epsilon, delta)``, 688); the test set
        has 20,000.
    seed : int
        Seed for data and training, ``>= 0``.

    Raises
    ------
    InvalidInputError
        For a sample count or seed out of range (before anything is computed or written).

    Examples
    --------
    >>> import tempfile
    >>> s = run_demo(tempfile.mkdtemp(), n_train=300, n_calibration=1000)
    >>> s.calibrated.n, s.calibrated.calibrated
    (20000, True)
    """
    _check_demo_sizes(n_train, n_calibration, seed)
    out = Path(out_dir)
    train_data = make_lagged_perception(n_train, seed=seed)
    cal_data = make_lagged_perception(n_calibration, seed=seed + 500_009)
    test_data = make_lagged_perception(20_000, seed=seed + 1_000_003)
    model = train(train_data, train_config=TrainConfig(seed=seed), progress=progress).model
    calibrated = calibrate(model, cal_data, DEMO_EPSILON, DEMO_DELTA, Global(mode="pac"))
    base = fit_global_mahalanobis(train_data).calibrate(cal_data, DEMO_EPSILON, DEMO_DELTA, mode="pac")
    base_sets = base.predict(test_data.x, test_data.yhat)
    ipc_sets = calibrated.predict_unguarded(test_data.x, test_data.yhat)
    png = figure_to_png(plot_demo_sets(test_data, ipc_sets, base_sets), dpi=110)
    # every step succeeded: only now write (a failed run leaves no partial set of files)
    out.mkdir(parents=True, exist_ok=True)
    for name, ds in (("train", train_data), ("calibration", cal_data), ("test", test_data)):
        save_dataset(ds, out / f"{name}.csv")
    save_model(model, out / "model.pt")
    save_model(calibrated, out / "calibrated.pt")
    atomic_write(out / "sets.png", lambda f: f.write(png))
    return DemoSummary(
        out_dir=out,
        raw=evaluate(model, test_data),
        calibrated=evaluate(calibrated, test_data),
        guarantee=calibrated.require_calibration().guarantee(),
        global_log_volume=float(np.median(base_sets.log_volume())),
        global_violations=int((~base_sets.contains(test_data.y)).sum()),
    )


def _check_demo_sizes(n_train: int, n_calibration: int, seed: int) -> None:
    """Refuse sample counts and a seed the demo cannot run with, before it computes anything."""
    need_cal = min_calibration_size(DEMO_EPSILON, DEMO_DELTA, "pac")
    for name, value, low, flagged in (
        ("n_train", n_train, DEMO_MIN_TRAIN, True),
        ("n_calibration", n_calibration, need_cal, False),
    ):
        if (
            isinstance(value, bool)
            or not isinstance(value, numbers.Integral)
            or not low <= value <= DEMO_MAX_SAMPLES
        ):
            raise InvalidInputError(
                f"the demo needs {option(name) if flagged else name} between {low:,} and "
                f"{DEMO_MAX_SAMPLES:,}; got {value!r}"
            )
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise InvalidInputError(f"the demo's {option('seed')} must be a non-negative integer; got {seed!r}")


def plot_demo_sets(data: PerceptionDataset, ipc: Ellipsoid, base: Ellipsoid) -> Figure:
    """The calibrated IPC's set beside the global ellipsoid for a slow, a medium and a fast sample.

    Each panel shows the (y_0, y_1) projection of both sets around the perceived value,
    in centimetres, with the truth marked: the IPC's set follows the state (small when
    the observer hovers, stretched along the velocity when it moves), the global one
    cannot.

    Examples
    --------
    >>> from ipcverify import example
    >>> d = example(50, seed=0).data
    >>> e = Ellipsoid(d.yhat, np.broadcast_to(np.eye(3) * 20.0, (50, 3, 3)))
    >>> len(plot_demo_sets(d, e, e).axes)
    3
    """
    speed = np.linalg.norm(data.x[:, 3:6], axis=1) if data.x.shape[1] >= 6 else np.arange(len(data))
    picks = [int(np.argmin(np.abs(speed - np.quantile(speed, q)))) for q in (0.2, 0.7, 0.97)]
    fig = Figure(figsize=(9.0, 3.3))
    for col, i in enumerate(picks):
        ax = fig.add_subplot(1, 3, col + 1)
        origin = data.yhat[i]
        for sets, color, label in ((base, "#8a8a8a", "global ellipsoid"), (ipc, "#4c72b0", "IPC")):
            pts = (ellipse_outline(sets.centers[i] - origin, sets.shapes[i], 0, 1)) * 100.0
            ax.fill(pts[0], pts[1], color=color, alpha=0.2)
            ax.plot(pts[0], pts[1], color=color, lw=1.2, label=label)
        truth = (data.y[i] - origin) * 100.0
        ax.plot([truth[0]], [truth[1]], "x", color="#1b7f3b", ms=9, mew=2, label="truth y")
        ax.plot([0.0], [0.0], "+", color="k", ms=9, label="estimate ŷ")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(f"speed {speed[i]:.2f} m/s", fontsize=9)
        ax.set_xlabel("y_0 − ŷ_0 (cm)", fontsize=8)
        ax.set_ylabel("y_1 − ŷ_1 (cm)", fontsize=8)
        ax.tick_params(labelsize=7)
        if col == 0:
            ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("Calibrated sets at the same certified level (projection on y_0, y_1)", fontsize=10)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.15, top=0.85, wspace=0.35)
    return fig
