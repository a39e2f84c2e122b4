"""A tiny report builder: one list of blocks rendered to Markdown and to self-contained HTML.

Building the document once as blocks (headings, paragraphs, tables, figures)
avoids parsing Markdown to make the HTML; figures are linked from the Markdown
and embedded (base64) in the HTML so the HTML file can be mailed on its own.
"""

from __future__ import annotations

import base64
import html
import math
import os
import re
from pathlib import Path

from .._io import atomic_write_text

__all__ = ["Report", "fmt", "axis_label", "unit_of"]

#: Column-name suffixes that carry a unit (``displacement_mm``, ``voltage_V``, ``temperature_front_C``).
_SUFFIX_UNITS = {
    "mm": "mm",
    "um": "µm",
    "m": "m",
    "V": "V",
    "mV": "mV",
    "A": "A",
    "mA": "mA",
    "W": "W",
    "C": "°C",
    "degC": "°C",
    "K": "K",
    "s": "s",
    "ms": "ms",
    "N": "N",
    "kPa": "kPa",
    "Pa": "Pa",
    "bar": "bar",
    "g": "g",
    "pct": "%",
    "percent": "%",
    "deg": "°",
}


#: A unit in brackets at the end of a column name: ``displacement [mm]``, ``stroke (mm)``.
_BRACKET_UNIT = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]+?)\s*[\])]\s*$")


def _name_and_unit(name, units=None):
    """``(name without its unit, unit)`` of column ``name``: the unit from the record's sidecar ``units``, else from
    brackets (``displacement [mm]``), else from a suffix such as ``_mm`` (``_V``, ``_C`` ...); ``(name, None)`` when
    none gives one."""
    name = str(name)
    if units and units.get(name):
        return name, str(units[name])
    bracket = _BRACKET_UNIT.match(name)
    if bracket and bracket.group(1):
        return bracket.group(1), bracket.group(2)
    base, sep, suffix = name.rpartition("_")
    unit = _SUFFIX_UNITS.get(suffix) if sep and base else None
    return (base, unit) if unit else (name, None)


def unit_of(name, units=None):
    """The unit of column ``name`` (sidecar, brackets or suffix: `_name_and_unit`); None when none gives one."""
    return _name_and_unit(name, units)[1] if name else None


def axis_label(name, units=None, *, prefix=""):
    """An axis label with a unit: ``displacement (mm)`` for ``displacement_mm`` or ``displacement [mm]``; a name
    without a known unit says so (``displacement (unit not given)``) instead of pretending to have one."""
    base, unit = _name_and_unit(name or "output", units)
    text = f"{prefix}{base.replace('_', ' ')}"
    return f"{text} ({unit})" if unit else f"{text} (unit not given)"


def fmt(x, digits=4):
    """Human formatting for report numbers (NaN/None shown as an en dash)."""
    if x is None:
        return "–"
    if isinstance(x, str):
        return x
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if not math.isfinite(x):
        return "–"
    if x != 0 and (abs(x) < 10 ** -(digits - 1) or abs(x) >= 10**6):
        return f"{x:.{digits - 1}e}"
    return f"{x:.{digits}g}"


class Report:
    """Ordered blocks of a report; `write` renders Markdown and HTML side by side."""

    def __init__(self, title):
        self.title = title
        self.blocks = []

    def heading(self, text, level=2):
        self.blocks.append(("h", level, text))

    def text(self, text):
        self.blocks.append(("p", text))

    def bullets(self, items):
        self.blocks.append(("ul", list(items)))

    def table(self, headers, rows):
        self.blocks.append(("table", list(headers), [[fmt(c) for c in r] for r in rows]))

    def figure(self, path, caption):
        # resolved now: a relative path would otherwise be joined to the report folder twice
        self.blocks.append(("fig", Path(path).resolve(), caption))

    # -- rendering -------------------------------------------------------
    def markdown(self, base: Path):
        out = [f"# {self.title}", ""]
        for b in self.blocks:
            if b[0] == "h":
                out += ["#" * b[1] + " " + b[2], ""]
            elif b[0] == "p":
                out += [b[1], ""]
            elif b[0] == "ul":
                out += [f"- {i}" for i in b[1]] + [""]
            elif b[0] == "table":
                out.append("| " + " | ".join(b[1]) + " |")
                out.append("|" + "---|" * len(b[1]))
                out += ["| " + " | ".join(r) + " |" for r in b[2]]
                out.append("")
            elif b[0] == "fig":
                rel = b[1].relative_to(base) if b[1].is_relative_to(base) else Path(os.path.relpath(b[1], base))
                out += [f"![{b[2]}]({rel.as_posix()})", "", f"*{b[2]}*", ""]
        return "\n".join(out)

    def html(self, base: Path):
        e = html.escape
        body = [f"<h1>{e(self.title)}</h1>"]
        for b in self.blocks:
            if b[0] == "h":
                body.append(f"<h{b[1]}>{e(b[2])}</h{b[1]}>")
            elif b[0] == "p":
                body.append(f"<p>{_inline(b[1])}</p>")
            elif b[0] == "ul":
                body.append("<ul>" + "".join(f"<li>{_inline(i)}</li>" for i in b[1]) + "</ul>")
            elif b[0] == "table":
                head = "".join(f"<th>{_inline(h)}</th>" for h in b[1])
                rows = "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>" for r in b[2])
                body.append(f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>")
            elif b[0] == "fig":
                data = base64.b64encode(b[1].read_bytes()).decode("ascii")
                body.append(
                    f'<figure><img alt="{e(b[2])}" src="data:image/png;base64,{data}"/>'
                    f"<figcaption>{_inline(b[2])}</figcaption></figure>"
                )
        style = (
            "body{font-family:system-ui,sans-serif;max-width:1000px;margin:2em auto;padding:0 1em;line-height:1.45}"
            "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}"
            "th{background:#eee}td:first-child,th:first-child{text-align:left}img{max-width:100%}"
            "figcaption{font-style:italic;color:#444}code{background:#f3f3f3;padding:0 3px}"
        )
        return (
            f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{e(self.title)}</title>"
            f"<style>{style}</style></head><body>{''.join(body)}</body></html>\n"
        )

    def write(self, md_path, html_path=None):
        md_path = Path(md_path)
        base = md_path.parent.resolve()
        atomic_write_text(md_path, self.markdown(base))
        if html_path is not None:
            atomic_write_text(html_path, self.html(base))


def _inline(text):
    """Escape HTML and render `code` and **bold** spans."""
    import re

    t = html.escape(str(text))
    t = re.sub(r"`([^`]+)`", r"<code>\1</code>", t)
    return re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", t)
