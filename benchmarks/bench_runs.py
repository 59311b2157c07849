"""Validity of every claim on logs of correlated runs, with known truth (the study behind docs/runs.md).

Run ``python -m benchmarks.bench_runs`` (about 10 minutes on 2 cores). It writes
``benchmarks/runs_results.json``, ``docs/img/runs_validity.png`` and ``docs/img/runs_floor.png``.

**Logs.** :mod:`benchmarks.run_logs` generates logs of runs in four settings, from errors independent
given the state to strong autocorrelation within a run plus per-run conditions.

**Calibrations.** For each setting and each case (20 runs of 200 rows, 50 of 200, 200 of 50), ``DRAWS``
independent calibration logs are drawn, scored with the generator's own contract (the ellipsoid
centred on the estimate with radius ``sigma(x)``: the score is ``|y - yhat| / sigma(x)``, so that
only the calibration is under test), and calibrated with every claim through the specs'
``fit`` (the code ``ipcverify.contract.calibrate`` runs after scoring): the row-level PAC and
marginal claims at epsilon 0.1, and the three run-level claims at the case's target. Each claim is
checked against its true value on ``TRUTH_RUNS`` fresh runs of the same setting: a PAC claim is
false when its true rate exceeds its target; the record keeps the share of false claims with its
exact (Clopper-Pearson) 99 % interval, against delta, and the calibrated scale over the oracle
scale (the scale at which the true rate equals the target). A marginal claim holds on average:
its mean true rate is recorded. The row rate (also the expected share, the runs being of equal
length) is exact; the share of runs and the trajectory rate are counted on ``TRUTH_RUNS`` fresh runs.

**Monitor.** A network (recipe v1) is trained on one log per setting and calibrated on 200 runs,
by runs (expected share 0.1) and by rows (PAC 0.1); ``MONITOR_REPLAYS`` in-distribution logs of 20
runs are replayed through ``ipcverify.contract.monitor_log`` (the whole path: sets, domain test,
e-process), and the share that raises an alarm is recorded for each; logs whose errors are 1.5x
larger give the detection delay in runs.
"""

from __future__ import annotations

import argparse
import re
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize, stats

from benchmarks.common import machine_info, save_figure, write_json
from benchmarks.run_logs import SETTINGS, Setting, make_run_log
from ipcverify.calibration import Global, Grouped
from ipcverify.calibration._bounds import clopper_pearson_interval
from ipcverify.calibration._group_fit import smallest_run_rate
from ipcverify.calibration._method import CalibrationSample
from ipcverify.calibration._run_fit import run_quantiles
from ipcverify.calibration._share_bound import run_floor
from ipcverify.data import PerceptionDataset
from ipcverify.errors import Hint, SampleSizeError

ROOT = Path(__file__).resolve().parent.parent
OUT = Path(__file__).with_name("runs_results.json")
FIGURES = {
    "validity": ROOT / "docs" / "img" / "runs_validity.png",
    "floor": ROOT / "docs" / "img" / "runs_floor.png",
}
DELTA = 0.01
ROW_EPSILON = 0.1
#: Within-run share of the share-of-runs claim.
WITHIN = 0.1
#: (runs, rows per run, target of the run-level claims)
CASES = ((20, 200, 0.227), (50, 200, 0.15), (200, 50, 0.1))
DRAWS = 500
TRUTH_RUNS = 20_000
MONITOR_REPLAYS = 500
SHIFT = 1.5

__all__ = ["CASES", "DELTA", "bench_runs", "main", "markdown_table", "page_blocks", "paste", "scores_of"]


def scores_of(log: PerceptionDataset) -> np.ndarray:
    """The generator's own contract: ``|y - yhat| / sigma(x)`` (an ellipsoid around the estimate)."""
    sigma = 0.02 + 0.015 * log.x[:, 0] + 0.004 * log.x[:, 1]
    return np.linalg.norm(log.yhat - log.y, axis=1) / sigma


def _specs(target: float) -> dict[str, Any]:
    return {
        "row PAC": (Global(), ROW_EPSILON),
        "row marginal": (Global(mode="marginal"), ROW_EPSILON),
        "expected share": (Grouped(column="run"), target),
        "share of runs": (Grouped(column="run", guarantee="share-of-runs", gamma=target), WITHIN),
        "trajectory": (Grouped(column="run", guarantee="trajectory"), target),
        "expected share, marginal": (Grouped(column="run", mode="marginal"), target),
    }


