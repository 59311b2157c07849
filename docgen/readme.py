"""Paste measured numbers into README.md and docs/ (results.md, benchmarks.md): none is typed by hand.

The documents mark each generated block::

    <!-- BEGIN generated:NAME (python -m docgen.readme) -->
    ...
    <!-- END generated:NAME -->

``python -m docgen.readme`` rewrites every block from ``benchmarks/results.json``,
``benchmarks/training_results.json`` and ``benchmarks/diagnosis_results.json``;
``--demo`` also reruns ``ipcverify demo`` (about 15 s) and pastes its console output.
``--check`` only reports blocks that are out of date (exit status 1).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from docgen.report_tables import (
    CM3,
    before_after_table,
    diagnosis_runs_table,
    diagnosis_table,
    fmt,
    guard_latency_tables,
    guard_methods_table,
    shift_table,
    table_head,
    targets_table,
)

__all__ = [
    "BLOCK",
    "DOCUMENTS",
    "load_results",
    "render_blocks",
    "replace_blocks",
    "demo_block",
    "console_block",
    "main",
]

ROOT = Path(__file__).resolve().parent.parent
HERE = ROOT / "benchmarks"  # the benchmark results the blocks are made from
DOCUMENTS = (ROOT / "README.md", ROOT / "docs" / "results.md", ROOT / "docs" / "benchmarks.md")
BLOCK = re.compile(
    r"(<!-- BEGIN generated:(?P<name>[\w-]+) \(python -m docgen\.readme[^)]*\) -->\n)(?P<body>.*?)"
    r"(<!-- END generated:(?P=name) -->)",
    re.S,
)


def _load(name: str) -> Any:
    path = HERE / name
    return json.loads(path.read_text()) if path.is_file() else None


def _readme_table(tight: dict[str, Any]) -> list[str]:
    names = [n for n in ("synthetic", "quad_landing") if n in tight]
    heads = [h for n in names for h in (f"{n}: mean vol. (cm³)", "× MAPIE", "coverage / worst bin")]
    lines = table_head("method (PAC ε = 0.01, δ = 0.001)", *heads)
    rows = (
        "ipc",
        "ipc_v1",
        "global_mahalanobis",
        "bonferroni_box",
        "mapie_multivariate",
        "oracle",
        "raw_ipc",
    )
    labels = {
        "ipc": "**ipcverify IPC, default recipe `tight`**",
        "ipc_v1": "ipcverify IPC, earlier default (`--recipe v1`)",
        "global_mahalanobis": "global Mahalanobis ellipsoid",
        "bonferroni_box": "Bonferroni box",
        "mapie_multivariate": "MAPIE 1.6 multivariate score",
        "oracle": "oracle: the true conditional law, same PAC radius",
        "raw_ipc": "raw paper IPC — **uncalibrated**, no certificate",
    }
    for method in rows:
        cells = []
        for n in names:
            r = tight[n].get(method)
            if r is None or "mean_volume" not in r:
                cells.append("– | – | –")
                continue
            cells.append(
                f"{fmt(r['mean_volume'] * CM3)} | {fmt(r.get('mean_volume_ratio_to_mapie'))} | "
                f"{100 * r['coverage']:.2f} % / {100 * r['worst_bin_coverage']:.1f} %"
            )
        if any(c != "– | – | –" for c in cells):
            lines.append(f"| {labels[method]} | " + " | ".join(cells) + " |")
    return lines


def _latency_table(lat: dict[str, Any]) -> list[str]:
    if "workloads" in lat:  # every workload, in-distribution first, with its share outside the domain
        return guard_latency_tables(lat)
    paths = lat["single_query"]["paths"]
    labels = {
        "bare_forward": "bare torch forward of the network, all members (reference)",
        "decide_float": "→ ellipsoid → domain test → float landing decision (not a proof)",
        "decide": "→ ellipsoid → domain test → landing decision of record (exact proof on accepts)",
        "decide_rejecting_queries": "  … its rejecting queries",
        "decide_accepting_queries": "  … its accepting queries",
        "decide_outside_domain_queries": "  … its queries outside the domain of validity",
        "decide_without_domain_test": "  … the same model with its domain dropped (no domain test)",
        "onnx_float32": "ONNX Runtime float32, (1, d) input",
    }
    lines = table_head("one query (x, ŷ), 1 thread", "p50 µs", "p99 µs", "p50 / bare torch forward")
    for key, label in labels.items():
        r = paths.get(key)
        if r is not None:
            lines.append(
                f"| {label} | {r['p50']['median']:.0f} | {r['p99']['median']:.0f} | "
                f"{r['p50_ratio_to_bare_forward']:.2f} |"
            )
    return lines


def _guard_block(lat: dict[str, Any] | None) -> list[str]:
    """docs/benchmarks.md's per-workload tables of the guarded paths and the domain test's methods."""
    if lat is None or "workloads" not in lat:
        return ["(Not in the committed results: they predate the per-workload latency benchmark.)"]
    described = [f"* `{k}`: {w['description']}" for k, w in lat["workloads"].items()]
    return [*described, "", *guard_latency_tables(lat), "", *guard_methods_table(lat)]


def _training_table(training: dict[str, Any]) -> list[str]:
    lines = table_head(
        "data (N = 5,000)", "recipe", "wall s, median [min–max] of 3", "CPU s", "epochs run", "≤ 10 s"
    )
    for key, r in training.items():
        if "/" not in key:
            continue
        name, recipe = key.split("/")
        lines.append(
            f"| {name} | `{recipe}` | {r['wall_seconds_median']:.1f} [{r['wall_seconds_min']:.1f}–"
            f"{r['wall_seconds_max']:.1f}] | {r['cpu_seconds_median']:.1f} | {r['epochs']} | "
            f"{'yes' if r['meets_target'] else 'no'} |"
        )
    m = training["machine"]
    lines += [
        "",
        f"One torch thread; {m['cpu_count']} cores shared with other jobs (load average "
        f"{m['load_average_at_start']} at start).",
    ]
    return lines


def _summary(results: dict[str, Any]) -> list[str]:
    t = results["tightness"]
    parts = []
    for name, label in (("quad_landing", "quad-landing"), ("synthetic", "synthetic (known-oracle)")):
        if name in t:
            ipc, v1 = t[name]["ipc"], t[name]["ipc_v1"]
            mapie, mapie_v1 = ipc.get("mean_volume_ratio_to_mapie"), v1.get("mean_volume_ratio_to_mapie")
            smaller = 1 / ipc["mean_volume_ratio_to_global_mahalanobis"]
            parts.append(
                f"on the {label} data the default's calibrated sets are {fmt(mapie, 2)}× MAPIE's mean volume "
                f"(the earlier default: {fmt(mapie_v1, 2)}×) and {fmt(smaller, 3)}× smaller than the global "
                "ellipsoid's"
            )
    lines = ["Measured by the run of " + results["date_utc"][:10] + ": " + "; ".join(parts) + "."]
    syn = t.get("synthetic", {}).get("ipc")
    if syn is not None and "mean_volume_ratio_to_oracle" in syn:
        pac, exact = syn["mean_volume_ratio_to_oracle"], syn["mean_volume_ratio_to_oracle_exact"]
        same = syn.get("mean_volume_ratio_to_oracle_same_coverage")
        margin = t["synthetic"]["oracle"]["mean_volume_ratio_to_oracle_exact"]
        lines.append(
            f"Against the oracle (the true conditional law) on the synthetic data: {fmt(pac, 3)}× its mean "
            f"volume when the oracle is calibrated by the same PAC order statistic, {fmt(same, 3)}× the "
            "oracle at the coverage the IPC's sets actually reach, and "
            f"{fmt(exact, 3)}× the oracle at exactly 1 − ε (the order statistic's margin costs the oracle "
            f"itself {fmt(margin, 3)}×)."
        )
    return lines


def load_results() -> tuple[dict[str, Any], dict[str, Any] | None, dict[str, Any] | None]:
    """The committed ``results.json``, ``training_results.json`` and ``diagnosis_results.json``."""
    return _load("results.json"), _load("training_results.json"), _load("diagnosis_results.json")


def render_blocks(
    results: dict[str, Any], training: dict[str, Any] | None, diagnosis: dict[str, Any] | None = None
) -> dict[str, str]:
    """Every generated block's markdown, from the saved results."""
    tight = results["tightness"]
    blocks = {
        "bench-summary": _summary(results),
        "bench-table": _readme_table(tight),
        "latency-table": _latency_table(results["latency"]) if "latency" in results else [],
        "guard-latency": _guard_block(results.get("latency")),
        "before-after": before_after_table(tight),
        "diagnosis": diagnosis_table(tight),
        "shift": shift_table(results["shift"]) if "shift" in results else [],
        "targets": targets_table(results["targets"]),
        "run-info": [
            f"Numbers of the committed run (`{results['command']}`, {results['date_utc']}, "
            f"{results['runtime_seconds'] / 60:.1f} minutes): "
            "[benchmarks/results.md](../benchmarks/results.md)."
        ],
    }
    if training is not None:
        blocks["training"] = _training_table(training)
    if diagnosis is not None:
        blocks["diagnosis-recipes"] = diagnosis_runs_table(diagnosis)
    return {k: "\n".join(v) + "\n" for k, v in blocks.items()}


