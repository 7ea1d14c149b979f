"""Updating the seed's bolted beam to Table 4 (seed section 5)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointid.errors import ConvergenceError, StructureError
from jointid.modal import (
    SEED_TABLE4_HZ,
    SEED_UPDATED_PARAMETERS,
    frequency_sensitivities,
    modal_analysis,
    parameter_study,
    seed_bolted_beam,
    update_to_frequencies,
)


@pytest.mark.parametrize("preload", [120, 540])
def test_updating_reproduces_table4_within_half_percent(preload):
    target = SEED_TABLE4_HZ[preload]
    result = update_to_frequencies(seed_bolted_beam(), target, ("k_w", "k_t", "k_c"), require_within=0.005)
    assert np.all(np.abs(result.relative_residuals) < 0.005)
    assert result.max_abs_relative_residual < 1e-6  # three parameters, three frequencies: exact
    assert not result.at_bounds
    # the stored seed parameters are this solution
    for name, value in SEED_UPDATED_PARAMETERS[preload].items():
        assert result.values[result.parameters.index(name)] == pytest.approx(value, rel=1e-4)
    modes = result.modes(n_modes=3)
    assert modes.mass_normalisation_error() < 1e-10
    phi1 = modes.shapes[:, 0]
    assert abs(phi1 @ modes.fe.M @ phi1 - 1.0) < 1e-10
    # the report names every mode and the summary is JSON
    text = result.report()
    for f in target:
        assert f"{f:.3f}" in text
    json.dumps(result.summary())


@pytest.mark.parametrize("preload", [120, 540])
def test_stored_seed_models_match_table4(preload):
    modes = modal_analysis(seed_bolted_beam(preload), 3)
    assert np.all(np.abs(modes.frequencies_hz / np.array(SEED_TABLE4_HZ[preload]) - 1) < 1e-5)
    assert modes.mass_normalisation_error() < 1e-10


def test_parameter_study_shows_which_parameters_the_data_need():
    study = parameter_study(seed_bolted_beam(), SEED_TABLE4_HZ[120], n_starts=4)
    springs, with_mass, with_E, with_clamp = study.results
    assert springs.parameters == ("k_w", "k_t")
    # mid-span springs alone (the seed's assumption): mode 1 stays ~6.7 % off
    assert 0.06 < springs.max_abs_relative_residual < 0.075
    assert springs.relative_residuals[0] > 0.06
    # joint mass and rotary inertia do not help
    assert with_mass.max_abs_relative_residual > 0.05
    # an effective modulus could, but only at ~0.8 x steel
    assert with_E.max_abs_relative_residual < 0.005
    assert 150e9 < with_E.values[2] < 180e9
    # a clamp spring does, exactly
    assert with_clamp.max_abs_relative_residual < 1e-6
    assert study.best(0.005) is with_E
    assert "k_w, k_t, k_c" in study.report()


def test_sensitivities_match_finite_differences():
    beam = seed_bolted_beam(540)
    names = ("k_w", "k_t", "k_c", "m_j", "E")
    beam = beam.with_parameters(m_j=0.01)
    S = frequency_sensitivities(beam, names, 3)
    f0 = modal_analysis(beam, 3).frequencies_hz
    for j, name in enumerate(names):
        p = beam.parameter(name)
        h = 1e-3 * p
        fp = modal_analysis(beam.with_parameters(**{name: p + h}), 3).frequencies_hz
        fm = modal_analysis(beam.with_parameters(**{name: p - h}), 3).frequencies_hz
        fd = (fp - fm) / (2 * h)
        # compare d ln f / d ln p (finite differences carry eigen-solver round-off)
        assert np.allclose(S[:, j] * p / f0, fd * p / f0, rtol=1e-3, atol=1e-5)
    # signs: stiffnesses raise, masses lower the frequencies
    assert np.all(S[:, :3] >= 0) and np.all(S[:, 3] <= 0) and np.all(S[:, 4] > 0)


def test_updating_failures_raise_convergence_error():
    with pytest.raises(ConvergenceError, match="required"):
        update_to_frequencies(seed_bolted_beam(), SEED_TABLE4_HZ[120], ("k_w", "k_t"), n_starts=2, require_within=0.005)
    with pytest.raises(ConvergenceError, match="did not converge"):
        update_to_frequencies(seed_bolted_beam(), SEED_TABLE4_HZ[120], ("k_w", "k_t", "k_c"), n_starts=1, max_nfev=1)


def test_updating_bad_input():
    beam = seed_bolted_beam()
    with pytest.raises(StructureError, match="unknown model parameter"):
        update_to_frequencies(beam, [26.4], ("k_zz",))
    with pytest.raises(StructureError, match="does not change natural frequencies"):
        update_to_frequencies(beam, [26.4], ("c_w",))
    with pytest.raises(StructureError, match="ascending"):
        update_to_frequencies(beam, [157.6, 26.4], ("k_t",))
    with pytest.raises(StructureError, match="bounds"):
        update_to_frequencies(beam, [26.4], ("k_t",), bounds={"k_t": (10.0, 1.0)})
