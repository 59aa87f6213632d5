"""Small HTML building blocks of the estimator's self-contained reports (no web framework).

Every text that comes from data goes through :func:`escape`; figures are embedded as base64 PNG so a
report survives being mailed. The lab diagnosis report (:mod:`receptance.diagnosis.report`) follows the
same conventions.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

import numpy as np
import pandas as pd

from receptance.formatting import format_value

__all__ = ["CSS", "escape", "fmt_number", "table_html", "figure_html", "page"]

CSS = """
body{font-family:-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1150px;margin:2em auto;padding:0 1em;
color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em}
h2{font-size:1.3em;margin-top:2em;border-bottom:1px solid #bbb;padding-bottom:.15em}
table{border-collapse:collapse;margin:.6em 0 1em 0;font-size:.84em}
th,td{border:1px solid #ccc;padding:.2em .5em;text-align:left;vertical-align:top}
th{background:#eee}
td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1em 0} figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.85em;color:#555}
.box{background:#f6f8fa;border-left:4px solid #3a6ea5;padding:.6em 1em;margin:1em 0}
.warn{border-left-color:#c0392b}
.small{font-size:.85em;color:#555}
pre{background:#f6f8fa;padding:.6em;overflow-x:auto;font-size:.85em}
"""


def escape(x) -> str:
    return html.escape(str(x), quote=True)


def fmt_number(v, digits: int = 4) -> str:
    """A cell value, escaped: :func:`receptance.formatting.format_value` (numbers with ``digits`` significant
    digits, '–' for missing, yes/no for booleans)."""
    return escape(format_value(v, digits))


def table_html(df: pd.DataFrame | None, max_rows: int = 60) -> str:
    """A DataFrame as an HTML table (numbers right-aligned), truncated to ``max_rows`` with a note."""
    if df is None or df.empty:
        return "<p><i>none</i></p>"
    d = df.head(max_rows)
    head = "".join(f"<th>{escape(c)}</th>" for c in d.columns)
    rows = []
    for r in d.itertuples(index=False):
        cells = []
        for v in r:
            num = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))
            cells.append(f"<td class='num'>{fmt_number(v)}</td>" if num else f"<td>{escape(v)}</td>")
        rows.append("<tr>" + "".join(cells) + "</tr>")
    more = f"<p class='small'>… {len(df) - max_rows} more rows in the CSV files</p>" if len(df) > max_rows else ""
    return f"<table><tr>{head}</tr>{''.join(rows)}</table>{more}"


def figure_html(path: Path | None, caption: str) -> str:
    """An embedded PNG with its caption ('' when the file is missing)."""
    if path is None or not Path(path).is_file():
        return ""
    data = base64.b64encode(Path(path).read_bytes()).decode()
    return (f"<figure><img src='data:image/png;base64,{data}' alt='{escape(caption)}'>"
            f"<figcaption>{escape(caption)}</figcaption></figure>")


def page(title: str, body: list[str]) -> str:
    """A complete HTML document."""
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{escape(title)}</title><style>{CSS}</style>"
            f"</head><body>\n" + "\n".join(body) + "\n</body></html>")
