"""jointid.simulate: the single-mode model in time and frequency.

* :mod:`jointid.simulate.model` -- :class:`SingleModeModel` with amplitude laws;
* :mod:`jointid.simulate.hbm` -- harmonic balance, continuation through folds, stability;
* :mod:`jointid.simulate.timeint` -- time integration and shooting (the cross-check);
* :mod:`jointid.simulate.synth` -- measured-looking records from a steady state.
"""

from .hbm import FrequencyResponse, SteadyState, frequency_response, steady_state
from .model import SingleModeModel, seed_model

__all__ = ["FrequencyResponse", "SteadyState", "frequency_response", "steady_state", "SingleModeModel", "seed_model"]
