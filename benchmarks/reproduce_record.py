"""The full reproduction's headline numbers, kept beside the docs that quote them.

A full ``python -m case_studies.quad_landing reproduce`` takes about six minutes and writes a
``summary.json`` of about 0.7 MB, which is not committed. This script extracts from it what
docs/reproduce_results.md and the README quote: per contract Table I (rates and counts), the landings
(Monte Carlo and paper-style), the hover half-widths and the certified bound on unsafe landings;
the baseline's landings; and the summary's format version (times are not kept: they come from
``python -m benchmarks.bench_commands --full`` on an idle machine). It writes
``benchmarks/reproduce_full_results.json``; ``tests/benchmarks/test_reproduce_record.py`` checks
the pages against that record, so a stale number in them fails a test.

Run ``python -m case_studies.quad_landing reproduce --out DIR --fly-uncalibrated``, then
``python -m benchmarks.reproduce_record DIR/summary.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from benchmarks.common import write_json

__all__ = ["OUT", "extract", "main"]

OUT = Path(__file__).with_name("reproduce_full_results.json")
_OUTCOMES = ("runs", "safe", "unsafe", "aborted")


def _outcomes(record: dict[str, Any] | None) -> dict[str, int] | None:
    return None if record is None else {k: int(record[k]) for k in _OUTCOMES}


def extract(summary: dict[str, Any]) -> dict[str, Any]:
    """The headline numbers of a reproduction's ``summary.json``.

    Parameters
    ----------
    summary : dict
        The parsed ``summary.json`` of a full (not ``--quick``) reproduction.

    Returns
    -------
    dict
        ``version``, ``baseline`` (landing outcomes at
        buffer size 1) and per contract ``table1`` (buffer size -> rate), ``table1_counts``
        (buffer size -> [violations, measurements]), ``landing`` and ``landing_paper_runs``
        (outcomes), ``hover_half_widths_median`` (m) and ``certified`` (the union bound and the
        refined one, or None for a contract without a guarantee).

    Raises
    ------
    ValueError
        If the summary is of a ``--quick`` run, whose numbers the docs do not quote.
    """
    if summary.get("quick"):
        raise ValueError("this summary is of a --quick run; the docs quote the full reproduction")
    contracts = {}
    for name, c in summary["contracts"].items():
        detail = c.get("table1_detail") or {}
        evc = c.get("empirical_vs_certified")
        contracts[name] = {
            "table1": c["table1"],
            "table1_counts": {b: [int(d["violations"]), int(d["n"])] for b, d in detail.items()},
            "landing": _outcomes(c.get("landing")),
            "landing_paper_runs": _outcomes(c.get("landing_paper_runs")),
            "hover_half_widths_median": c["hover_half_widths"]["median"],
            "certified": None
            if evc is None
            else {"union": evc["certified_union"], "refined": evc["certified_refined"]},
        }
    return {
        "version": summary["version"],
        "baseline": _outcomes(summary["landing"]["baseline"]),
        "contracts": contracts,
    }


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Read a full reproduction's ``summary.json`` and write the record.

    Parameters
    ----------
    argv : list of str, optional
        ``SUMMARY [--out FILE]`` (default benchmarks/reproduce_full_results.json).

    Returns
    -------
    dict
        The record written.
    """
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("summary", type=Path)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    record = extract(json.loads(args.summary.read_text()))
    write_json(args.out, record)
    return record


if __name__ == "__main__":
    main()
