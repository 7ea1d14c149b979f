"""Records outside the stepped-sine chain that could not be used: one line each for the console.

Broadband records (:mod:`jointid.app.broadband_records`) and ring-down records (identified
with the backbones, :mod:`jointid.app.backbones`) are not in ``result.records``; a flagged or
failed one must still make the run a partial one (exit 1) and be listed, like a flagged
stepped-sine record.
"""

from __future__ import annotations

from .broadband_records import broadband_problem_lines

__all__ = ["problem_lines"]


def ringdown_problem_lines(backbones) -> list:
    """One line per ring-down record the backbones could not use (its error, with the numbers)."""
    lines = []
    for p in getattr(backbones, "preloads", ()) or ():
        for key, message in (getattr(p, "errors", None) or {}).items():
            if str(key).startswith("record "):
                lines.append(f"ring-down preload {p.preload}, {key}: {message}")
    return lines


def problem_lines(result) -> list:
    """Broadband and ring-down problems of a :class:`~jointid.app.workflow.CampaignResult` (empty when none)."""
    return broadband_problem_lines(getattr(result, "broadband", ())) + ringdown_problem_lines(
        getattr(result, "backbones", None)) + first_harmonic_problem_lines(result)


def first_harmonic_problem_lines(result) -> list:
    """One line per preload of a first-harmonic campaign whose model could not be fitted."""
    if not hasattr(result, "write_set"):  # only a first-harmonic result writes its own set
        return []
    return [f"preload {p.preload}: not identified: {p.errors['fit']}" for p in getattr(result, "preloads", ())
            if "fit" in (getattr(p, "errors", None) or {})]
