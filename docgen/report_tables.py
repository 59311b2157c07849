"""Markdown tables of the benchmark results, shared by ``results.md``, the README and docs/benchmarks.md.

Every function takes the parsed ``benchmarks/results.json`` (or a part of it) and returns
lines of markdown; nothing here is typed in by hand (:mod:`docgen.readme` pastes the
tables into the documents between generated-block markers).
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "LABELS",
    "CM3",
    "fmt",
    "table_head",
    "tightness_table",
    "before_after_table",
    "diagnosis_table",
    "diagnosis_runs_table",
    "shift_table",
    "targets_table",
    "guard_latency_tables",
    "guard_methods_table",
]

#: Display names of the methods.
LABELS: dict[str, str] = {
    "ipc": "**ipcverify IPC, default recipe `tight`**",
    "ipc_v1": "ipcverify IPC, earlier default `v1`",
    "ipc_paper": "ipcverify IPC, recipe `paper`",
    "global_mahalanobis": "global Mahalanobis ellipsoid",
    "bonferroni_box": "Bonferroni box",
    "mapie_multivariate": "MAPIE 1.6 multivariate score",
    "oracle": "oracle (true law), PAC radius",
    "oracle_exact": "oracle at exactly 1 − ε (no calibration)",
    "raw_ipc": "raw paper IPC (UNCALIBRATED)",
    "raw_ipc_paper_head": "raw paper IPC, paper head (UNCALIBRATED)",
}
#: m^3 -> cm^3
CM3 = 1e6


def fmt(v: float | None, digits: int = 3) -> str:
    """``v`` with ``digits`` significant digits (``–`` for missing)."""
    return "–" if v is None else f"{v:.{digits}g}"


def table_head(*columns: str) -> list[str]:
    """A markdown table's header row and the separator row under it (one ``---`` per column).

    Examples
    --------
    >>> table_head("a", "b")
    ['| a | b |', '|---|---|']
    """
    return ["| " + " | ".join(columns) + " |", "|---" * len(columns) + "|"]


def _vol(r: dict[str, Any], key: str) -> str:
    s = r["spread"][key]
    if s["n"] == 1:
        return fmt(r[key] * CM3)
    return f"{fmt(r[key] * CM3)} [{fmt(s['min'] * CM3)}–{fmt(s['max'] * CM3)}]"


def _ratio(r: dict[str, Any], key: str) -> str:
    return fmt(r.get(key), 3)


#: The volume ratios every tightness table shows, in its column order.
_RATIO_REFERENCES = ("mapie", "oracle", "oracle_same_coverage", "oracle_exact", "global_mahalanobis")


def _ratio_cells(r: dict[str, Any]) -> str:
    """The five ``× reference`` cells of a method's row, ``" | "``-joined."""
    return " | ".join(_ratio(r, f"mean_volume_ratio_to_{ref}") for ref in _RATIO_REFERENCES)


#: The column heads of :func:`_factor_cells`'s two groups of cells.
_FACTOR_HEADS = ("centre", "shape", "calibration", "PAC margin")
_STAT_HEADS = ("RMS whitened centre bias", "sd log size", "aspect misfit")


def _factor_cells(d: dict[str, Any]) -> tuple[str, str]:
    """A diagnosis's symmetric factors (centre, shape, calibration, PAC margin) and its statistics
    (RMS whitened centre bias, sd of log size, aspect misfit), each as ``" | "``-joined cells."""
    sym, st = d["factors_symmetric"], d["stats"]
    factors = [sym["centre"], sym["shape"], sym["calibration"], d["factors"]["pac_margin"]]
    stats = [st["rms_whitened_bias"], st["sd_log_rel_scale"], st["aspect_misfit"]]
    return " | ".join(map(fmt, factors)), " | ".join(map(fmt, stats))


def tightness_table(name: str, res: dict[str, Any]) -> list[str]:
    """All methods on one dataset: volumes, coverage, worst-bin coverage and the volume ratios."""
    ipc = res["ipc"]
    lines = [
        f"**{name}** — PAC calibration at ε = {ipc['epsilon']:g}, δ = {ipc['delta']:g} on "
        f"{ipc['calibration_n']:,} samples; test split of {ipc['test_n']:,}. Volumes in cm³: median over "
        "training seeds [min–max]. Ratios are of mean volumes.",
        "",
        *table_head(
            "method",
            "calibrated",
            "mean volume",
            "median volume",
            "test coverage",
            "worst-bin coverage",
            "× MAPIE",
            "× oracle (PAC)",
            "× oracle (same coverage)",
            "× oracle (exact 1 − ε)",
            "× global",
            "train s",
        ),
    ]
    for method, r in res.items():
        label = LABELS.get(method, method)
        if "skipped" in r:
            lines.append(f"| {label} | – | not run: {r['skipped']} | | | | | | | | | |")
            continue
        cal = "yes" if r["calibrated"] else "**no**"
        train_s = fmt(r["train_seconds"], 2) if "train_seconds" in r else ""
        lines.append(
            f"| {label} | {cal} | {_vol(r, 'mean_volume')} | {_vol(r, 'median_volume')} | "
            f"{100 * r['coverage']:.2f} % | {r['worst_bin_coverage']:.3f} | {_ratio_cells(r)} | {train_s} |"
        )
    return lines


