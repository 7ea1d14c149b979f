"""Self-contained HTML reports: figures embedded as base64 PNG, every text escaped.

A report is a list of sections; a section has a title, paragraphs, tables (lists of dicts,
rendered by :func:`jointid.report.formatting.html_table`, the one HTML table builder) and
matplotlib figures.  The page needs no network and no files beside it.
"""

from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass, field

from ..io.results import atomic_write
from .formatting import html_table

__all__ = ["Section", "render_html", "write_html", "figure_to_data_uri", "figure_to_png", "page_meta"]

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em auto;max-width:1100px;color:#222;
line-height:1.45;padding:0 1em}
h1{font-size:1.6em;border-bottom:2px solid #345;padding-bottom:.3em}
h2{font-size:1.25em;margin-top:2em;color:#234}
table{border-collapse:collapse;margin:.8em 0;font-size:.9em}
th,td{border:1px solid #bbb;padding:.25em .6em;text-align:right}
th{background:#eef2f6}
td.text{text-align:left}
figure{display:inline-block;margin:.5em 1em .5em 0;vertical-align:top}
figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.85em;color:#555;max-width:520px}
.note{color:#555;font-size:.9em}
.meta{color:#555;font-size:.85em;margin-top:-.6em}
caption{text-align:left;font-weight:600;padding:.2em 0}
nav a{margin-right:1em}
"""


@dataclass
class Section:
    """One section of a report (built up by the report writer, then rendered once)."""

    title: str
    paragraphs: list = field(default_factory=list)
    tables: list = field(default_factory=list)  # (caption, rows: list[dict], columns or None)
    figures: list = field(default_factory=list)  # (caption, matplotlib figure or PNG bytes)


def figure_to_png(fig, dpi=110) -> bytes:
    """PNG bytes of a matplotlib figure."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def figure_to_data_uri(fig, dpi=110) -> str:
    """``data:`` URI of a figure, or of PNG bytes already rendered."""
    png = bytes(fig) if isinstance(fig, (bytes, bytearray)) else figure_to_png(fig, dpi)
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def page_meta(run_id=None) -> dict:
    """Version of jointid, the UTC date and time, and the run id shown at the top of a report."""
    import time

    from .. import __version__

    meta = {"jointid": __version__, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    if run_id:
        meta["run id"] = str(run_id)
    return meta


def render_html(title: str, sections, intro: str = "", meta=None) -> str:
    """The whole page as a string; ``meta`` (default :func:`page_meta`) is shown under the title."""
    meta = page_meta() if meta is None else meta
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        "<p class='meta'>" + " · ".join(f"{html.escape(k)} {html.escape(str(v))}" for k, v in meta.items()) + "</p>",
    ]
    if intro:
        parts.append(f"<p>{html.escape(intro)}</p>")
    parts.append("<nav>" + "".join(f"<a href='#s{i}'>{html.escape(s.title)}</a>" for i, s in enumerate(sections))
                 + "</nav>")
    for i, s in enumerate(sections):
        parts.append(f"<h2 id='s{i}'>{html.escape(s.title)}</h2>")
        parts += [f"<p>{html.escape(p)}</p>" for p in s.paragraphs]
        parts += [html_table(rows, cols, caption=c, css_class=None, empty="no rows") for c, rows, cols in s.tables]
        for caption, fig in s.figures:
            parts.append(f"<figure><img alt='{html.escape(caption, quote=True)}' src='{figure_to_data_uri(fig)}'>"
                         f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_html(path, title, sections, intro="", meta=None) -> None:
    """Render and write the page atomically."""
    atomic_write(path, render_html(title, sections, intro, meta))
