"""What a report figure compares, and how the agreement is measured, stored in its PNG.

A figure that puts a model beside a measurement carries an error measure: error bars from
the standard errors, a shaded 95 % band, or a printed rms error.  The function that draws
it says so with :func:`mark_comparison`; the figure (a :class:`ReportFigure`) writes that
note into the text chunks of every PNG it is saved as (``savefig`` by any writer: the
campaign report, the demo, the example, the CLI), so a reader or a test finds it with
:func:`png_metadata` without knowing which code drew the figure.

Keys written (PNG ``tEXt``/``iTXt``):

``jointid:comparison``
    What is compared with what (``"identified damping law vs per-record damping"``).
``jointid:error_measure``
    The error measures drawn, ``"; "``-separated, each one of :data:`MEASURES`.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

from matplotlib.figure import Figure

__all__ = ["ReportFigure", "mark_comparison", "figure_metadata", "png_metadata", "MEASURES", "COMPARISON_KEY",
           "ERROR_MEASURE_KEY"]

COMPARISON_KEY = "jointid:comparison"
ERROR_MEASURE_KEY = "jointid:error_measure"

#: The error measures a comparison figure can carry, and what each shows.
MEASURES = {
    "stderr bars": "error bars: ± 1 standard error of each point",
    "ci95 bars": "error bars: 95 % interval of each point",
    "band95": "shaded band: 95 % interval of the model curve",
    "rms error": "rms error (or rms difference) printed in the legend or title",
    "error axis": "the plotted quantity is itself the error",
}

_ATTR = "jointid_metadata"


class ReportFigure(Figure):
    """A :class:`matplotlib.figure.Figure` whose saved PNG (or SVG) carries its comparison note."""

    def savefig(self, fname, *args, **kwargs):
        meta = figure_metadata(self)
        if meta:
            fmt = kwargs.get("format")
            if fmt is None and isinstance(fname, (str, os.PathLike)):
                fmt = Path(fname).suffix.lstrip(".") or None
            if fmt is None:
                import matplotlib

                fmt = matplotlib.rcParams["savefig.format"]
            fmt = str(fmt).lower()
            given = dict(kwargs.get("metadata") or {})
            if fmt == "png":
                kwargs["metadata"] = {**meta, **given}
            elif fmt == "svg":
                kwargs["metadata"] = {"Description": "; ".join(f"{k} = {v}" for k, v in meta.items()), **given}
        return super().savefig(fname, *args, **kwargs)


def _figure(fig_or_ax):
    obj = fig_or_ax
    if isinstance(obj, (list, tuple)) or hasattr(obj, "ravel"):
        import numpy as np

        obj = np.ravel(obj)[0]
    return obj if isinstance(obj, Figure) else obj.figure


def mark_comparison(fig_or_ax, comparison, *measures):
    """Record on a figure that it compares a model with a measurement, and its error measures.

    Parameters
    ----------
    fig_or_ax : Figure, Axes or array of Axes
    comparison : str
        What is compared with what.
    *measures : str
        Keys of :data:`MEASURES` (at least one).

    Returns
    -------
    Figure
    """
    if not measures:
        raise ValueError("a comparison figure needs at least one error measure")
    unknown = [m for m in measures if m not in MEASURES]
    if unknown:
        raise ValueError(f"unknown error measure(s) {unknown}; known: {sorted(MEASURES)}")
    fig = _figure(fig_or_ax)
    meta = dict(getattr(fig, _ATTR, None) or {})
    have = [m for m in meta.get(ERROR_MEASURE_KEY, "").split("; ") if m]
    meta[COMPARISON_KEY] = comparison if not meta.get(COMPARISON_KEY) or meta[COMPARISON_KEY] == comparison \
        else f"{meta[COMPARISON_KEY]}; {comparison}"
    meta[ERROR_MEASURE_KEY] = "; ".join(dict.fromkeys(have + list(measures)))
    setattr(fig, _ATTR, meta)
    return fig


def figure_metadata(fig_or_ax) -> dict:
    """The comparison note of a figure (empty for a figure that compares nothing)."""
    return dict(getattr(_figure(fig_or_ax), _ATTR, None) or {})


def png_metadata(png) -> dict:
    """Text chunks of a PNG (bytes or path), e.g. ``{"jointid:error_measure": "stderr bars"}``."""
    from PIL import Image

    data = Path(png).read_bytes() if isinstance(png, (str, os.PathLike)) else bytes(png)
    with Image.open(io.BytesIO(data)) as im:
        im.load()
        return dict(getattr(im, "text", {}) or {})
