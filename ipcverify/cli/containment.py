"""CLI commands ``prove-containment`` and ``check-certificate``.

Thin wrappers over :mod:`ipcverify.decision.containment`: parse the JSON, call the library,
write or print the result. The JSON formats are described in ``docs/containment.md``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click

from ipcverify.cli.app import EXISTING_FILE, OUTPUT_FILE, app, console
from ipcverify.cli.outputs import check_outputs, force_option
from ipcverify.data._files import atomic_write
from ipcverify.decision.containment import prove, verify
from ipcverify.decision.containment._certificate import ContainmentCertificate, certificate_from_dict
from ipcverify.decision.containment._io import problem_from_dict
from ipcverify.decision.containment._status import Method, check_method
from ipcverify.errors import InvalidInputError

__all__ = ["load_json_items"]


def load_json_items(path: Path, what: str) -> list[Any]:
    """Read a JSON file holding one object or a list of objects.

    Raises
    ------
    InvalidInputError
        If the file is not valid JSON, not an object or a list, or an empty list (nothing to do).
    """
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InvalidInputError(f"{path}: not UTF-8 text; expected a JSON file") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidInputError(
            f"{path}: not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})"
        ) from None
    except RecursionError:
        raise InvalidInputError(f"{path}: JSON nested too deeply to read; expected {what} objects") from None
    except ValueError:  # an integer literal longer than Python converts (4300 digits)
        raise InvalidInputError(
            f"{path}: a number in it has more digits than can be read (over {sys.get_int_max_str_digits()}); "
            "write numbers as ordinary floats such as 1.5e3"
        ) from None
    if isinstance(data, dict):
        return [data]
    if isinstance(data, list) and not data:
        raise InvalidInputError(
            f"{path}: an empty list, no {what} in it; give one {what} object or a list of them"
        )
    if isinstance(data, list):
        return data
    raise InvalidInputError(f"{path}: expected one {what} object or a list of them")


def _fmt_margin(m: float | None) -> str:
    return "n/a" if m is None else f"{m:.3g}"


@app.command("prove-containment")
@click.argument("problems", type=EXISTING_FILE)
@click.option(
    "--out",
    type=OUTPUT_FILE,
    required=True,
    help="Where to write the certificates (.json: a list, same order as the problems).",
)
@force_option
@click.option(
    "--method",
    type=click.Choice([m.value for m in Method]),
    default=None,
    help="Method for the problems that do not name one: closed-form (boxes and polytopes; exact, "
    "the default), socp (cross-check) or sdp (S-lemma by Clarabel, re-checked exactly; the only "
    "one for ellipsoids).",
)
def prove_containment_cmd(problems: Path, out: Path, force: bool, method: str | None) -> None:
    """Prove or refute 'inner ellipsoid inside outer set' for every problem in PROBLEMS.

    PROBLEMS is a JSON object {"inner": ..., "outer": ...} or a list of them; the
    outer set is a box, a polytope or an ellipsoid. Each certificate says PROVEN,
    REFUTED (with a witness point) or UNKNOWN; re-check them with check-certificate.
    """
    outputs = check_outputs(
        [out], force=force, suffixes=(".json",), what="a JSON list", inputs={"PROBLEMS": problems}
    )
    items = load_json_items(problems, "problem")
    parsed = []
    names_own = []  # whether each problem names its own method (then --method is not used for it)
    for i, item in enumerate(items):
        try:
            inner, outer, own = problem_from_dict(item)
        except InvalidInputError as exc:
            raise InvalidInputError(f"{problems}: problem {i}: {exc}") from None
        chosen = own if own is not None or method is None else Method(method)
        if chosen is not None and own is None:  # a problem's own method was checked when parsed
            try:
                check_method(chosen, outer)
            except InvalidInputError as exc:
                hint = f"--method {method}; or give the problem its own 'method'"
                raise InvalidInputError(f"{problems}: problem {i}: {exc} ({hint})") from None
        parsed.append((inner, outer, chosen))
        names_own.append(own is not None)
    if method is not None and all(names_own):
        raise InvalidInputError(
            f"--method {method} applies to no problem: every problem in {problems} names its own 'method'; "
            "leave --method out"
        )
    certs: list[ContainmentCertificate] = []
    for inner, outer, chosen in parsed:
        certs.append(prove(inner, outer, method=chosen))
    # one certificate per line: readable, and floats round-trip exactly (json uses repr)
    lines = [json.dumps(c.to_dict(), allow_nan=False) for c in certs]
    payload = "[\n" + ",\n".join(lines) + "\n]\n"
    atomic_write(out, lambda f: f.write(payload), mode="w")
    for i, c in enumerate(certs):
        console.print(
            f"problem {i}: {c.status.value} ({c.method.value}, {type(c.outer).__name__.lower()}, "
            f"margin {_fmt_margin(c.margin)})",
            markup=False,
            highlight=False,
        )
    counts = {s: sum(c.status.value == s for c in certs) for s in ("PROVEN", "REFUTED", "UNKNOWN")}
    console.print(
        f"wrote {len(certs)} certificates to {out}: " + ", ".join(f"{v} {k}" for k, v in counts.items()),
        markup=False,
        highlight=False,
    )
    outputs.announce()


@app.command("check-certificate")
@click.argument("certificates", type=EXISTING_FILE)
def check_certificate_cmd(certificates: Path) -> None:
    """Re-verify every certificate in CERTIFICATES in exact rational arithmetic.

    Exits with status 1 if any certificate claims PROVEN or REFUTED and the exact
    check does not support the claim (the failing ones are named).
    """
    items = load_json_items(certificates, "certificate")
    certs = []
    for i, item in enumerate(items):
        try:
            certs.append(certificate_from_dict(item))
        except InvalidInputError as exc:
            raise InvalidInputError(f"{certificates}: certificate {i}: {exc}") from None
    failed = []
    for i, cert in enumerate(certs):
        v = verify(cert)
        if v.ok:
            line = f"certificate {i}: {cert.status.value} re-verified ({v.reason})"
        else:
            failed.append(i)
            line = (
                f"certificate {i}: FAILED: claims {cert.status.value} but the exact check gives "
                f"{v.status.value} ({v.reason})"
            )
        console.print(line, markup=False, highlight=False, soft_wrap=True)
    if failed:
        console.print(
            f"{len(failed)} of {len(certs)} certificates failed: " + ", ".join(str(i) for i in failed),
            markup=False,
            highlight=False,
        )
        raise click.exceptions.Exit(1)
    console.print(f"all {len(certs)} certificates re-verified", markup=False, highlight=False)