def demo_block(figure: Path | None = ROOT / "docs" / "img" / "demo_sets.png") -> str:
    """The console output of a real ``ipcverify demo`` run (80 columns), as a code block.

    The run's ``sets.png`` is copied to ``figure`` (the README's picture) unless it is None.
    It runs in a temporary directory with the default ``--out`` (``ipcverify-demo``), so that the
    last line, which lists the files, reads as a user's does.
    """
    with tempfile.TemporaryDirectory() as tmp:
        path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
        env = {**os.environ, "COLUMNS": "80", "TERM": "dumb", "NO_COLOR": "1", "PYTHONPATH": path}
        out = subprocess.run(
            [sys.executable, "-m", "ipcverify", "demo", "--out", "ipcverify-demo"],
            capture_output=True,
            text=True,
            env=env,
            cwd=tmp,
            check=True,
        ).stdout
        if figure is not None:
            figure.write_bytes((Path(tmp) / "ipcverify-demo" / "sets.png").read_bytes())
    return console_block(out)


def console_block(out: str) -> str:
    r"""A command's console output as a fenced code block: every line as printed, right-stripped.

    Examples
    --------
    >>> print(console_block("table  \nfiles in ipcverify-demo/: a.csv, \nsets.png\n"), end="")
    ```
    table
    files in ipcverify-demo/: a.csv,
    sets.png
    ```
    """
    lines = [ln.rstrip() for ln in out.splitlines()]
    return "```\n" + "\n".join(lines).strip("\n") + "\n```\n"


