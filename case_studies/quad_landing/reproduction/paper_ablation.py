"""Why the paper's IPC does not land here: its method changed one part at a time, on a reproduction's data.

``python -m case_studies.quad_landing paper-ablation OUT`` reads the datasets a reproduction
cached in ``OUT/data`` (training, calibration, held-out test and pilot flights at buffer size 1)
and ipcverify's default model ``OUT/models/ipc_k1.pt``, and measures each variant of the
paper's method (:data:`VARIANTS`) the same way:

* Table I of the raw network on the pilot flights (the paper's protocol);
* on the held-out test set, the vertical half-height of its sets where the vehicle hovers
  (speed below 0.1 m/s) and where it flies fast (above 1 m/s), and the 99th percentile of its
  centre's vertical error at the hover: what decides whether a set fits ``G`` (2 cm);
* flown raw (no guarantee) in Monte Carlo landings, with the per-axis half-widths of its sets
  at the hover against ``G``'s (:func:`.contracts.hover_half_widths`).

Every variant is trained on the same rows with the same selection rule; nothing is tuned to
the landing. It writes ``OUT/paper_ablation.json``, ``.md`` and ``.png``. Timing or detector
parameters are not changed here; to see another detector, run a reproduction with
``--config`` and this command on its output.

Examples
--------
>>> [v.name for v in VARIANTS][:2]
['as_specified', 'perfect_perception']
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from case_studies.quad_landing.data.datasets import as_dataset
from case_studies.quad_landing.landing.contracts import LearnedContract
from case_studies.quad_landing.landing.state_machine import decision_target
from case_studies.quad_landing.reproduction.campaign import run_campaign, summarize
from case_studies.quad_landing.reproduction.config import PaperParams, ReproduceConfig, load_reproduce_config
from case_studies.quad_landing.reproduction.contracts import hover_half_widths
from case_studies.quad_landing.reproduction.figures import figure_png
from case_studies.quad_landing.reproduction.table1 import table1
from case_studies.quad_landing.sim.config import SimConfig, load_config
from ipcverify.contract import IPCModel
from ipcverify.data import PerceptionDataset
from ipcverify.data._files import atomic_write, write_json
from ipcverify.errors import InvalidInputError
from ipcverify.io import load_model
from ipcverify.network import ModelConfig
from ipcverify.training import train

__all__ = ["Variant", "VARIANTS", "run_paper_ablation", "ablation_markdown"]

#: Speeds (m/s) that mark a test row as hovering or as fast flight.
HOVER_SPEED, FAST_SPEED = 0.1, 1.0
#: Seed of the ablation's Monte Carlo landings (the reproduction's Monte Carlo seed).
MC_SEED = 11


@dataclass(frozen=True)
class Variant:
    """One variant of the paper's method: a name, what it changes, and how its model is trained."""

    name: str
    change: str
    fit: Callable[[PerceptionDataset, PaperParams], IPCModel]
    perfect: bool = False  # trained and tested with yhat := y (a perception module without error)
    fly: bool = True


def _paper(data: PerceptionDataset, p: PaperParams, **changes: Any) -> IPCModel:
    model_changes = {k: changes.pop(k) for k in ("center",) if k in changes}
    mc = ModelConfig.recipe("paper", x_dim=data.x_dim, y_dim=data.y_dim, hidden=p.hidden, **model_changes)
    tc = dataclasses.replace(p.train_config(), **changes)
    return train(data, mc, tc, select=p.selection()).model


#: The variants, each one change to the paper's method as the reproduction runs it.
VARIANTS: tuple[Variant, ...] = (
    Variant("as_specified", "the paper's method as the reproduction runs it ([paper])", _paper),
    Variant(
        "perfect_perception",
        "trained and tested on yhat = y: no perception error at all",
        _paper,
        perfect=True,
        fly=False,
    ),  # fmt: skip
    Variant("epochs_100", "100 epochs instead of the paper's 20", lambda d, p: _paper(d, p, epochs=100)),
    Variant(
        "offset_centre",
        "centre yhat + sigma o instead of predicted outright",
        lambda d, p: _paper(d, p, center="offset"),
    ),  # fmt: skip
    Variant(
        "default_init",
        "PyTorch's default initialisation (centre not started at yhat)",
        lambda d, p: _paper(d, p, start_at_estimate=False),
    ),  # fmt: skip
)