class _Truth:
    """True rates of a threshold in one setting (runs of equal length).

    The row rate, which is also the expected share of a run's rows for runs of equal length, is
    exact: every row's score is ``c |z|`` with ``z`` standard normal in 3-D (the AR(1) series is
    stationary) and ``c`` the run's log-normal factor, so ``P(score > t) = E_c[chi2_3.sf((t/c)^2)]``,
    integrated by Gauss-Hermite quadrature. The share of runs and the trajectory rate are counted on
    ``TRUTH_RUNS`` fresh runs.
    """

    _NODES, _WEIGHTS = np.polynomial.hermite_e.hermegauss(80)

    def __init__(self, setting: Setting, rows: int, seed: int) -> None:
        self.cond = setting.cond
        log = make_run_log(TRUTH_RUNS, rows, setting, seed)
        s = scores_of(log).reshape(TRUTH_RUNS, rows)
        self.maxima = np.sort(s.max(axis=1))
        codes = np.repeat(np.arange(TRUTH_RUNS), rows)
        self.quantiles = np.sort(run_quantiles(s.ravel(), codes, TRUTH_RUNS, WITHIN))

    def row_rate(self, t: float) -> float:
        """``P(score > t)`` for a row of a new run, exactly."""
        factors = np.exp(self.cond * self._NODES - self.cond**2 / 2)
        weights = self._WEIGHTS / self._WEIGHTS.sum()
        return float(stats.chi2.sf((t / factors) ** 2, 3) @ weights)

    @staticmethod
    def _above(sorted_values: np.ndarray, t: float) -> float:
        return 1.0 - np.searchsorted(sorted_values, t, side="right") / sorted_values.size

    def rate(self, claim: str, t: float) -> float:
        """The claim's true quantity at threshold ``t``."""
        if claim == "trajectory":
            return self._above(self.maxima, t)
        if claim == "share of runs":
            return self._above(self.quantiles, t)
        return self.row_rate(t)  # equal run lengths: expected share = row rate

    def oracle(self, claim: str, target: float) -> float:
        """The threshold at which the claim's true quantity equals ``target``."""
        if claim in ("trajectory", "share of runs"):
            values = self.maxima if claim == "trajectory" else self.quantiles
            return float(np.quantile(values, 1.0 - target))
        return float(optimize.brentq(lambda t: self.row_rate(t) - target, 1e-6, 100.0, xtol=1e-12))


def _interval(k: int, n: int) -> list[float]:
    lo, hi = clopper_pearson_interval(k, n, 0.01)
    return [lo, hi]


def _calibrations(setting: Setting, case: tuple[int, int, float], draws: int) -> dict[str, Any]:
    G, rows, target = case
    truth = _Truth(setting, rows, seed=10_000 + G)
    specs = _specs(target)
    rates: dict[str, list[float]] = {name: [] for name in specs}
    scales: dict[str, list[float]] = {name: [] for name in specs}
    refused: dict[str, int] = dict.fromkeys(specs, 0)
    for r in range(draws):
        log = make_run_log(G, rows, setting, seed=r)
        scores = scores_of(log)
        for name, (spec, eps) in specs.items():
            sample = CalibrationSample(
                scores=scores, data=log, epsilon=eps, delta=DELTA, data_hash="", network_hash=""
            )
            try:
                cal = spec.fit(sample)
            except SampleSizeError:  # a refusal (too few runs) is recorded
                refused[name] += 1
                continue
            t = float(cal.groups()[0].scale)
            rates[name].append(truth.rate(name, t))
            scales[name].append(t)
    out: dict[str, Any] = {}
    for name, (spec, eps) in specs.items():
        goal = target if name == "share of runs" else eps
        rate = np.array(rates[name])
        oracle = truth.oracle(name, goal)
        k = int((rate > goal).sum())
        n = len(rate)
        out[name] = {
            "mode": spec.mode,
            "target": goal,
            "calibrations": n,
            "refused": refused[name],
            "false": k,
            "false_share": k / n if n else None,
            "false_interval_99": _interval(k, n) if n else None,
            "valid": None if not n or spec.mode != "pac" else bool(_interval(k, n)[0] <= DELTA),
            "mean_true_rate": float(rate.mean()) if n else None,
            "oracle_scale": oracle,
            "scale_over_oracle_median": float(np.median(np.array(scales[name]) / oracle)) if n else None,
        }
    return out