def replace_blocks(text: str, blocks: dict[str, str]) -> tuple[str, list[str]]:
    """``text`` with every known block replaced; also the names of the blocks that changed."""
    changed: list[str] = []

    def sub(m: re.Match[str]) -> str:
        name = m.group("name")
        if name not in blocks:
            return m.group(0)
        if m.group("body") != blocks[name]:
            changed.append(name)
        return m.group(1) + blocks[name] + m.group(4)

    return BLOCK.sub(sub, text), changed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--demo", action="store_true", help="also rerun `ipcverify demo` and paste its output")
    ap.add_argument("--check", action="store_true", help="report out-of-date blocks, write nothing")
    a = ap.parse_args(argv)
    blocks = render_blocks(*load_results())
    if a.demo:
        blocks["demo"] = demo_block()
    stale = []
    for doc in DOCUMENTS:
        text, changed = replace_blocks(doc.read_text(encoding="utf-8"), blocks)
        stale += [f"{doc.relative_to(ROOT)}:{name}" for name in changed]
        if changed and not a.check:
            doc.write_text(text, encoding="utf-8")
    print(("out of date: " if a.check else "rewrote: ") + (", ".join(stale) or "nothing"))
    return 1 if (a.check and stale) else 0


if __name__ == "__main__":
    raise SystemExit(main())