def _perfect(data: PerceptionDataset) -> PerceptionDataset:
    return dataclasses.replace(data, yhat=data.y.copy())


def _heights(model: IPCModel, data: PerceptionDataset, scale: float = 1.0) -> dict[str, Any]:
    """Vertical half-heights of the sets (hover, fast) and the hover centre's vertical error."""
    centers, shapes = model.raw_arrays(data.x, data.yhat)
    cov = np.linalg.inv(np.einsum("bji,bjk->bik", shapes, shapes))
    down = data.x[:, 6:9]  # the unit down direction in the camera frame (x_6 .. x_8)
    half = scale * np.sqrt(np.einsum("bi,bij,bj->b", down, cov, down))
    err = np.abs(np.einsum("bi,bi->b", down, data.y - centers))
    speed = np.linalg.norm(data.x[:, 3:6], axis=1)
    hover, fast = speed < HOVER_SPEED, speed > FAST_SPEED
    if not hover.any() or not fast.any():
        raise InvalidInputError("the test set has no hovering or no fast rows; use a reproduction's test_k1")
    return {
        "hover_rows": int(hover.sum()),
        "fast_rows": int(fast.sum()),
        "z_half_height_hover": float(np.median(half[hover])),
        "z_half_height_fast": float(np.median(half[fast])),
        "hover_to_fast": float(np.median(half[hover]) / np.median(half[fast])),
        "centre_z_error_p99_hover": float(np.quantile(err[hover], 0.99)),
    }


def _load(out: Path, name: str) -> PerceptionDataset:
    path = out / "data" / f"{name}.parquet"
    if not path.exists():
        raise InvalidInputError(f"{path} does not exist; run `reproduce --out {out}` first")
    return as_dataset(pd.read_parquet(path), str(path))


def _fly(
    model: IPCModel, cfg: ReproduceConfig, sim: SimConfig, runs: int, raw: bool, jobs: int
) -> dict[str, Any]:
    contract = LearnedContract(model, "variant", uncalibrated=raw)
    flown = run_campaign(contract, runs, seed=MC_SEED, sim_config=sim, scenario=cfg.scenario,
                         landing=cfg.landing, n_jobs=jobs)  # fmt: skip
    s = summarize(flown)
    target = decision_target(cfg.landing.tracking_tolerance, cfg.landing.target)
    return {"runs": s.runs, "safe": s.safe, "unsafe": s.unsafe, "aborted": s.aborted,
            "hover_half_widths": hover_half_widths(flown, target).to_dict()}  # fmt: skip


def run_paper_ablation(
    out: str | Path,
    *,
    runs: int = 30,
    config: ReproduceConfig | None = None,
    sim_config: SimConfig | None = None,
    jobs: int = 2,
) -> dict[str, Any]:
    """Measure every variant on the data of the reproduction in ``out``; write ``OUT/paper_ablation.*``.

    Parameters
    ----------
    out : path
        A reproduction's output directory (its ``data`` and ``models``).
    runs : int
        Monte Carlo landings per flown variant.
    config, sim_config : optional
        The settings the reproduction ran with (default: the shipped ones).
    jobs : int
        Worker processes of the landings.

    Returns
    -------
    dict
        ``rows`` (one per variant and one for ipcverify's default), ``runs``, ``seconds``.
    """
    out_dir = Path(out)
    cfg, sim = config or load_reproduce_config(), sim_config or load_config()
    started = time.perf_counter()
    tr, te = _load(out_dir, "train_k1"), _load(out_dir, "test_k1")
    pilots = {b: _load(out_dir, f"pilot_k{b}") for b in cfg.sizes.buffers}
    torch.set_num_threads(1)
    rows: list[dict[str, Any]] = []
    for v in VARIANTS:
        data, test = (_perfect(tr), _perfect(te)) if v.perfect else (tr, te)
        model = v.fit(data, cfg.paper)
        tests = {b: _perfect(d) for b, d in pilots.items()} if v.perfect else pilots
        rows.append({
            "name": v.name, "change": v.change,
            "selection": model.metadata["selection"]["summary"],
            "table1": {str(r.buffer_size): r.rate for r in table1(model, tests).rows},
            **_heights(model, test),
            "landing": _fly(model, cfg, sim, runs, True, jobs) if v.fly else None,
        })  # fmt: skip
    default = load_model(out_dir / "models" / "ipc_k1.pt")
    scale = float(default.require_calibration().summary().groups[0].scale)
    rows.append({
        "name": "default_calibrated", "change": "ipcverify's default recipe, PAC-calibrated (reference)",
        "selection": None, "table1": {str(r.buffer_size): r.rate for r in table1(default, pilots).rows},
        **_heights(default, te, scale), "landing": _fly(default, cfg, sim, runs, False, jobs),
    })  # fmt: skip
    g_tau = decision_target(cfg.landing.tracking_tolerance, cfg.landing.target)
    result = {"rows": rows, "runs": runs, "seconds": round(time.perf_counter() - started, 1),
              "limit_z": float((g_tau.upper[2] - g_tau.lower[2]) / 2)}  # fmt: skip
    write_json(out_dir / "paper_ablation.json", result, indent=1)
    text = ablation_markdown(result) + "\n"
    atomic_write(out_dir / "paper_ablation.md", lambda fh: fh.write(text), "w")
    png = figure_png(plot_paper_ablation(result))
    atomic_write(out_dir / "paper_ablation.png", lambda fh: fh.write(png))
    return result


