"""jointid.rig: the virtual bolted-beam test rig of the seed paper (section 5).

* :mod:`jointid.rig.iwan` -- joint laws with an explicit hysteretic state: Segalman's
  four-parameter Iwan model (Jenkins elements) plus cubic stiffness, one protocol for
  time integration (``force``) and harmonic balance (``periodic_force``);
* :mod:`jointid.rig.reduced` -- the modal-truncated beam with joint laws: multi-harmonic
  balance (alternating frequency/time, exact Jacobian) and a vectorised fixed-step
  integrator;
* :mod:`jointid.rig.rig` -- :class:`VirtualRig`: shaker, force cell, accelerometers,
  noise, random and stepped-sine tests; :func:`seed_rig` for the 120 and 540 N preloads;
* :mod:`jointid.rig.plan` -- the seed's test plan written as physical campaigns
  (CSV and UFF 58 records, ``campaign.toml`` with a ``[structure]`` section).
"""

from .iwan import IwanParameters, JenkinsElements, JointLaw, discretize_iwan
from .plan import MeasurementPlan, RigCampaign, read_random_record, run_test_plan, structure_section, write_manifest
from .reduced import ReducedModel, RigSteadyState, integrate, settle_check
from .rig import SEED_RIG_JOINTS, SEED_SENSORS, Acquisition, Dwell, RandomTest, RigFRF, VirtualRig, seed_rig

__all__ = [
    "IwanParameters", "JenkinsElements", "JointLaw", "discretize_iwan",
    "ReducedModel", "RigSteadyState", "integrate", "settle_check",
    "Acquisition", "RandomTest", "Dwell", "RigFRF", "VirtualRig", "seed_rig", "SEED_RIG_JOINTS", "SEED_SENSORS",
    "MeasurementPlan", "RigCampaign", "run_test_plan", "structure_section", "write_manifest", "read_random_record",
]
