"""A self-contained HTML page from sections of text, tables and figures (figures embedded as base64
PNG, so the file can be mailed or archived alone). Plain Python and ``html.escape``: no templates."""

from __future__ import annotations

import base64
import html
from collections.abc import Callable, Mapping
from pathlib import Path

import pandas as pd

STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1000px; margin: 2em auto; padding: 0 1em;
       color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { margin-top: 2em; border-bottom: 1px solid #ccc; } h3 { font-size: 1.05em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; }
th { background: #f3f3f3; text-align: left; } td { text-align: left; } td.n { text-align: right; }
.note { color: #555; font-size: 0.9em; } .problem { background: #fff4e5; border-left: 4px solid #e69500;
        padding: 0.5em 1em; } figure { margin: 1em 0; } img { max-width: 100%; }
figcaption { font-size: 0.85em; color: #555; }
.banner { background: #ffe3e3; border: 2px solid #c92a2a; padding: 0.8em 1em; font-weight: bold; }
"""

Formatter = Callable[[object], str]


def text(value: str) -> str:
    return html.escape(value)


def paragraph(value: str, css: str = "") -> str:
    return f'<p class="{css}">{text(value)}</p>' if css else f"<p>{text(value)}</p>"


def items(values: list[str], css: str = "") -> str:
    inner = "".join(f"<li>{text(v)}</li>" for v in values)
    return f'<ul class="{css}">{inner}</ul>'


def cell(value: object) -> str:
    """A table cell's text: '' for missing values, 2 decimals for floats."""
    if value is None or (not isinstance(value, str) and pd.isna(value)):
        return ""
    if isinstance(value, float):
        return f"{value:.2f}"
    return str(value)


def table(frame: pd.DataFrame, headers: Mapping[str, str],
          formats: Mapping[str, Formatter] | None = None) -> str:
    """``frame``'s columns named in ``headers`` (column → heading), formatted by ``formats``."""
    formats = formats or {}
    head = "".join(f"<th>{text(h)}</th>" for h in headers.values())

    def td(value: object, column: str) -> str:
        numeric = pd.api.types.is_number(value) and not pd.api.types.is_bool(value)
        return f'<td{" class=n" if numeric else ""}>{text(formats.get(column, cell)(value))}</td>'

    body = "".join("<tr>" + "".join(td(row[c], c) for c in headers) + "</tr>"
                   for _, row in frame.iterrows())
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def figure(png: Path, caption: str) -> str:
    data = base64.b64encode(Path(png).read_bytes()).decode("ascii")
    return (f'<figure><img src="data:image/png;base64,{data}" alt="{text(caption)}">'
            f"<figcaption>{text(caption)}</figcaption></figure>")


def section(title: str, *parts: str, level: int = 2) -> str:
    return f"<h{level}>{text(title)}</h{level}>" + "".join(parts)


def page(title: str, *parts: str) -> str:
    return ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{text(title)}</title><style>{STYLE}</style></head><body>"
            f"<h1>{text(title)}</h1>{''.join(parts)}</body></html>\n")
