"""The modal workflow of a structure description (``jointid modal``).

:func:`modal_workflow` reads a TOML file with a ``[structure]`` table (a ``campaign.toml``
works), builds the :class:`~jointid.modal.structure.Structure` (FE modes, updating, sensor
shapes) and, with a random-excitation record, estimates the H1 FRF of one response channel
and fits its modes (:func:`jointid.signal.frf.h1_estimate`, :func:`jointid.signal.frf.fit_modes`).
:func:`write_modal` writes ``modal.json`` and the mode-shape, updating and FRF figures.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import IdentificationError

__all__ = ["ModalRun", "parse_bands", "check_bands", "modal_workflow", "write_modal"]


def parse_bands(text: str) -> list:
    """Explicit fit bands in Hz: ``"24-29,140-175"`` -> ``[(24.0, 29.0), (140.0, 175.0)]``.

    The bands are checked by :func:`check_bands` (finite, ``0 < LO < HI``, no two sharing frequencies).
    """
    bands = []
    for part in text.split(","):
        try:
            lo, hi = (float(v) for v in part.strip().split("-"))
        except ValueError:
            raise IdentificationError(f"--bands: expected LO-HI pairs in Hz separated by commas, got {part!r}") from None
        bands.append((lo, hi))
    return check_bands(bands)


def check_bands(bands) -> list:
    """The fit bands ``[(lo, hi), ...]`` in Hz, refused when one is not ``0 < lo < hi`` (finite) or two overlap.

    A band given twice, or two bands sharing frequencies, would fit one mode twice and report
    it as two; bands that only touch (``hi`` of one equals ``lo`` of the next) are accepted.
    """
    out = []
    for band in bands:
        try:
            lo, hi = (float(v) for v in band)
        except (TypeError, ValueError):
            raise IdentificationError(f"--bands: expected (LO, HI) pairs in Hz, got {band!r}") from None
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
            raise IdentificationError(f"--bands: expected finite 0 < LO < HI, got {lo:g}-{hi:g}")
        out.append((lo, hi))
    order = sorted(range(len(out)), key=lambda i: out[i])
    for a, b in zip(order, order[1:]):
        (lo1, hi1), (lo2, hi2) = out[a], out[b]
        if lo2 < hi1:
            what = "is given twice" if (lo1, hi1) == (lo2, hi2) else f"overlaps band {b + 1} ({lo2:g}-{hi2:g} Hz)"
            raise IdentificationError(f"--bands: band {a + 1} ({lo1:g}-{hi1:g} Hz) {what}; each band holds one "
                                      f"mode, so the bands may not share frequencies")
    return out


@dataclass(frozen=True)
class ModalRun:
    """A structure's modes and, with a record, its H1 FRF and the modes fitted to it."""

    structure: object  # Structure
    frf: object = None  # FRFEstimate of the record's response channel
    fit: object = None  # ModalFit of the FRF
    record: str | None = None
    channel: str | None = None

    def summary(self) -> dict:
        """The content of ``modal.json``."""
        d = {"structure": self.structure.summary()}
        if self.fit is not None:
            d["frf_fit"] = {"frequencies_hz": self.fit.frequencies_hz, "damping_ratios": self.fit.damping_ratios,
                            "record": self.record, "channel": self.channel, "h1": self.frf.summary(),
                            **self.fit.summary()}
        return d

    def frf_report(self) -> str:
        """The FRF fit's text ('' without a record)."""
        if self.fit is None:
            return ""
        from ..report.formatting import format_percent, format_value

        lines = [f"\nH1 of {self.channel!r} in {self.record}: {self.frf.report()}", self.fit.report()]
        for i, (f, z, ok) in enumerate(zip(self.fit.frequencies_hz, self.fit.damping_ratios, self.fit.trusted), 1):
            lines.append(f"  mode {i}: {format_value(f, 6)} Hz, damping ratio {format_percent(100 * z)}"
                         f"{'' if ok else ' (NOT trusted)'}")
        return "\n".join(lines)

    def report(self) -> str:
        text = self.structure.report()
        return text + ("\n" + self.frf_report() if self.fit is not None else "")

    def figures(self) -> list:
        """``(file name, matplotlib figure)`` of the mode shapes, the updating residuals and the FRF fit."""
        from ..report.modal_plots import plot_frf, plot_mode_shapes, plot_update_residuals

        s, out = self.structure, []
        if s.modes is not None:
            fig, _ = plot_mode_shapes(s.modes, sensors=dict(s.sensors), force_position=s.force_position)
            out.append(("mode_shapes.png", fig))
        if s.update is not None:
            out.append(("updating_residuals.png", plot_update_residuals(s.update)[0]))
        if self.fit is not None:
            out.append(("frf.png", plot_frf(self.frf, fit=self.fit)[0]))
        return out


