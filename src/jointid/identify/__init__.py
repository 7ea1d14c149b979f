"""jointid.identify: force-state mapping and the laws built on it.

* :mod:`jointid.identify.terms` -- named restoring-force terms and libraries;
* :mod:`jointid.identify.fsm` -- per-record and pooled force-state mapping (seed Eq 21-23);
* :mod:`jointid.identify.model` -- one model per preload, amplitude laws inside the regression;
* :mod:`jointid.identify.uncertainty` -- the noise model: score and sandwich covariances;
* :mod:`jointid.identify.gain` -- the pooled regression with an unknown force gain;
* :mod:`jointid.identify.broadband` -- force-state mapping of broadband records;
* :mod:`jointid.identify.laws` -- damping law, energy per cycle, power law (Eq 25-26);
* :mod:`jointid.identify.hysteresis` -- measured and identified loops (Figs 17-19);
* :mod:`jointid.identify.delay` -- the response channel's delay behind the excitation, from the dwells;
* :mod:`jointid.identify.backbone` -- omega(a), zeta(a): identified models with bands, stepped-sine points;
* :mod:`jointid.identify.ringdown` -- force-state mapping on a free decay, window by window;
* :mod:`jointid.identify.jointlaw` -- Iwan and cubic + viscous joint laws fitted to a backbone through the FE modes;
* :mod:`jointid.identify.regression` -- the scaled, blockwise least squares underneath.
"""

from .backbone import Backbone, equivalent_linearisation, model_backbone, phase_resonance_points
from .delay import ChannelDelay, ChannelDelayEstimator
from .jointlaw import JointLawFit, JointModes, fit_cubic_viscous, fit_iwan, fit_joint_laws
from .fsm import ForceStateMapping, PooledForceStateMapping, band_average
from .gain import PooledGainForceStateMapping
from .hysteresis import hysteresis_loop
from .laws import fit_damping_law, fit_power_law
from .model import PreloadForceStateMapping, PreloadModel
from .terms import Term, TermLibrary, library, term

__all__ = ["Backbone", "equivalent_linearisation", "model_backbone", "phase_resonance_points", "JointLawFit",
           "JointModes", "fit_cubic_viscous", "fit_iwan", "fit_joint_laws", "ChannelDelay", "ChannelDelayEstimator", "ForceStateMapping", "PooledForceStateMapping", "PooledGainForceStateMapping", "band_average",
           "PreloadForceStateMapping", "PreloadModel", "hysteresis_loop", "fit_damping_law", "fit_power_law", "Term", "TermLibrary", "library", "term"]
