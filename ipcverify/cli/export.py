"""CLI command ``export`` (ONNX); registered on the shared app.

A thin wrapper: load the model, call :func:`ipcverify.io.export_onnx`, and -- when
ONNX Runtime is installed -- :func:`ipcverify.io.check_onnx` on random inputs.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import click
import numpy as np

from ipcverify.cli.app import EXISTING_FILE, OUTPUT_FILE, app, choice_option, console, err_console
from ipcverify.cli.outputs import check_outputs, force_option
from ipcverify.errors import InvalidInputError

if TYPE_CHECKING:
    from ipcverify.contract._model import IPCModel

__all__: list[str] = []

#: Largest relative difference to the model accepted by the export check, per dtype.
CHECK_TOLERANCE = {"float64": 1e-10, "float32": 1e-4}
#: Largest relative difference accepted against the float32 torch network.
TORCH_TOLERANCE = 1e-4


@app.command("export")
@click.argument("model", type=EXISTING_FILE)
@click.option(
    "--onnx",
    "onnx_path",
    type=OUTPUT_FILE,
    required=True,
    help="Write the model's (calibrated) sets as an ONNX graph here (.onnx).",
)
@force_option
@click.option(
    "--no-domain",
    is_flag=True,
    help="Export a model with a domain-of-validity test without it (ONNX cannot reproduce the test "
    "exactly): check each query with `ipcverify predict` or IPCQuery before trusting its set.",
)
@choice_option(
    "--dtype",
    choices=["float64", "float32"],
    default="float64",
    help="float64 reproduces the calibrated sets to ~1e-15; float32 is smaller and faster for big batches.",
)
def export_cmd(model: Path, onnx_path: Path, force: bool, dtype: str, no_domain: bool) -> None:
    """Export MODEL to ONNX: inputs x (B, d), yhat (B, n); outputs center (B, n), shape (B, n, n).

    A global calibration is included (shape = C / scale); a Mondrian calibration is refused. The
    domain-of-validity test is not in the graph: a model with one needs --no-domain.
    """
    from ipcverify.io._modelio import load_model

    outputs = check_outputs(
        [onnx_path],
        force=force,
        option="--onnx",
        suffixes=(".onnx",),
        what="an ONNX graph",
        inputs={"MODEL": model},
    )
    m = load_model(model)
    if no_domain and m.domain is None:
        raise InvalidInputError(
            f"--no-domain: {model} has no domain-of-validity test to leave out; leave --no-domain out"
        )
    scratch = onnx_path
    if onnx_path.exists():  # --force: written beside, checked, then put in place; a failed check keeps it
        fd, name = tempfile.mkstemp(prefix=f".{onnx_path.name}.", suffix=".onnx", dir=onnx_path.parent)
        os.close(fd)
        scratch = Path(name)
    try:
        _export_checked(m, scratch, onnx_path, dtype, no_domain)
    except BaseException:
        scratch.unlink(missing_ok=True)
        raise
    outputs.announce()


def _export_checked(m: IPCModel, scratch: Path, onnx_path: Path, dtype: str, no_domain: bool) -> None:
    """Export ``m`` to ``scratch``, check it in ONNX Runtime if installed, then move it to ``onnx_path``.

    ``scratch`` is ``onnx_path`` itself when no file is there to keep; the caller removes it if this fails.
    """
    from ipcverify.io._onnx import check_onnx, export_onnx

    info = export_onnx(m, scratch, dtype=dtype, without_domain=no_domain)  # type: ignore[arg-type]
    what = f"calibrated (scale {info.scale:.6g})" if info.calibrated else "UNCALIBRATED raw network sets"
    if m.domain is not None:
        err_console.print(
            "warning: the ONNX graph has no domain-of-validity test (--no-domain): its sets carry the "
            "guarantee only for queries that pass the model's test; check them with `ipcverify predict` "
            "(in_domain) or IPCQuery",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
    try:
        import onnxruntime  # noqa: F401
    except ImportError:
        os.replace(scratch, onnx_path)
        console.print(f"wrote {onnx_path} ({info.nbytes:,} bytes, {dtype}, {what})", markup=False)
        console.print("onnxruntime is not installed: export not checked (pip install 'ipcverify[onnx]')")
        return
    rng = np.random.default_rng(0)
    eng = m.engine
    d = m.config.x_dim
    z = eng.in_mean + rng.standard_normal((256, len(eng.in_mean))) / eng.in_scale
    chk = check_onnx(m, scratch, z[:, :d], z[:, d:])
    worst = max(chk.vs_engine_center, chk.vs_engine_shape)
    if worst > CHECK_TOLERANCE[dtype] or not chk.passes(TORCH_TOLERANCE):
        raise InvalidInputError(
            f"the ONNX graph disagrees with the model (relative difference {worst:.3g} to the float64 "
            f"engine); nothing was written to {onnx_path} -- please report this with the model file"
        )
    os.replace(scratch, onnx_path)
    console.print(f"wrote {onnx_path} ({info.nbytes:,} bytes, {dtype}, {what})", markup=False)
    console.print(
        f"checked in ONNX Runtime on {chk.samples} inputs: max relative difference {worst:.2g} to the "
        f"float64 engine, {max(chk.vs_torch_center, chk.vs_torch_shape):.2g} to the float32 torch network",
        markup=False,
    )
