"""Shared numerics on the ground floor: harmonic (AFT) bases and peak refinement.

Small, general routines used by several floors (harmonic balance in
:mod:`jointid.simulate.hbm`, the rig's reduced model in :mod:`jointid.rig.reduced`, the
re-prediction and demo of :mod:`jointid.app`).  This package imports only numpy, scipy
and :mod:`jointid.errors` / :mod:`jointid.conventions`, so every floor may use it.

* :mod:`jointid.numerics.aft` -- time basis, phase derivative and projection of the
  alternating frequency/time method in the harmonic convention of
  :mod:`jointid.conventions`;
* :mod:`jointid.numerics.peaks` -- the peak of sampled data refined by a parabola, and
  samples of a peak refined by interval halving.
"""

from .aft import aft_basis, basis_at
from .peaks import parabolic_peak, refine_peak

__all__ = ["aft_basis", "basis_at", "parabolic_peak", "refine_peak"]
