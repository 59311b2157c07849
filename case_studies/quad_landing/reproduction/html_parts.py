"""The pieces every HTML page of the reproduction is built from: escaping, numbers, tables, figures.

Examples
--------
>>> table(["a", "b"], [["x", pct(0.5)]]).count("<td")
2
>>> pct(0.5), interval((0.0, 0.0125))
('50.00 %', '[0.00, 1.25] %')
"""

from __future__ import annotations

import base64
import html
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["CSS", "esc", "pct", "num", "interval", "table", "figure", "yes"]

#: The page style (serif text, compact numeric tables).
CSS = """
body{font-family:Georgia,'Times New Roman',serif;max-width:1000px;margin:2em auto;padding:0 1.2em;
color:#1d1d1f;line-height:1.5;font-size:16px}
h1{font-size:1.7em;margin-bottom:.2em} h2{font-size:1.3em;margin-top:2em;border-bottom:1px solid #ccc}
h3{font-size:1.08em;margin-top:1.4em} p.lead{font-size:1.05em}
table{border-collapse:collapse;margin:.6em 0 1.2em;font-family:system-ui,sans-serif;font-size:.88em}
td,th{border:1px solid #bbb;padding:.28em .6em;text-align:right;font-variant-numeric:tabular-nums;
white-space:nowrap} th{background:#eef1f5;white-space:normal} td.l,th.l{text-align:left;white-space:normal}
div.wide{max-width:100%;overflow-x:auto}
caption{caption-side:top;text-align:left;font-style:italic;padding-bottom:.3em}
.ok{color:#1b7f3b;font-weight:600} .no{color:#b42318;font-weight:600} .muted{color:#555;font-size:.92em}
figure{margin:1em 0} figure img{max-width:100%} figcaption{font-size:.9em;color:#333}
.box{background:#f5f7fa;border-left:4px solid #1b5e7f;padding:.5em 1em;margin:.9em 0}
"""


def esc(v: Any) -> str:
    """HTML-escaped ``str(v)``."""
    return html.escape(str(v))


def pct(v: Any, digits: int = 2) -> str:
    """A share as a percentage (``—`` for None)."""
    return "—" if v is None else f"{100 * float(v):.{digits}f} %"


def num(v: Any, digits: int = 4) -> str:
    """A number with ``digits`` significant digits; booleans as yes / no; None as ``—``."""
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    return f"{float(v):.{digits}g}"


def interval(iv: Sequence[float] | None) -> str:
    """An interval of shares in percent."""
    return "—" if not iv else f"[{100 * iv[0]:.2f}, {100 * iv[1]:.2f}] %"


def table(
    header: Sequence[str], rows: Sequence[Sequence[Any]], caption: str = "", text: Sequence[int] = (0,)
) -> str:
    """A table with a header row; the columns in ``text`` are left-aligned and wrap, the rest are numbers."""

    def cls(i: int) -> str:
        return ' class="l"' if i in text else ""

    th = "".join(f"<th{cls(i)}>{esc(h)}</th>" for i, h in enumerate(header))
    body = "".join("<tr>" + "".join(f"<td{cls(i)}>{c}</td>" for i, c in enumerate(r)) + "</tr>" for r in rows)
    cap = f"<caption>{esc(caption)}</caption>" if caption else ""
    return f'<div class="wide"><table>{cap}<thead><tr>{th}</tr></thead><tbody>{body}</tbody></table></div>'


def figure(figs: Mapping[str, bytes], name: str, caption: str) -> str:
    """The PNG ``figs[name]`` inlined as base64 with its caption (empty if there is no such figure)."""
    if name not in figs:
        return ""
    data = base64.b64encode(figs[name]).decode("ascii")
    return (
        f'<figure><img alt="{esc(caption)}" src="data:image/png;base64,{data}">'
        f"<figcaption>{esc(caption)}</figcaption></figure>"
    )


def yes(v: Any) -> str:
    """A green *yes* or a red *no*."""
    return '<span class="ok">yes</span>' if v else '<span class="no">no</span>'
