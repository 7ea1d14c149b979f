"""Hysteresis loops: restoring force minus its linear stiffness part vs displacement (seed Figs 17-19).

For one steady-state period of a record:

* measured loop: ``Q(t) - q''(t) - omega1^2 q(t)``; "filtered" uses the harmonic fits of
  both force and acceleration (the seed's filtered loops), "unfiltered" the raw samples;
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
        from ..report.identify_plots import plot_hysteresis

        return plot_hysteresis(self, ax=ax, **kw)


def hysteresis_loop(signals: StateSignals, terms, coefficients, *, filtered=True) -> HysteresisLoop:
    """Loop of one period (the first whole period of the record).

    Parameters
    ----------
    signals : StateSignals
    terms : str or TermLibrary
        The identified terms (must contain ``q``).
    coefficients : array
        Identified coefficients, in the order of ``terms``.
    filtered : bool
        Use harmonic fits of force and acceleration (True) or the raw samples (False).
    """
    lib = library(terms)
    coefficients = np.asarray(coefficients, float)
    i_lin = lib.index("q")
    T = 1.0 / signals.frequency_hz
    t = signals.t
    sel = t < t[0] + T
    q_all, v_all, a_fit = signals.states()
    q, v = q_all[sel], v_all[sel]
    if filtered:
        fseries, _ = fit_harmonics(t, signals.force, signals.omega, signals.acceleration.n_harmonics, channel="force")
        restoring = fseries(t[sel]) - a_fit[sel]
    else:
        restoring = signals.force[sel] - signals.accel_measured[sel]
    measured = restoring - coefficients[i_lin] * q
    others = np.array(coefficients)
    others[i_lin] = 0.0
    identified = lib.restoring_force(q, v, others)
    return HysteresisLoop(q, measured, identified, filtered, signals.frequency_hz)