def _monitor(setting: Setting, replays: int) -> dict[str, Any]:
    from ipcverify.contract import calibrate, monitor_log
    from ipcverify.network._architecture import ModelConfig
    from ipcverify.training._train import TrainConfig, train

    train_log = make_run_log(100, 200, setting, seed=900)
    mc = ModelConfig.recipe("v1", x_dim=4, y_dim=3, hidden=(32,))
    model = train(train_log, mc, TrainConfig.recipe("v1", epochs=30, seed=0)).model
    cal_log = make_run_log(200, 200, setting, seed=901, start=10_000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Hint)
        contracts = {
            "runs": calibrate(model, cal_log, ROW_EPSILON, DELTA, Grouped(column="run")),
            "rows": calibrate(model, cal_log, ROW_EPSILON, DELTA, Global()),
        }
    alarms = {name: 0 for name in contracts}
    delays: list[float] = []
    for r in range(replays):
        log = make_run_log(20, 200, setting, seed=20_000 + r, start=20_000)
        for name, contract in contracts.items():
            alarms[name] += monitor_log(contract, log).alarm_index is not None
        shifted = monitor_log(
            contracts["runs"], make_run_log(40, 200, setting, seed=30_000 + r, error_scale=SHIFT)
        )
        delays.append(np.inf if shifted.alarm_index is None else shifted.alarm_index + 1)
    d = np.array(delays)
    return {
        "replays": replays,
        "runs_per_replay": 20,
        "false_alarms": {
            name: {"alarms": k, "share": k / replays, "interval_99": _interval(k, replays)}
            for name, k in alarms.items()
        },
        "run_monitor_valid": bool(_interval(alarms["runs"], replays)[0] <= DELTA),
        "shift": SHIFT,
        "detected_within_40_runs": float(np.isfinite(d).mean()),
        "median_delay_runs": float(np.median(d)) if np.isfinite(np.median(d)) else None,
        "calibrated_share_bound": contracts["runs"].calibration.bound,  # type: ignore[union-attr]
    }


def floor_curve(runs: Sequence[int] = (5, 10, 20, 30, 44, 50, 75, 100, 150, 200, 300, 500)) -> dict[str, Any]:
    """The smallest rate each claim can certify from G runs at ``DELTA``, and the floor."""
    return {
        "runs": list(runs),
        "floor": [run_floor(g, DELTA) for g in runs],
        "expected share": [smallest_run_rate("expected-share", "pac", g, DELTA) for g in runs],
        "share of runs (gamma)": [smallest_run_rate("share-of-runs", "pac", g, DELTA) for g in runs],
        "trajectory": [smallest_run_rate("trajectory", "pac", g, DELTA) for g in runs],
    }


def bench_runs(
    draws: int = DRAWS, replays: int = MONITOR_REPLAYS, settings: Sequence[Setting] = SETTINGS
) -> dict[str, Any]:
    """Every claim's false-claim share and scale per setting and case, and the monitor's false alarms."""
    start = time.perf_counter()
    out: dict[str, Any] = {
        "delta": DELTA,
        "row_epsilon": ROW_EPSILON,
        "within_run_share": WITHIN,
        "cases": [{"runs": g, "rows": r, "target": t} for g, r, t in CASES],
        "draws": draws,
        "truth_runs": TRUTH_RUNS,
        "settings": {},
        "floor_curve": floor_curve(),
    }
    for setting in settings:
        entry: dict[str, Any] = {"rho": setting.rho, "cond": setting.cond, "cases": {}}
        for case in CASES:
            entry["cases"][f"{case[0]} runs"] = _calibrations(setting, case, draws)
            print(f"{setting.name}, {case[0]} runs: done ({time.perf_counter() - start:.0f} s)", flush=True)
        entry["monitor"] = _monitor(setting, replays)
        print(f"{setting.name}: monitor done ({time.perf_counter() - start:.0f} s)", flush=True)
        out["settings"][setting.name] = entry
    out["machine"] = machine_info()
    out["runtime_seconds"] = time.perf_counter() - start
    return out


