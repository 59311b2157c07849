"""The pictures of docs/certify.md, made by running its worked example.

Run ``python -m docgen.docs_certify`` (about a minute on 2 cores). It does what the worked
example of docs/certify.md tells a user to do -- 20,000 synthetic samples split 25 / 25 / 50 %,
``ipcverify train``, ``ipcverify calibrate --epsilon 0.01 --delta 0.001`` and ``ipcverify
certify --data test.csv --train-data train.csv`` (the CLI, in this process) -- and draws the
report's three plots from the certificate's evidence:

* ``docs/img/certify_scores.png`` -- the test scores with the set boundary at 1;
* ``docs/img/certify_coverage.png`` -- the violation rate per bin of the first state column;
* ``docs/img/certify_projections.png`` -- the smallest, median and largest set and a violated one.

The numbers the page quotes (order statistic, scale, test violations, upper bound) go to
``docgen/docs_certify_results.json``, so that a reader can check the page against a run.
The report's screenshot (``certify_report.png``) is of a EuRoC run and is made as the page says.
"""

from __future__ import annotations

import argparse
import shlex
import tempfile
from functools import partial
from pathlib import Path
from typing import Any, BinaryIO

from benchmarks.common import write_json
from ipcverify.certification._certify import certify_files
from ipcverify.certification._report_plots import figure_to_png, plot_coverage, plot_projections, plot_scores
from ipcverify.cli import main as cli_main
from ipcverify.data import save_dataset
from ipcverify.data._files import atomic_write
from ipcverify.data._synthetic import make_lagged_perception

__all__ = ["FIGURES", "main", "run_example"]

ROOT = Path(__file__).resolve().parent.parent
OUT = Path(__file__).with_name("docs_certify_results.json")
IMG = ROOT / "docs" / "img"
#: The files this script writes into the image folder.
FIGURES = ("certify_scores.png", "certify_coverage.png", "certify_projections.png")


def _cli(argv: list[str]) -> None:
    """One ``ipcverify`` command in this process; a non-zero exit status is an error here."""
    try:
        cli_main(argv)
    except SystemExit as done:
        if done.code not in (0, None):
            raise RuntimeError(f"ipcverify {shlex.join(argv)} exited with {done.code}") from None


def _write_bytes(data: bytes, f: BinaryIO) -> None:
    f.write(data)


def run_example(work: Path, n: int = 20_000, train_args: tuple[str, ...] = ()) -> dict[str, Any]:
    """The worked example in ``work``: data, train, calibrate, certify; the certificate's numbers.

    Parameters
    ----------
    work : Path
        An existing folder for the data, the model files and ``certificate/``.
    n : int
        Samples of ``make_lagged_perception`` before the 25 / 25 / 50 % split.
    train_args : tuple of str
        Extra options for ``ipcverify train`` (e.g. ``("--epochs", "2")`` for a quick run).

    Returns
    -------
    dict
        ``result`` (the :class:`~ipcverify.certification.CertifyResult`) and ``numbers`` (what
        the page quotes).
    """
    parts = make_lagged_perception(n, seed=0).split((0.25, 0.25, 0.5), seed=0)
    for name, part in (("train", parts.train), ("calibration", parts.calibration), ("test", parts.test)):
        assert part is not None  # three fractions given
        save_dataset(part, work / f"{name}.csv")
    _cli(["train", str(work / "train.csv"), "--out", str(work / "model.pt"), *train_args])
    _cli(
        [
            "calibrate",
            str(work / "model.pt"),
            str(work / "calibration.csv"),
            "--epsilon",
            "0.01",
            "--delta",
            "0.001",
            "--out",
            str(work / "calibrated.pt"),
        ]
    )
    result = certify_files(
        work / "calibrated.pt", work / "test.csv", work / "certificate", train_path=work / "train.csv"
    )
    cert = result.certificate
    cal, test = cert.calibration, cert.test
    assert cal is not None and test is not None  # calibrated above, tested above
    numbers = {
        "n_samples": n,
        "train_args": list(train_args),
        "calibration_n": cal.n,
        "calibration_k": cal.groups[0].k,
        "calibration_scale": cal.groups[0].scale,
        "certified_epsilon": cal.certified_epsilon,
        "test_n": test.n,
        "test_violations": test.violations,
        "test_upper_bound": test.upper_bound,
        "status": cert.status.text,
        "mean_log_volume": None if cert.volume is None else cert.volume.mean_log,
        "domain_outside": None if cert.domain is None else cert.domain.outside,
    }
    return {"result": result, "numbers": numbers}


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Run the worked example and write the three figures and the JSON.

    Parameters
    ----------
    argv : list of str, optional
        ``--n N``, ``--img DIR`` (default docs/img), ``--out FILE`` (default
        docgen/docs_certify_results.json), ``--train-args "..."`` (extra ``train`` options).

    Returns
    -------
    dict
        The numbers written to the JSON.
    """
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20_000)
    ap.add_argument("--img", type=Path, default=IMG)
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--train-args", default="", help="extra options for `ipcverify train`, quoted")
    ap.add_argument("--work", type=Path, default=None, help="keep the data and model files here")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp) if args.work is None else args.work
        work.mkdir(parents=True, exist_ok=True)
        run = run_example(work, args.n, tuple(shlex.split(args.train_args)))
    result, numbers = run["result"], run["numbers"]
    cert, ev = result.certificate, result.evidence
    assert ev is not None and cert.test is not None and cert.coverage is not None and cert.summary is not None
    eps = None if cert.calibration is None else cert.calibration.epsilon
    axes = [cert.summary.axis_label(i) for i in range(len(cert.summary.labels))]
    figures = {
        "certify_scores.png": plot_scores(ev, cert.calibration is not None),
        "certify_coverage.png": plot_coverage(cert.coverage, cert.test.delta, eps),
        "certify_projections.png": plot_projections(ev, axes),
    }
    args.img.mkdir(parents=True, exist_ok=True)
    for name, fig in figures.items():
        atomic_write(args.img / name, partial(_write_bytes, figure_to_png(fig)))
    write_json(args.out, numbers)
    print(
        f"k = {numbers['calibration_k']} of {numbers['calibration_n']}, "
        f"scale {numbers['calibration_scale']:.5f}; "
        f"{numbers['test_violations']} of {numbers['test_n']} test samples outside, upper bound "
        f"{numbers['test_upper_bound']:.6f}; figures in {args.img}"
    )
    return numbers


if __name__ == "__main__":
    main()