def modal_workflow(structure_file, *, frf=None, response=None, modes=3, bands=None, f_range=None, order=8,
                   nperseg=None, min_coherence=0.8, echo=None) -> ModalRun:
    """The structure of ``structure_file`` and, with ``frf`` (a record file), its H1 FRF and modal fit.

    Parameters
    ----------
    structure_file : path
        TOML with a ``[structure]`` table.
    frf : path, optional
        A random-excitation record (time, force, responses).
    response : str, optional
        Its response column (default: the structure's first sensor).
    modes : int
        Modes fitted in the FRF (ignored with ``bands``).
    bands : str or sequence of (lo, hi), optional
        Explicit fit bands in Hz, one per mode (text as :func:`parse_bands`).
    f_range, order, nperseg, min_coherence
        Passed to :func:`~jointid.signal.frf.fit_modes` (``f_range``, ``max_order``, ``min_coherence``)
        and :func:`~jointid.signal.frf.h1_estimate` (``nperseg``).
    echo : callable, optional
        Called with each part of the report as soon as it is known (the structure's before the FRF's).
    """
    from ..io.campaign import read_toml
    from ..modal.structure import Structure

    if isinstance(bands, str):  # refused before any work
        bands = parse_bands(bands)
    elif bands is not None:
        bands = check_bands(bands)
    data = read_toml(structure_file, "structure file")
    structure = Structure.from_mapping(data, source=str(structure_file))
    if echo is not None:
        echo(structure.report())
    if frf is None:
        return ModalRun(structure)
    from ..io.campaign import RecordSpec, read_record
    from ..signal.frf import fit_modes, h1_estimate

    frf = Path(frf)
    column = response or next(iter(structure.sensors))
    spec = RecordSpec(0, str(frf), frf.resolve(), None, None, None)
    rec = read_record(spec, required=("time", structure.force_column, column))
    fs = 1.0 / float(np.mean(np.diff(rec.time)))
    if nperseg is not None and 2 * nperseg > rec.time.size:  # one segment: coherence 1 whatever the data
        raise IdentificationError(f"{frf}: --nperseg {nperseg} leaves fewer than two averages in the record's "
                                  f"{rec.time.size} samples (H1 and its coherence need several); give at most "
                                  f"{rec.time.size // 2}")
    try:
        h1 = h1_estimate(rec.channels[structure.force_column], rec.channels[column], fs, nperseg=nperseg)
        fit = fit_modes(h1, None if bands else modes, bands=bands, f_range=f_range, max_order=order,
                        min_coherence=min_coherence)
    except (IdentificationError, ValueError) as exc:
        raise IdentificationError(f"{frf}: H1 of channel {column!r}: {exc}") from None
    run = ModalRun(structure, h1, fit, str(frf), column)
    if echo is not None:
        echo(run.frf_report())
    return run


def write_modal(run: ModalRun, out) -> list:
    """``modal.json`` and the figures of ``run`` into the folder ``out``; returns the paths written."""
    from ..io.results import atomic_savefig, write_json

    out = Path(out)
    paths = [out / "modal.json"]
    write_json(paths[0], run.summary())
    for name, fig in run.figures():
        atomic_savefig(fig, out / name, dpi=120)
        paths.append(out / name)
    return paths