def figures(results: dict[str, Any]) -> None:
    """``docs/img/runs_validity.png`` (false claims per claim and setting) and ``runs_floor.png``."""
    from matplotlib.figure import Figure

    settings = list(results["settings"])
    cases = list(next(iter(results["settings"].values()))["cases"])
    claims = ["row PAC", "expected share", "share of runs", "trajectory"]
    fig = Figure(figsize=(11.0, 3.6 * len(cases) / 1.5))
    axes = fig.subplots(1, len(cases), sharey=True)
    colors = ["#b42318", "#1b7f3b", "#4c72b0", "#9a6700"]
    for ax, case in zip(np.atleast_1d(axes), cases, strict=True):
        for j, claim in enumerate(claims):
            xs, ys, lo, hi = [], [], [], []
            for i, name in enumerate(settings):
                rec = results["settings"][name]["cases"][case][claim]
                if not rec["calibrations"]:
                    continue
                xs.append(i + (j - 1.5) * 0.18)
                ys.append(rec["false_share"])
                lo.append(rec["false_share"] - rec["false_interval_99"][0])
                hi.append(rec["false_interval_99"][1] - rec["false_share"])
            ax.errorbar(xs, ys, yerr=[lo, hi], fmt="o", color=colors[j], label=claim, capsize=3, ms=4)
        ax.axhline(results["delta"], color="#555555", ls="--", lw=1, label=f"delta = {results['delta']:g}")
        ax.set_xticks(range(len(settings)), settings, rotation=20, fontsize=8)
        ax.set_yscale("symlog", linthresh=0.01)
        rows = next(c["rows"] for c in results["cases"] if f"{c['runs']} runs" == case)
        ax.set_title(f"{case} of {rows} rows", fontsize=10)
    first = np.atleast_1d(axes)[0]
    first.set_ylabel("share of false claims (99 % interval)")
    handles, names = first.get_legend_handles_labels()
    fig.legend(handles, names, loc="lower center", ncol=5, fontsize=8, frameon=False)
    fig.suptitle(f"False claims over {results['draws']} calibrations per setting", fontsize=11)
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.2, top=0.88, wspace=0.06)
    save_figure(fig, FIGURES["validity"])

    curve = results["floor_curve"]
    runs = np.array(curve["runs"], dtype=float)
    fig = Figure(figsize=(10.5, 4.0))
    ax, bx = fig.subplots(1, 2)
    floor = "floor 1 - delta^(1/G): no claim goes below"
    ax.plot(runs, curve["floor"], color="#111111", lw=2.5, label=floor)
    ax.plot(runs, curve["expected share"], color="#1b7f3b", marker="o", ms=3, label="expected share")
    rows_claim = 1.0 - results["delta"] ** (1.0 / (200 * runs))
    ax.plot(
        runs,
        rows_claim,
        color="#b42318",
        ls="--",
        label="row-level PAC, 200 rows per run (assumes independent rows)",
    )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("independent runs G")
    ax.set_ylabel(f"smallest certifiable rate at delta = {results['delta']:g}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title("What G runs can certify about a new run", fontsize=10)
    for name, color, style in (
        ("expected share", "#1b7f3b", "-"),
        ("share of runs (gamma)", "#4c72b0", "--"),
        ("trajectory", "#9a6700", ":"),
    ):
        ratio = np.array(curve[name]) / np.array(curve["floor"])
        bx.plot(runs, ratio, color=color, ls=style, marker="o", ms=3, label=name)
    bx.axhline(1.0, color="#111111", lw=2.5)
    bx.axhline(1.1, color="#555555", lw=1, ls="--", label="1.1 x the floor")
    bx.set_xscale("log")
    bx.set_ylim(0.98, 1.15)
    bx.set_xlabel("independent runs G")
    bx.set_ylabel("smallest certifiable rate / floor")
    bx.grid(True, which="both", alpha=0.3)
    bx.legend(fontsize=7)
    bx.set_title("Each claim against the floor (rounded up to 3 digits)", fontsize=10)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.13, top=0.92, wspace=0.25)
    save_figure(fig, FIGURES["floor"])


