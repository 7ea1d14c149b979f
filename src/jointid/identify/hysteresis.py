"""Hysteresis loops: restoring force minus its linear stiffness part vs displacement (seed Figs 17-19).

For one steady-state period of a record:

* measured loop: ``Q(t) - q''(t) - omega1^2 q(t)``; "filtered" uses the harmonic fits of
  both force and acceleration over one period (the seed's filtered loops); "unfiltered"
  uses the raw samples with every harmonic kept, averaged synchronously over all the
  periods of the record in phase bins (up to 256 a period) so that measurement noise
  does not hide the loop;
* identified loop: the identified terms other than ``q`` (``c q' - k3 q^3`` for the seed
  model) evaluated on the same ``q, q'``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..signal.harmonics import StateSignals, fit_harmonics
from .terms import library

__all__ = ["HysteresisLoop", "hysteresis_loop"]


@dataclass(frozen=True)
class HysteresisLoop:
    """One period of ``q`` and the nonlinear restoring force, measured and identified."""

    q: np.ndarray
    measured: np.ndarray
    identified: np.ndarray
    filtered: bool
    frequency_hz: float

    @property
    def rms_difference(self) -> float:
        """RMS of measured minus identified, relative to the RMS of the measured loop."""
        return float(np.sqrt(np.mean((self.measured - self.identified) ** 2)) / np.sqrt(np.mean(self.measured**2)))

    def enclosed_area(self, which="measured") -> float:
        """Area of the loop (energy per cycle of the nonlinear force), by the shoelace formula."""
        f = self.measured if which == "measured" else self.identified
        q = self.q
        return float(0.5 * abs(np.dot(q, np.roll(f, -1)) - np.dot(f, np.roll(q, -1))))

    def summary(self) -> dict:
        return {
            "frequency_hz": self.frequency_hz,
            "filtered": self.filtered,
            "rms_difference": self.rms_difference,
            "area_measured": self.enclosed_area("measured"),
            "area_identified": self.enclosed_area("identified"),
        }

    def plot(self, ax=None, **kw):
        from .. import plotting

        return plotting.draw("identify_plots.plot_hysteresis", self, ax=ax, **kw)


def hysteresis_loop(signals: StateSignals, terms, coefficients, *, filtered=True) -> HysteresisLoop:
    """Hysteresis loop of a record over one period.

    Parameters
    ----------
    signals : StateSignals
    terms : str or TermLibrary
        The identified terms (must contain ``q``).
    coefficients : array
        Identified coefficients, in the order of ``terms``.
    filtered : bool
        Use harmonic fits of force and acceleration over one period (True), or the raw
        samples averaged synchronously over all periods (False).
    """
    lib = library(terms)
    coefficients = np.asarray(coefficients, float)
    i_lin = lib.index("q")
    others = np.array(coefficients)
    others[i_lin] = 0.0
    t = signals.t
    if filtered:
        m = int(np.searchsorted(t, t[0] + 1.0 / signals.frequency_hz))  # the samples of the first period
        q, v, a_fit = signals.states(stop=m)
        fseries, _ = fit_harmonics(t, signals.force, signals.omega, signals.acceleration.n_harmonics, channel="force")
        measured = fseries(t[:m]) - a_fit - coefficients[i_lin] * q
        identified = lib.restoring_force(q, v, others)
        return HysteresisLoop(q, measured, identified, True, signals.frequency_hz)
    # synchronous average in phase bins: identical averaging of measured and identified values,
    # block by block (a long record is never held as a whole in states)
    dt = (t[-1] - t[0]) / (t.size - 1)
    n_bins = int(min(256, max(8, np.floor(1.0 / (signals.frequency_hz * dt)))))
    count = np.zeros(n_bins)
    sums = np.zeros((3, n_bins))
    for sl, q, v, _ in signals.exact_blocks():
        phase = np.mod((t[sl] - t[0]) * signals.frequency_hz, 1.0)
        idx = np.minimum((phase * n_bins).astype(int), n_bins - 1)
        count += np.bincount(idx, minlength=n_bins)
        raw = signals.force[sl] - signals.accel_measured[sl] - coefficients[i_lin] * q
        for row, x in zip(sums, (q, raw, lib.restoring_force(q, v, others))):
            row += np.bincount(idx, x, n_bins)
    keep = count > 0
    q_avg, raw_avg, identified_avg = (row[keep] / count[keep] for row in sums)
    return HysteresisLoop(q_avg, raw_avg, identified_avg, False, signals.frequency_hz)
