"""The domain test fitted by rows vs by flight, on data whose rows come in correlated flights.

Run ``python -m benchmarks.bench_domain_groups`` (a few seconds on 2 cores). It writes
``benchmarks/domain_groups_results.json`` and ``docs/img/domain_by_flight.png``.

Each of ``draws`` seeded draws makes 60 calibration flights of 20 rows in 5-D (every flight
has its own offset, its rows scatter tightly around it) and 5 new flights drawn the same way,
so the new flights are exchangeable with the calibration flights but no new row is. The
domain test is fitted at ``alpha`` twice -- by rows (leave-one-out threshold) and by flight
(``DomainModel.fit(groups=...)``: leave-one-group-out distances, risk-control threshold) --
and the share of the new flights' rows each flags is recorded, with the flagged share of the
same flights moved 4x away from the origin (a shift both should flag).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from benchmarks.common import machine_info, write_json
from ipcverify.guard import DomainModel

ROOT = Path(__file__).resolve().parent.parent
ALPHA = 0.05


def correlated_flights(
    rng: np.random.Generator, n_flights: int, per: int = 20
) -> tuple[np.ndarray, np.ndarray]:
    """Inputs (n_flights * per, 5) and flight labels: each flight has its own offset, its rows
    scatter tightly around it."""
    labels = np.repeat(np.arange(n_flights), per)
    offsets = rng.normal(size=(n_flights, 5))
    return offsets[labels] + 0.15 * rng.normal(size=(len(labels), 5)), labels


def _share(dom: DomainModel, z: np.ndarray) -> float:
    return float((~dom.contains(z[:, :3], z[:, 3:])).mean())


def run(draws: int = 200, alpha: float = ALPHA) -> dict[str, Any]:
    """Flagged shares of new (exchangeable) and shifted flights, by rows and by flight."""
    out: dict[str, list[float]] = {"rows_new": [], "flight_new": [], "rows_shifted": [], "flight_shifted": []}
    start = time.perf_counter()
    for seed in range(draws):
        rng = np.random.default_rng(seed)
        z, labels = correlated_flights(rng, 60)
        new, _ = correlated_flights(rng, 5)
        rows = DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=alpha)
        flight = DomainModel.fit(z[:, :3], z[:, 3:], flag_rate=alpha, groups=labels)
        for name, dom in (("rows", rows), ("flight", flight)):
            out[f"{name}_new"].append(_share(dom, new))
            out[f"{name}_shifted"].append(_share(dom, 4.0 * new))
    return {
        "alpha": alpha,
        "draws": draws,
        "calibration": "60 flights x 20 rows, 5-D, flight offsets N(0, I), rows N(offset, 0.15^2 I)",
        "mean_flagged_share": {k: float(np.mean(v)) for k, v in out.items()},
        "per_draw": out,
        "seconds": time.perf_counter() - start,
        "machine": machine_info(),
    }


def figure(result: dict[str, Any], path: Path) -> None:
    """Histograms of a new flight's flagged share per draw, by rows and by flight."""
    fig = Figure(figsize=(7.0, 3.4), dpi=100)
    ax = fig.add_subplot()
    bins = np.linspace(0, 1, 41)
    per = result["per_draw"]
    mean = result["mean_flagged_share"]
    for key, how, fmt in (("rows_new", "rows", ".0%"), ("flight_new", "flight", ".1%")):
        ax.hist(per[key], bins=bins, alpha=0.7, label=f"fitted by {how} (mean {mean[key]:{fmt}})")
    ax.axvline(result["alpha"], color="k", linestyle=":", label=f"alpha = {result['alpha']:g}")
    title = f"domain test on correlated flights ({result['draws']} seeded draws)"
    ax.set(xlabel="share of 5 new, exchangeable flights flagged", ylabel="draws", title=title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)


def main() -> None:
    result = run()
    write_json(ROOT / "benchmarks" / "domain_groups_results.json", result)
    figure(result, ROOT / "docs" / "img" / "domain_by_flight.png")
    m = result["mean_flagged_share"]
    print(
        f"new flights flagged: by rows {m['rows_new']:.1%}, by flight {m['flight_new']:.1%} "
        f"(alpha {ALPHA:g}); "
        f"shifted x4: by rows {m['rows_shifted']:.1%}, by flight {m['flight_shifted']:.1%} "
        f"({result['seconds']:.1f} s)"
    )


if __name__ == "__main__":
    main()
