"""A report page read as a reader's browser reads it: the tables, headings, figures and
paragraphs in document order, parsed with the standard library's :mod:`html.parser` (so the
tests do not depend on how the markup is spelt: quotes, attribute order, whitespace)."""

from __future__ import annotations

from dataclasses import dataclass, field
from html.parser import HTMLParser


@dataclass
class Table:
    caption: str = ""
    header: list = field(default_factory=list)
    rows: list = field(default_factory=list)  # list of lists of cell texts
    classes: dict = field(default_factory=dict)  # (row, column) -> class attribute of the cell

    def text(self) -> str:
        """Caption, header and every cell, one string (for "is this text in the table")."""
        return " ".join([self.caption, *self.header, *(c for r in self.rows for c in r)])

    def column(self, name) -> list:
        j = self.header.index(name)
        return [r[j] for r in self.rows]


@dataclass
class Page:
    title: str = ""
    outline: list = field(default_factory=list)  # ("h1" | "h2" | "p" | "table" | "img", text or Table), in order
    meta: str = ""  # the paragraph of class "meta" under the title
    images: list = field(default_factory=list)  # the src of every image, in order

    @property
    def tables(self) -> list:
        return [t for kind, t in self.outline if kind == "table"]

    def position(self, kind, where=lambda value: True) -> int:
        """Index in :attr:`outline` of the first element of ``kind`` for which ``where`` holds."""
        for i, (k, v) in enumerate(self.outline):
            if k == kind and where(v):
                return i
        raise ValueError(f"no {kind} element found")

    def last_position(self, kind) -> int:
        return max(i for i, (k, _) in enumerate(self.outline) if k == kind)

    def table(self, caption_start) -> Table:
        """The first table whose caption starts with ``caption_start``."""
        return self.outline[self.position("table", lambda t: t.caption.startswith(caption_start))][1]

    def heading(self, text) -> int:
        return self.position("h2", lambda v: v == text)


class _Parser(HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.page = Page()
        self._text = None  # text being collected for the current element
        self._kind = None
        self._classes = None
        self._table = None
        self._row = None
        self._cell_class = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self._table = Table()
        elif tag == "tr" and self._table is not None:
            self._row = []
        elif tag in ("td", "th", "caption") and self._table is not None:
            self._kind, self._text, self._cell_class = tag, [], a.get("class")
        elif tag in ("h1", "h2", "p", "title") and self._table is None:
            self._kind, self._text, self._classes = tag, [], a.get("class")
        elif tag == "img":
            self.page.outline.append(("img", a.get("alt", "")))
            self.page.images.append(a.get("src", ""))

    def handle_data(self, data):
        if self._text is not None:
            self._text.append(data)

    def handle_endtag(self, tag):
        text = "".join(self._text or ()).strip()
        t = self._table
        if tag == "caption" and t is not None:
            t.caption = text
        elif tag in ("td", "th") and t is not None and self._row is not None:
            if self._cell_class:
                t.classes[(len(t.rows), len(self._row))] = self._cell_class
            self._row.append(text)
        elif tag == "tr" and t is not None and self._row is not None:
            if self._row and not t.header and not t.rows and self._kind == "th":
                t.header = self._row
            else:
                t.rows.append(self._row)
            self._row = None
        elif tag == "table" and t is not None:
            self.page.outline.append(("table", t))
            self._table = None
        elif tag == "title":
            self.page.title = text
        elif tag in ("h1", "h2", "p") and t is None and self._kind == tag:
            if tag == "p" and self._classes == "meta" and not self.page.meta:
                self.page.meta = text
            self.page.outline.append((tag, text))
        if tag in ("td", "th", "caption", "h1", "h2", "p", "title"):
            self._text = None


def parse_page(page: str) -> Page:
    """The :class:`Page` of an HTML document (a jointid report or a browser's dump of it)."""
    p = _Parser()
    p.feed(page)
    p.close()
    return p.page


def parse_tables(fragment: str) -> list:
    """The tables of an HTML fragment (e.g. one :func:`jointid.report.formatting.html_table`)."""
    return parse_page(fragment).tables