def before_after_table(tightness: dict[str, Any]) -> list[str]:
    """Old default (``v1``) against the new default (``tight``), MAPIE and the oracle, per dataset."""
    lines = table_head(
        "dataset",
        "method",
        "mean vol. (cm³)",
        "× MAPIE",
        "× oracle (PAC)",
        "× oracle (same coverage)",
        "× oracle (exact)",
        "× global",
        "coverage",
        "worst-bin coverage",
    )
    for name, res in tightness.items():
        for method in ("ipc_v1", "ipc", "mapie_multivariate", "oracle"):
            r = res.get(method)
            if r is None or "mean_volume" not in r:
                continue
            label = {"ipc_v1": "before: `v1`", "ipc": "**after: `tight`**"}.get(method, LABELS[method])
            lines.append(
                f"| {name} | {label} | {fmt(r['mean_volume'] * CM3)} | {_ratio_cells(r)} | "
                f"{100 * r['coverage']:.2f} % | {r['worst_bin_coverage']:.3f} |"
            )
    return lines


def diagnosis_table(tightness: dict[str, Any]) -> list[str]:
    """The volume-excess diagnosis of every ellipsoidal method (first training seed) on the oracle data."""
    lines = table_head(
        "dataset",
        "method",
        "× oracle (1 − ε)",
        *_FACTOR_HEADS,
        "shape-first: size / orientation / centre",
        *_STAT_HEADS,
        "population coverage",
        "× oracle at that coverage",
    )
    for name, res in tightness.items():
        for method in ("ipc_v1", "ipc", "mapie_multivariate", "global_mahalanobis", "oracle"):
            d = res.get(method, {}).get("diagnosis")
            if d is None:
                continue
            sf, st = d["factors_shape_first"], d["stats"]
            factors, stats = _factor_cells(d)
            label = {"ipc_v1": "`v1` (earlier default)", "ipc": "`tight` (default)"}.get(
                method, LABELS[method]
            )
            lines.append(
                f"| {name} | {label} | {fmt(d['volume_ratio_to_oracle'])} | {factors} | "
                f"{fmt(sf['rel_scale'])} / {fmt(sf['orientation'])} / {fmt(sf['centre'])} | "
                f"{stats} | {100 * st['population_coverage']:.2f} % | "
                f"{fmt(d.get('volume_ratio_to_oracle_same_coverage'))} |"
            )
    return lines


def diagnosis_runs_table(diagnosis: dict[str, Any]) -> list[str]:
    """``benchmarks/diagnosis_results.json``: each recipe's diagnosis per law and training seed."""
    lines = table_head("law", "recipe", "seed", "× oracle (1 − ε)", *_FACTOR_HEADS, *_STAT_HEADS, "coverage")
    for law, recipes in diagnosis.items():
        if law == "settings":
            continue
        for recipe, runs in recipes.items():
            for seed, d in enumerate(runs):
                factors, stats = _factor_cells(d)
                lines.append(
                    f"| {law} | `{recipe}` | {seed} | {fmt(d['volume_ratio_to_oracle'])} | {factors} | "
                    f"{stats} | {100 * d['coverage']:.2f} % |"
                )
    return lines


def shift_table(shift: dict[str, Any]) -> list[str]:
    """Violation rates (mean [worst] over folds and seeds) and mean volumes under shift."""
    methods = ("ipc_v1", "ipc", "global_mahalanobis")
    heads = {
        "ipc_v1": "earlier default `v1`",
        "ipc": "default `tight`",
        "global_mahalanobis": "global Mahalanobis",
    }
    lines = table_head("setting", *(f"{heads[m]}: violation mean [worst] (mean vol. m³)" for m in methods))
    for setting, rows in shift.items():
        if not isinstance(rows, dict) or "ipc" not in rows:
            continue
        cells = []
        for m in methods:
            r = rows[m]
            cell = (
                f"{100 * r['violation_mean']:.2f} % [{100 * r['violation_max']:.2f} %] "
                f"({fmt(r['mean_volume'])})"
            )
            if "worst_group_violation" in r:
                cell += f"; worst run {100 * r['worst_group_violation']:.1f} %"
            cells.append(cell)
        lines.append(f"| {setting} | " + " | ".join(cells) + " |")
    return lines


