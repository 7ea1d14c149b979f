"""Physical to modal coordinates through two accelerometers (seed Eq 11, A6)."""

from __future__ import annotations

import numpy as np
import pytest

from jointid.errors import JointidWarning, StructureError
from jointid.modal import (
    Structure,
    modal_acceleration,
    modal_analysis,
    modal_force,
    seed_bolted_beam,
    sensor_shapes,
    simulate_beam_response,
)

FS = 4096.0
SENSORS = {"accel_30": 0.30, "accel_42": 0.42}


@pytest.fixture(scope="module")
def modes():
    return modal_analysis(seed_bolted_beam(120), 6)


def _record(modes, f_hz, amplitude=3.0, n_modes=5, zeta=0.01, duration=12.0, settle=8.0):
    """Steady-state response to a sine at f_hz: several modes respond, q_r known."""
    t = np.arange(int(duration * FS)) / FS
    force = amplitude * np.sin(2 * np.pi * f_hz * t)
    r = simulate_beam_response(modes, force, FS, 0.05, list(SENSORS.values()), damping_ratio=zeta, n_modes=n_modes)
    k = slice(int(settle * FS), None)
    accels = {name: r.response[i, k] for i, name in enumerate(SENSORS)}
    return force[k], accels, r.qdd[:, k]


@pytest.mark.parametrize("ratio", [0.97, 1.0, 1.03])
def test_first_mode_coordinate_within_one_percent_near_resonance(modes, ratio):
    st = Structure.from_modal_model(modes, SENSORS, 0.05)
    force, accels, qdd_true = _record(modes, ratio * modes.frequencies_hz[0])
    # several modes respond (they are what the residual sees)
    assert np.std(qdd_true[1]) > 1e-4 * np.std(qdd_true[0])
    Q, qdd, residual = st.to_modal(force, accels)
    err = np.sqrt(np.mean((qdd - qdd_true[0]) ** 2) / np.mean(qdd_true[0] ** 2))
    assert err < 0.01
    assert residual < 0.01
    assert np.allclose(Q, modes.shape_at([0.05], 0)[0] * force)


def test_residual_flags_a_record_dominated_by_mode_two(modes):
    st = Structure.from_modal_model(modes, SENSORS, 0.05)
    force, accels, qdd_true = _record(modes, modes.frequencies_hz[1])
    assert np.std(qdd_true[1]) > 5 * np.std(qdd_true[0])  # mode 2 dominates
    _, _, residual_2 = st.to_modal(force, accels)
    force, accels, _ = _record(modes, modes.frequencies_hz[0])
    _, _, residual_1 = st.to_modal(force, accels)
    assert residual_2 > 0.3
    assert residual_2 > 50 * residual_1


def test_two_mode_basis_removes_mode_two(modes):
    # three sensors, two modes in the basis: mode-2 contamination is estimated, not leaked
    sensors = {"a20": 0.20, "a30": 0.30, "a42": 0.42}
    t = np.arange(int(4 * FS)) / FS
    force = np.sin(2 * np.pi * modes.frequencies_hz[0] * t) + np.sin(2 * np.pi * modes.frequencies_hz[1] * t)
    r = simulate_beam_response(modes, force, FS, 0.05, list(sensors.values()), n_modes=2)
    one = modal_acceleration(r.response, sensor_shapes(modes, list(sensors.values()), 1))
    two = modal_acceleration(r.response, sensor_shapes(modes, list(sensors.values()), 2))
    assert np.allclose(two.qdd, r.qdd, atol=1e-9 * np.max(np.abs(r.qdd)))
    assert two.relative_residual < 1e-9 < one.relative_residual
    with pytest.warns(JointidWarning, match="identically zero"):
        modal_acceleration(r.response[:2], sensor_shapes(modes, [0.2, 0.3], 2))
    with pytest.raises(StructureError, match="cannot be resolved"):
        modal_acceleration(r.response[:1], sensor_shapes(modes, [0.2], 2))


def test_modal_force_shapes():
    F = np.array([1.0, -2.0, 3.0])
    assert np.allclose(modal_force(F, 0.1), 0.1 * F)
    assert modal_force(F, [0.1, 0.2]).shape == (2, 3)