def main(argv: Sequence[str] | None = None) -> None:
    """``python -m benchmarks.bench_runs [--draws N] [--replays N]``."""
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--draws", type=int, default=DRAWS)
    p.add_argument("--replays", type=int, default=MONITOR_REPLAYS)
    p.add_argument("--out", type=Path, default=OUT)
    a = p.parse_args(argv)
    results = bench_runs(a.draws, a.replays)
    write_json(a.out, results)
    figures(results)
    PAGE.write_text(paste(PAGE.read_text(encoding="utf-8"), results), encoding="utf-8")
    print(f"wrote {a.out}, {FIGURES['validity']}, {FIGURES['floor']} and the tables of {PAGE}")


_CLAIMS = ("row PAC", "expected share", "share of runs", "trajectory")


def markdown_table(results: dict[str, Any]) -> str:
    """The page's table of false claims, per case, claim and setting (docs/runs.md pastes it)."""
    settings = list(results["settings"])
    lines = [
        "| runs x rows | claim (target) | " + " | ".join(settings) + " |",
        "|---|---|" + "---|" * len(settings),
    ]
    for case in results["cases"]:
        key = f"{case['runs']} runs"
        for claim in _CLAIMS:
            first = results["settings"][settings[0]]["cases"][key][claim]
            cells = []
            for name in settings:
                rec = results["settings"][name]["cases"][key][claim]
                lo, hi = rec["false_interval_99"]
                share = f"{rec['false']}/{rec['calibrations']} ({100 * lo:.1f}–{100 * hi:.1f} %)"
                cells.append(f"**{share}**" if rec["valid"] is False else share)
            label = f"{claim} ({first['target']:g})"
            lines.append(f"| {case['runs']} x {case['rows']} | {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def scale_table(results: dict[str, Any]) -> str:
    """Median calibrated scale over the oracle scale, per case, run-level claim and setting."""
    settings = list(results["settings"])
    lines = ["| runs x rows | claim | " + " | ".join(settings) + " |", "|---|---|" + "---|" * len(settings)]
    for case in results["cases"]:
        key = f"{case['runs']} runs"
        for claim in _CLAIMS[1:]:
            cells = [
                f"{results['settings'][n]['cases'][key][claim]['scale_over_oracle_median']:.3f}"
                for n in settings
            ]
            lines.append(f"| {case['runs']} x {case['rows']} | {claim} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def monitor_table(results: dict[str, Any]) -> str:
    """False alarms of the run and row monitors on in-distribution replays, and the detection delay."""
    lines = [
        "| setting | run monitor: false alarms | row monitor: false alarms | errors x1.5: detected within "
        "40 runs (median delay) |",
        "|---|---|---|---|",
    ]
    for name, entry in results["settings"].items():
        m = entry["monitor"]
        cells = []
        for unit in ("runs", "rows"):
            f = m["false_alarms"][unit]
            lo, hi = f["interval_99"]
            cells.append(f"{f['alarms']}/{m['replays']} ({100 * lo:.1f}–{100 * hi:.1f} %)")
        delay = "–" if m["median_delay_runs"] is None else f"{m['median_delay_runs']:.0f} runs"
        cells.append(f"{100 * m['detected_within_40_runs']:.0f} % ({delay})")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


PAGE = ROOT / "docs" / "runs.md"
_BLOCK = re.compile(r"(<!-- runs:(?P<name>[\w-]+) -->)(?P<body>.*?)(<!-- /runs:(?P=name) -->)", re.S)


def page_blocks(results: dict[str, Any]) -> dict[str, str]:
    """What docs/runs.md shows between its ``<!-- runs:NAME -->`` markers, from the record."""
    return {
        "draws": str(results["draws"]),
        "validity": "\n" + markdown_table(results) + "\n",
        "scale": "\n" + scale_table(results) + "\n",
        "monitor": "\n" + monitor_table(results) + "\n",
    }


def paste(text: str, results: dict[str, Any]) -> str:
    """``text`` with every block replaced by :func:`page_blocks` (unknown blocks are an error)."""
    blocks = page_blocks(results)

    def fill(m: re.Match[str]) -> str:
        return m.group(1) + blocks[m.group("name")] + m.group(4)

    return _BLOCK.sub(fill, text)


if __name__ == "__main__":
    main()
