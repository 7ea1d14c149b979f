"""Measured backbones as targets of ``jointid update``: the file, and the model's nonlinear mode at its amplitudes.

A measured backbone (a ring-down analysed window by window, :mod:`jointid.signal.ringdown`) gives,
at each first-harmonic displacement amplitude of one DOF, the natural frequency and the damping
ratio of one mode with their standard errors (``BACKBONE.csv``, docs/formats.md "Measured
backbones for updating").  The amplitude is that of the named DOF of the structure model (m, or rad
for a rotation), not a modal coordinate: a modal amplitude depends on the normalisation of the
mode shapes, which a test and a model do not share.

The model side is the damped nonlinear mode of the extended periodic motion concept
(:func:`jointid.simulate.nlmodes.epmc_point`), whose amplitude is the first harmonic of the
mode's own mass-normalised modal coordinate.  At a measured DOF amplitude ``A`` the modal
amplitude is found by the fixed point ``a <- a A / |X_dof(a)|`` from ``a = A / |phi_r(dof)|``,
with ``X_dof`` the first harmonic of the DOF's displacement (all modes of the point: the other
modes' part makes ``|X_dof| / a`` differ slightly from ``|phi_r(dof)|``), to a relative 1e-10.
The points of one (DOF, mode) are solved in increasing amplitude, each started from the one before.
The model's frequency is the mode's ``omega / 2 pi`` and its damping ratio ``xi / (2 omega)``
(for a linear mode the natural frequency and modal damping ratio: what a ring-down window's
``|lambda|`` and ``sigma / |lambda|`` estimate).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import (
    ConvergenceError,
    ManifestError,
    RecordFileNotFoundError,
    StructureError,
)
from ..simulate.nlmodes import epmc_point
from ..simulate.structure_hb import to_complex

__all__ = ["BACKBONE_COLUMNS", "FRF_COLUMNS", "MeasuredBackbone", "backbone_curve", "backbone_response", "dof_cell",
           "measured_kind", "number_cell", "read_measured_backbone", "table_rows"]

BACKBONE_COLUMNS = ("dof", "amplitude", "frequency_hz", "se_frequency_hz", "damping_ratio", "se_damping_ratio")
FRF_COLUMNS = ("force_level", "frequency_hz", "dof", "a1", "b1", "se")


@dataclass(frozen=True, eq=False)
class MeasuredBackbone:
    """Backbone points: at ``amplitude`` (first harmonic of ``dof``'s displacement) of mode ``mode`` (1-based),
    the natural frequency and damping ratio with standard errors; ``line`` the file's line of each point."""

    path: str
    dof: tuple
    mode: np.ndarray
    amplitude: np.ndarray
    frequency_hz: np.ndarray
    se_frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    se_damping_ratio: np.ndarray
    line: np.ndarray

    @property
    def n(self) -> int:
        return int(self.amplitude.size)

    def z_scores(self, f, z):
        """``(z_f, z_zeta)``: model frequencies ``f`` and damping ratios ``z`` less the measured ones, over
        their standard errors."""
        return (np.asarray(f) - self.frequency_hz) / self.se_frequency_hz, \
            (np.asarray(z) - self.damping_ratio) / self.se_damping_ratio

    def subset(self, mask):
        m = np.asarray(mask, bool)
        return MeasuredBackbone(self.path, tuple(d for d, k in zip(self.dof, m) if k), self.mode[m],
                                self.amplitude[m], self.frequency_hz[m], self.se_frequency_hz[m],
                                self.damping_ratio[m], self.se_damping_ratio[m], self.line[m])


def read_rows(p, what="measured file"):
    """``(kept, rows)``: the file's non-blank, non-comment lines as ``(line number, text)`` and the CSV rows
    under its header; :class:`ManifestError` when it is not readable CSV."""
    if p.is_dir():
        raise ManifestError(f"{p}: {what} is a folder, not a file")
    if not p.is_file():
        raise RecordFileNotFoundError(f"{p}: {what} not found")
    try:  # utf-8-sig: a byte-order mark (a spreadsheet's "CSV UTF-8") is not part of the first line
        with open(p, newline="", encoding="utf-8-sig") as fh:
            kept = [(n, line) for n, line in enumerate(fh, start=1)
                    if line.strip() and not line.lstrip().startswith("#")]
        rows = list(csv.DictReader(line for _, line in kept))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ManifestError(f"{p}: cannot read as CSV ({exc})") from None
    return kept, rows


def table_rows(p, what, columns, optional=""):
    """``[(line number, row)]`` of a measured CSV file with every one of ``columns`` in its header;
    :class:`ManifestError` for no rows or a missing column."""
    kept, rows = read_rows(p, what)
    if not rows:
        raise ManifestError(f"{p}: no data rows")
    missing = [c for c in columns if c not in rows[0]]
    if missing:
        raise ManifestError(f"{p}: missing column(s) {', '.join(missing)} (needs {', '.join(columns)}{optional})")
    return [(i, r) for (i, _), r in zip(kept[1:], rows)]


def number_cell(p, i, r, c) -> float:
    """The finite number in column ``c`` of row ``r`` (line ``i`` of ``p``), or :class:`ManifestError`."""
    try:
        v = float(r[c])
    except (TypeError, ValueError):
        raise ManifestError(f"{p}: line {i}, column {c}: not a number ({r[c]!r})") from None
    if not math.isfinite(v):
        raise ManifestError(f"{p}: line {i}, column {c}: not finite")
    return v


def dof_cell(p, i, r) -> str:
    d = (r["dof"] or "").strip()
    if not d:
        raise ManifestError(f"{p}: line {i}, column dof: empty")
    return d


def measured_kind(path) -> str:
    """``"frf"`` or ``"backbone"`` from a measured file's header columns; otherwise :class:`ManifestError`."""
    p = Path(path)
    kept, _ = read_rows(p)
    if not kept:
        raise ManifestError(f"{p}: no header line (a measured file needs the columns of first harmonics "
                            f"{', '.join(FRF_COLUMNS)} or of a backbone {', '.join(BACKBONE_COLUMNS)})")
    cols = {c.strip() for c in next(csv.reader([kept[0][1]]))}
    if "force_level" in cols or "a1" in cols:
        return "frf"
    if "amplitude" in cols or "damping_ratio" in cols:
        return "backbone"
    raise ManifestError(f"{p}: neither first harmonics (columns {', '.join(FRF_COLUMNS)}) nor a backbone "
                        f"(columns {', '.join(BACKBONE_COLUMNS)}[, mode]); header: {', '.join(sorted(cols))}")


def read_measured_backbone(path) -> MeasuredBackbone:
    """Read a BACKBONE.csv; bad input -> :class:`ManifestError` naming the file, line and column."""
    p = Path(path)
    num = [c for c in BACKBONE_COLUMNS if c != "dof"]
    vals = {c: [] for c in num}
    dofs, modes, lines = [], [], []
    for i, r in table_rows(p, "measured backbone file", BACKBONE_COLUMNS, ", optional mode"):
        for c in num:
            v = number_cell(p, i, r, c)
            if c == "damping_ratio" and v <= 0:
                raise ManifestError(f"{p}: line {i}, column {c}: {'zero' if v == 0 else f'negative ({v:g})'}; a "
                                    "motion that does not decay is not a backbone point of a free decay")
            if v <= 0:
                raise ManifestError(f"{p}: line {i}, column {c}: must be > 0, got {v:g}")
            vals[c].append(v)
        d = dof_cell(p, i, r)
        m = (r.get("mode") or "1").strip()
        if not (m.isdigit() and int(m) >= 1):
            raise ManifestError(f"{p}: line {i}, column mode: expected a mode number 1, 2, ..., got {m!r}")
        dofs.append(d)
        modes.append(int(m))
        lines.append(i)
    return MeasuredBackbone(str(p), tuple(dofs), np.array(modes), *(np.array(vals[c]) for c in num),
                            np.array(lines))


def check_backbone(bb: MeasuredBackbone, model, source):
    """The DOFs and modes of ``bb`` exist in ``model`` (a StructureModel) and the DOF moves in the mode."""
    for d, r, ln in zip(bb.dof, bb.mode, bb.line):
        if d not in model.modal.dof_names:
            raise ManifestError(f"{bb.path}: line {ln}: dof {d!r} is not a DOF of the structure model {source}")
        if r > model.modal.n_modes:
            raise ManifestError(f"{bb.path}: line {ln}: mode {r}: the structure model {source} has "
                                f"{model.modal.n_modes} mode(s)")
        phi = model.modal.shape(d)
        if abs(phi[r - 1]) <= 1e-9 * np.abs(phi).max(initial=0.0):
            raise ManifestError(f"{bb.path}: line {ln}: dof {d!r} does not move in mode {r} of {source}")


def _dof_amplitude(model, dof, pt):
    return float(abs(to_complex(model.modal.shape(dof) @ pt.modal)[1]))


def backbone_response(model, bb: MeasuredBackbone, n_harmonics=9, n_time=None, rtol=1e-10, max_iter=12):
    """``(frequency [Hz], damping ratio)`` of ``model``'s nonlinear modes at the measured DOF amplitudes.

    Raises :class:`ConvergenceError` naming the file and line of a point that cannot be solved.
    """
    f = np.empty(bb.n)
    z = np.empty(bb.n)
    for key in sorted(set(zip(bb.dof, bb.mode.tolist()))):
        idx = [i for i in range(bb.n) if (bb.dof[i], int(bb.mode[i])) == key]
        idx.sort(key=lambda i: bb.amplitude[i])
        dof, r = key[0], key[1] - 1
        phi = float(model.modal.shape(dof)[r])
        prev = None
        for i in idx:
            A = float(bb.amplitude[i])
            a = A / abs(phi) if prev is None else prev.amplitude * A / _dof_amplitude(model, dof, prev)
            try:
                for _ in range(max_iter):
                    pt = epmc_point(model.engine, r, a, n_harmonics, n_time=n_time, guess=prev)
                    ratio = A / _dof_amplitude(model, dof, pt)
                    prev = pt
                    if abs(ratio - 1) <= rtol:
                        break
                    a *= ratio
                else:
                    raise ConvergenceError(f"the DOF amplitude did not settle in {max_iter} iterations")
            except (ConvergenceError, StructureError) as exc:
                raise ConvergenceError(f"{bb.path}: line {bb.line[i]}: the model's nonlinear mode {r + 1} cannot be "
                                       f"solved at {dof} amplitude {A:.6g} ({exc})") from None
            f[i] = pt.frequency_hz
            z[i] = pt.damping_ratio
    return f, z


def backbone_curve(model, bb: MeasuredBackbone, n_harmonics=9, n_time=None, n_points=40):
    """The model's nonlinear mode on a fine grid between the smallest and largest amplitude of ``bb``,
    for a figure: ``(amplitude, frequency_hz, damping_ratio)``; None for a file of several DOFs or
    modes, or when a grid point cannot be solved (the figure then joins the model's values at the
    measured points)."""
    if len(set(zip(bb.dof, bb.mode.tolist()))) != 1:
        return None
    dof, mode = bb.dof[0], int(bb.mode[0])
    amp = np.geomspace(bb.amplitude.min(), bb.amplitude.max(), n_points)
    ones = np.ones(n_points)
    grid = MeasuredBackbone(bb.path, (dof,) * n_points, np.full(n_points, mode), amp, ones, ones, ones, ones,
                            np.zeros(n_points, int))
    try:
        f, z = backbone_response(model, grid, n_harmonics, n_time)
    except (ConvergenceError, StructureError):
        return None
    return amp, f, z