def targets_table(targets: dict[str, Any]) -> list[str]:
    """The issue's targets as computed by :func:`benchmarks.report.targets`."""
    lines = table_head("target", "measured", "limit", "met")
    for t in targets.values():
        val = "n/a" if t["value"] is None else f"{t['value']:.3g}"
        met = "n/a" if t["met"] is None else ("yes" if t["met"] else f"**no** ({t['by']:.3g}× the limit)")
        rel = "≥" if t.get("at_least") else "≤"
        lines.append(f"| {t['what']} | {val} | {rel} {t['limit']:.3g} | {met} |")
    return lines


#: Single-query paths of the per-workload table, in order, with their labels.
_ONE_QUERY = {
    "bare_forward": "bare torch forward of the network, all members (reference)",
    "decide": "→ ellipsoid → domain test → landing decision of record (exact proof on accepts)",
    "decide_without_domain_test": "  … the same model with its domain dropped (no domain test)",
    "decide_float": "→ ellipsoid → domain test → float landing decision (not a proof)",
    "onnx_float32": "ONNX Runtime float32, (1, d) input",
}


def _share(w: dict[str, Any]) -> str:
    share = w.get("outside_fraction")
    return "no domain" if share is None else f"{100 * share:.1f} % outside the domain"


def guard_latency_tables(lat: dict[str, Any]) -> list[str]:
    """Per workload (in-distribution first): single-query latency and guarded batch throughput.

    Each workload's header gives the share of its queries outside the domain of validity.
    """
    lines = table_head(
        "one query (x, ŷ), 1 thread", "p50 µs", "p99 µs", "p50 / bare forward", "p99 / bare forward"
    )
    for name, w in lat["workloads"].items():
        lines.append(f"| **{name}** ({_share(w)}) | | | | |")
        paths = w["single_query"]["paths"]
        for key, label in _ONE_QUERY.items():
            if key in paths:
                r = paths[key]
                lines.append(
                    f"| {label} | {r['p50']['median']:.0f} | {r['p99']['median']:.0f} | "
                    f"{r['p50_ratio_to_bare_forward']:.2f} | {r['p99_ratio_to_bare_forward']:.2f} |"
                )
    lines += [
        "",
        *table_head(
            "batch, 1 thread",
            "queries",
            "bare torch forward (q/s)",
            "guarded `predict_sets` (q/s)",
            "× bare forward",
            "without the domain test, × bare forward",
            "domain test alone (µs / query)",
        ),
    ]
    for name, w in lat["workloads"].items():
        paths = w["batch_throughput"]["paths"]
        for b in w["batch_throughput"]["sizes"]:
            if b < 10_000 and len(w["batch_throughput"]["sizes"]) > 2:
                continue
            bare = paths["bare_torch_forward"][str(b)]["median"]
            guarded = paths["predict_sets"][str(b)]["median"]
            alone = paths["predict_sets_without_domain"][str(b)]["median"]
            dom = paths["domain_contains"][str(b)]["median"]
            lines.append(
                f"| {name} ({_share(w)}) | {b:,} | {bare:,.0f} | {guarded:,.0f} | {guarded / bare:.2f} | "
                f"{alone / bare:.2f} | {1e6 / dom:.2f} |"
            )
    return lines


def guard_methods_table(lat: dict[str, Any]) -> list[str]:
    """The exact threshold test three ways, and the exact distances, per workload (µs per query)."""
    lines = table_head(
        "workload",
        "queries / references / inputs",
        "SciPy k-d tree (exact)",
        "float32 BLAS product",
        "compiled tree search (ships)",
        "exact distances",
        "same answers",
        "decided by the search / product / exact test",
    )
    for name, w in lat["workloads"].items():
        m = w.get("domain_methods")
        if not m:
            continue
        us = {k: f"{v['us_per_query_wall']['median']:.2f}" for k, v in m["methods"].items()}
        t = m["tree_tiers"]
        size = f"{m['queries']:,} / {m['references']:,} / {m['inputs']}"
        tiers = (
            f"{100 * t['decided_by_the_search']:.1f} % / {100 * t['over_budget_to_the_product']:.1f} % / "
            f"{100 * t['in_the_band_to_the_exact_test']:.2f} %"
        )
        cells = [us["exact_ckdtree"], us["blas_product"], us["tree_search"], us["distance"]]
        lines.append(
            f"| {name} ({100 * m['outside_fraction']:.1f} % outside) | {size} | "
            + " | ".join(cells)
            + f" | {'yes' if m['agree'] else '**no**'} | {tiers} |"
        )
    return lines
