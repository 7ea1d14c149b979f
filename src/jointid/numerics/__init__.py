"""Shared numerics on the ground floor: harmonic (AFT) bases, peak refinement, band-mean intervals,
the modal receptance.

Small, general routines used by several floors (harmonic balance in
:mod:`jointid.simulate.hbm`, the rig's reduced model in :mod:`jointid.rig.reduced`, the
re-prediction and demo of :mod:`jointid.app`).  This package imports only numpy, scipy
and :mod:`jointid.errors` / :mod:`jointid.conventions`, so every floor may use it.

* :mod:`jointid.numerics.aft` -- time basis, phase derivative and projection of the
  alternating frequency/time method in the harmonic convention of
  :mod:`jointid.conventions`, its sample count and the real <-> complex coefficients;
* :mod:`jointid.numerics.peaks` -- the peak of sampled data refined by a parabola, and
  samples of a peak refined by interval halving;
* :mod:`jointid.numerics.intervals` -- the standard error, 95 % interval and resolution of
  a band average of single-record estimates (computed by :mod:`jointid.app`, read by the
  report);
* :mod:`jointid.numerics.receptance` -- the denominator ``Omega^2 - w^2 + 2 i zeta Omega w``
  of a mode's receptance (FRFs, modal fits and the periodic steady state of
  :mod:`jointid.signal.frf`).
"""

from .aft import aft_basis, basis_at
from .intervals import band_mean_resolution
from .peaks import parabolic_peak, refine_peak
from .receptance import modal_denominator

__all__ = ["aft_basis", "basis_at", "band_mean_resolution", "modal_denominator", "parabolic_peak", "refine_peak"]
