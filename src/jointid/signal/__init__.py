"""jointid.signal: from sampled records to state signals.

* :mod:`jointid.signal.harmonics` -- single-frequency steady states: excitation
  frequency, harmonic fit, analytic integration (seed Eq 16-18);
* :mod:`jointid.signal.broadband` -- multisine and random records: period averaging,
  noise lines, frequency-domain integration;
* :mod:`jointid.signal.frf` -- H1 and coherence, modal fit, linear modal responses;
* :mod:`jointid.signal.ringdown` -- free decays: windowed damped-oscillation fit, states, noise floor;
* :mod:`jointid.signal.backbone` -- the backbone result type, omega(a) and zeta(a) with bands.
"""

from .harmonics import HarmonicSeries, StateSignals, estimate_frequency, fit_harmonics, steady_state_signals
from .ringdown import DecayFit, fit_decay

__all__ = ["HarmonicSeries", "StateSignals", "estimate_frequency", "fit_harmonics", "steady_state_signals", "DecayFit",
           "fit_decay"]