def ablation_markdown(result: dict[str, Any]) -> str:
    """The ablation as a Markdown table (the one in ``docs/reproduce.md``).

    Examples
    --------
    >>> row = {"name": "x", "change": "c", "table1": {"1": 0.0}, "z_half_height_hover": 0.05,
    ...        "z_half_height_fast": 0.1, "hover_to_fast": 0.5, "centre_z_error_p99_hover": 0.02,
    ...        "landing": None}
    >>> ablation_markdown({"rows": [row], "limit_z": 0.02}).splitlines()[2]
    '| x: c | 0.0 | 5.0 | 10.0 | 0.50 | 2.0 | not flown | — |'
    """
    head = (
        "| variant | Table I raw, b = 1 … 5 (%) | z half-height at the hover (cm) | in fast flight (cm) "
        "| hover / fast | centre's vertical error at the hover, p99 (cm) "
        "| raw landings safe / unsafe / aborted | hover half-widths x / y / z, median (cm) |"
    )
    lines = [head, "|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        t1 = " / ".join(f"{100 * v:.1f}" for _, v in sorted(r["table1"].items(), key=lambda kv: int(kv[0])))
        land = r.get("landing")
        flown = "not flown" if land is None else f"{land['safe']} / {land['unsafe']} / {land['aborted']}"
        med = None if land is None else land["hover_half_widths"].get("median")
        widths = "—" if med is None else " / ".join(f"{100 * v:.1f}" for v in med)
        lines.append(
            f"| {r['name']}: {r['change']} | {t1} | {100 * r['z_half_height_hover']:.1f} "
            f"| {100 * r['z_half_height_fast']:.1f} | {r['hover_to_fast']:.2f} "
            f"| {100 * r['centre_z_error_p99_hover']:.1f} | {flown} | {widths} |"
        )
    return "\n".join(lines)


def plot_paper_ablation(result: dict[str, Any]) -> Figure:
    """Vertical half-height at the hover and in fast flight per variant, against what ``G`` allows."""
    rows = result["rows"]
    fig = Figure(figsize=(9.5, 4.0))
    ax = fig.subplots()
    x = np.arange(len(rows))
    ax.bar(
        x - 0.2, [100 * r["z_half_height_hover"] for r in rows], width=0.4, color="#1f77b4", label="hovering"
    )
    ax.bar(
        x + 0.2,
        [100 * r["z_half_height_fast"] for r in rows],
        width=0.4,
        color="#bbbbbb",
        label="fast flight",
    )
    ax.axhline(100 * result["limit_z"], color="k", ls="--", lw=1.2, label="largest half-height G allows")
    ax.set_xticks(x, [r["name"].replace("_", "\n") for r in rows], fontsize=8)
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.set_ylabel("vertical half-height of the set (cm, median)")
    ax.set_title("the paper's method, one change at a time (held-out test rows)", fontsize=10)
    ax.grid(alpha=0.3, axis="y", which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
