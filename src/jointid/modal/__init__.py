"""jointid.modal: the structure -- beam FE with the joint element, modal analysis,
updating to measured frequencies, and physical-to-modal coordinates.

Seed paper sections 2 and 5, Appendix A (Eq 1-13, A1-A10, Table 4, Figs 1-3, 8-9).
"""

from .analysis import ModalModel, mac, modal_analysis, simulate_beam_response
from .beam import (
    PARAMETERS,
    SEED_GEOMETRY,
    SEED_TABLE4_HZ,
    SEED_UPDATED_PARAMETERS,
    BeamSection,
    FEModel,
    JointedBeam,
    beam_element_matrices,
    cantilever_frequencies,
    hermite_shape_functions,
    seed_bolted_beam,
)
from .coordinates import ModalAcceleration, modal_acceleration, modal_force, sensor_shapes
from .joint import GenericJoint, SpringJoint, relative_motion_matrix
from .structure import MODELS, Structure
from .updating import (
    DEFAULT_BOUNDS,
    DEFAULT_STUDY_SETS,
    ParameterStudy,
    UpdateResult,
    frequency_sensitivities,
    parameter_study,
    update_to_frequencies,
)

__all__ = [
    "BeamSection", "FEModel", "JointedBeam", "GenericJoint", "SpringJoint", "ModalModel",
    "ParameterStudy", "UpdateResult", "ModalAcceleration", "Structure", "MODELS",
    "modal_acceleration", "modal_force", "sensor_shapes",
    "beam_element_matrices", "cantilever_frequencies", "hermite_shape_functions", "seed_bolted_beam",
    "relative_motion_matrix", "modal_analysis", "mac", "simulate_beam_response",
    "frequency_sensitivities", "update_to_frequencies", "parameter_study",
    "PARAMETERS", "SEED_GEOMETRY", "SEED_TABLE4_HZ", "SEED_UPDATED_PARAMETERS", "DEFAULT_BOUNDS", "DEFAULT_STUDY_SETS",
]
