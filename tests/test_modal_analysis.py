"""Modal analysis: mass normalisation, shape interpolation, MAC."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointid.modal import BeamSection, JointedBeam, mac, modal_analysis, seed_bolted_beam


@pytest.fixture(scope="module")
def seed_modes():
    return modal_analysis(seed_bolted_beam(120), 6)


def test_mass_normalised_and_orthogonal(seed_modes):
    m = seed_modes
    G = m.shapes.T @ m.fe.M @ m.shapes
    assert np.max(np.abs(G - np.eye(m.n_modes))) < 1e-10
    Kg = m.shapes.T @ m.fe.K @ m.shapes
    assert np.allclose(Kg, np.diag(m.omega**2), rtol=1e-9, atol=1e-6 * m.omega[-1] ** 2)
    assert np.all(np.diff(m.omega) > 0)


def test_modal_mass_matches_continuous_cantilever():
    """Mass-normalised tip deflection of a uniform cantilever: phi(L) = 2 / sqrt(m_total)."""
    s = BeamSection()
    m = modal_analysis(JointedBeam(0.42, s, n_elements=35), 3)
    total = s.mass_per_length * 0.42
    tip = m.shape_at([0.42])[0]
    assert np.allclose(np.abs(tip), 2 / np.sqrt(total), rtol=1e-3)
    assert np.all(tip > 0)  # sign convention: free end positive


def test_shape_interpolation(seed_modes):
    m = seed_modes
    fe = m.fe
    nodal = fe.nodal_values(m.shapes)  # (n_nodes, 2, n_modes)
    # at the nodes the interpolation returns the DOF values (left beam end at the joint)
    left_nodes = [i for i in range(fe.node_x.size) if i != fe.joint_nodes[1]]
    assert np.allclose(m.shape_at(fe.node_x[left_nodes]), nodal[left_nodes, 0, :], atol=1e-12)
    # right beam end at the joint through side="right"
    xj = fe.node_x[fe.joint_nodes[1]]
    assert np.allclose(m.shape_at([xj], side="right")[0], nodal[fe.joint_nodes[1], 0, :])
    assert np.allclose(m.shape_at([xj], derivative=1, side="right")[0], nodal[fe.joint_nodes[1], 1, :])
    # slope is the derivative of the deflection
    x = np.array([0.05, 0.137, 0.3, 0.41])
    h = 1e-6
    fd = (m.shape_at(x + h) - m.shape_at(x - h)) / (2 * h)
    assert np.allclose(m.shape_at(x, derivative=1), fd, rtol=1e-6, atol=1e-6)
    # clamp: zero deflection
    assert np.allclose(m.shape_at([0.0]), 0.0)
    # int selection gives a 1-D array
    assert m.shape_at(x, 0).shape == (4,)


def test_joint_shape_and_relative_motion(seed_modes):
    m = seed_modes
    J = m.joint_shape()
    assert J.shape == (4, m.n_modes)
    dw, dth = m.fe.relative_motion(m.shapes)
    assert np.allclose(dw, J[2] - J[0]) and np.allclose(dth, J[3] - J[1])
    # the soft joint rotates: relative rotation of mode 1 is clearly non-zero
    assert abs(dth[0]) > 1e-3 * np.max(np.abs(m.shapes[:, 0]))


def test_mac_properties(seed_modes):
    x = np.linspace(0.01, 0.42, 60)
    A = seed_modes.shape_at(x, [0, 1, 2])
    M = mac(A)
    assert np.allclose(np.diag(M), 1.0)
    assert np.all((M >= 0) & (M <= 1 + 1e-12))
    assert np.allclose(mac(A, -3.0 * A), M)  # scale and sign invariant
    assert M[0, 1] < 0.3 and M[1, 2] < 0.3
    assert mac(np.zeros(3), np.ones(3))[0, 0] == 0.0
    # a continuous beam and the updated jointed beam: same mode family
    other = modal_analysis(JointedBeam(0.42), 3).shape_at(x)
    assert np.all(np.diag(mac(A, other)) > 0.9)


def test_summary_report(seed_modes):
    s = seed_modes.summary()
    json.dumps(s)
    assert s["mass_normalisation_error"] < 1e-10
    assert "26.400" in seed_modes.report()
