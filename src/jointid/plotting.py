"""The plotting protocol: how objects of the lower floors reach their drawing functions.

Results of ``signal``, ``modal``, ``identify`` and ``simulate`` offer conveniences such as
``result.plot()`` or a notebook display (``_repr_html_``).  The drawing itself lives in
:mod:`jointid.report`, a floor above them, which they must not import.  They call
:func:`draw` (or :func:`resolve`) with the *name* of a drawing function instead; this module
looks the name up in :data:`DRAWERS`, the one table of every such function, and imports the
module it names only when the drawing is asked for.

The table is deliberately short and named: a new ``.plot()`` convenience adds one entry here,
pointing into ``jointid.report`` (never into ``app`` or ``cli``; the architecture test checks
this), and calls ``plotting.draw("<module>.<function>", obj, ...)``.  This module imports only
the standard library and :mod:`jointid.errors`, so any floor may use it.
"""

from __future__ import annotations

import importlib

from .errors import JointidError

__all__ = ["DRAWERS", "PlottingError", "resolve", "draw"]

#: Drawing functions reachable from the lower floors: ``"<report module>.<function>"`` ->
#: ``"<importable module>:<attribute>"``.
DRAWERS: dict[str, str] = {
    # signal, modal
    "modal_plots.plot_frf": "jointid.report.modal_plots:plot_frf",
    "modal_plots.plot_mode_shapes": "jointid.report.modal_plots:plot_mode_shapes",
    "modal_plots.plot_update_residuals": "jointid.report.modal_plots:plot_update_residuals",
    # identify
    "backbone_plots.plot_backbone": "jointid.report.backbone_plots:plot_backbone",
    "data_plots.plot_broadband_fit": "jointid.report.data_plots:plot_broadband_fit",
    "data_plots.plot_gain_fit": "jointid.report.data_plots:plot_gain_fit",
    "identify_plots.new_axes": "jointid.report.identify_plots:new_axes",
    "identify_plots.plot_damping_law": "jointid.report.identify_plots:plot_damping_law",
    "identify_plots.plot_hysteresis": "jointid.report.identify_plots:plot_hysteresis",
    "identify_plots.plot_per_record": "jointid.report.identify_plots:plot_per_record",
    "identify_plots.plot_power_law": "jointid.report.identify_plots:plot_power_law",
    "notebook.result_html": "jointid.report.notebook:result_html",
    "selection_plots.plot_level_equality": "jointid.report.selection_plots:plot_level_equality",
    "selection_plots.plot_selection": "jointid.report.selection_plots:plot_selection",
    # simulate
    "frf_plots.plot_frequency_response": "jointid.report.frf_plots:plot_frequency_response",
}


class PlottingError(JointidError, LookupError):
    """A drawing function was asked for by a name the plotting table does not hold."""


def resolve(name: str):
    """The drawing function registered under ``name`` (its module is imported now)."""
    try:
        target = DRAWERS[name]
    except KeyError:
        known = ", ".join(sorted(DRAWERS))
        raise PlottingError(f"no drawing function named {name!r} in jointid.plotting.DRAWERS; known: {known}") from None
    module, _, attribute = target.partition(":")
    return getattr(importlib.import_module(module), attribute)


def draw(name: str, *args, **kwargs):
    """Call the drawing function registered under ``name`` with ``args`` and ``kwargs``."""
    return resolve(name)(*args, **kwargs)
