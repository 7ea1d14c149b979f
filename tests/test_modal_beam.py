"""Beam finite elements, the joint element and the jointed cantilever."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from jointid.errors import StructureError
from jointid.modal import (
    BeamSection,
    GenericJoint,
    JointedBeam,
    SpringJoint,
    beam_element_matrices,
    cantilever_frequencies,
    hermite_shape_functions,
    modal_analysis,
    relative_motion_matrix,
    seed_bolted_beam,
)

SECTION = BeamSection(210e9, 7850.0, 0.0254, 0.00636)


def test_element_matrices_rigid_body_and_mass():
    EI, rA, l = 114.0, 1.27, 0.012
    K, M = beam_element_matrices(EI, rA, l)
    assert np.allclose(K, K.T) and np.allclose(M, M.T)
    translation = np.array([1.0, 0.0, 1.0, 0.0])
    rotation = np.array([0.0, 1.0, l, 1.0])  # w = x, theta = 1
    assert np.allclose(K @ translation, 0.0, atol=1e-6 * np.abs(K).max())
    assert np.allclose(K @ rotation, 0.0, atol=1e-6 * np.abs(K).max())
    assert translation @ M @ translation == pytest.approx(rA * l, rel=1e-12)
    assert np.all(np.linalg.eigvalsh(M) > 0)


def test_hermite_interpolates_cubics_exactly():
    l, xa = 0.02, 0.1
    c = [0.3, -1.0, 4.0, 2.0]  # w = c0 + c1 x + c2 x^2 + c3 x^3
    w = lambda x: c[0] + c[1] * x + c[2] * x**2 + c[3] * x**3
    dw = lambda x: c[1] + 2 * c[2] * x + 3 * c[3] * x**2
    d2w = lambda x: 2 * c[2] + 6 * c[3] * x
    nodal = np.array([w(xa), dw(xa), w(xa + l), dw(xa + l)])
    xi = np.linspace(0, 1, 7)
    x = xa + xi * l
    assert np.allclose(hermite_shape_functions(xi, l) @ nodal, w(x))
    assert np.allclose(hermite_shape_functions(xi, l, 1) @ nodal, dw(x))
    assert np.allclose(hermite_shape_functions(xi, l, 2) @ nodal, d2w(x))


def test_uniform_cantilever_matches_closed_form_within_0p1_percent():
    beam = JointedBeam(0.42, SECTION, joint=None, n_elements=35)
    f = modal_analysis(beam, 3).frequencies_hz
    exact = cantilever_frequencies(SECTION, 0.42, 3)
    # beta_n L = 1.8751, 4.6941, 7.8548
    bl = np.array([1.8751, 4.6941, 7.8548])
    ref = bl**2 / (2 * np.pi * 0.42**2) * math.sqrt(SECTION.bending_stiffness / SECTION.mass_per_length)
    assert np.allclose(exact, ref, rtol=1e-4)
    assert np.all(np.abs(f / exact - 1) < 1e-3)


def test_stiff_joint_reproduces_continuous_beam():
    continuous = modal_analysis(JointedBeam(0.42, SECTION, n_elements=35), 4).frequencies_hz
    stiff = modal_analysis(JointedBeam(0.42, SECTION, SpringJoint(k_w=1e10, k_t=1e7), n_elements=35), 4).frequencies_hz
    assert np.all(np.abs(stiff / continuous - 1) < 5e-4)
    assert np.all(np.abs(stiff[:3] / cantilever_frequencies(SECTION, 0.42) - 1) < 1e-3)


def test_soft_rotational_joint_lowers_mode_one_most_unless_at_its_curvature_minimum():
    """A soft rotational joint lowers a mode by the curvature it sees at the joint.

    Near the clamp (where mode 1 bends most) it lowers mode 1 most.  At mid-span, mode 2
    has more curvature (relative to its frequency) than mode 1 and mode 3 almost none,
    so there mode 2 drops most, mode 1 next and mode 3 hardly moves.
    """

    def drop(xj):
        stiff = modal_analysis(JointedBeam(0.42, SECTION, SpringJoint(1e10, 1e7), xj), 3).frequencies_hz
        soft = modal_analysis(JointedBeam(0.42, SECTION, SpringJoint(1e10, 500.0), xj), 3).frequencies_hz
        return 1 - soft / stiff

    near_clamp = drop(0.05)
    assert near_clamp[0] > near_clamp[1] > near_clamp[2] > 0
    assert near_clamp[0] > 0.3
    mid = drop(0.21)
    assert mid[0] > 0.1 and mid[1] > mid[0] and mid[2] < 1e-3


def test_clamp_spring_lowers_frequencies_and_tends_to_ideal_clamp():
    ideal = modal_analysis(JointedBeam(0.42, SECTION), 3).frequencies_hz
    soft = modal_analysis(JointedBeam(0.42, SECTION, clamp_stiffness=3e3), 3).frequencies_hz
    hard = modal_analysis(JointedBeam(0.42, SECTION, clamp_stiffness=1e7), 3).frequencies_hz
    drop = 1 - soft / ideal
    assert drop[0] > drop[1] > drop[2] > 0  # a flexible clamp lowers mode 1 most
    assert np.allclose(hard, ideal, rtol=1e-4)


def test_mesh_and_joint_dofs():
    beam = seed_bolted_beam()
    fe = beam.assemble()
    n_nodes = fe.node_x.size
    assert n_nodes == 35 + 2  # two coincident nodes at the joint
    assert fe.n_dof == 2 * n_nodes - 2  # w and theta at the ideal clamp removed
    assert seed_bolted_beam(120).assemble().n_dof == 2 * n_nodes - 1  # clamp spring: theta(0) free
    a, b = fe.joint_nodes
    assert fe.node_x[a] == pytest.approx(0.21) and fe.node_x[b] == pytest.approx(0.21)
    assert fe.elements.shape == (35, 2)
    np.testing.assert_array_equal(fe.joint_dofs, np.concatenate([fe.dof_map[a], fe.dof_map[b]]))
    # relative motion: right minus left
    d = np.zeros((fe.n_dof, 3))
    w1, t1, w2, t2 = fe.joint_dofs
    d[w1], d[t1], d[w2], d[t2] = 1.0, 2.0, 1.5, 2.75
    dw, dth = fe.relative_motion(d)
    assert np.allclose(dw, 0.5) and np.allclose(dth, 0.75)
    T = fe.relative_motion_matrix()
    assert np.allclose(T @ d, np.vstack([dw, dth]))
    full = fe.nodal_values(d).reshape(2 * n_nodes, 3)  # full numbering, constrained DOFs = 0
    assert np.allclose(full[fe.joint_dofs_full], d[fe.joint_dofs])
    assert np.allclose(np.vstack(fe.relative_motion(full)), np.vstack([dw, dth]))
    with pytest.raises(StructureError):
        fe.relative_motion(np.zeros(3))


def test_joint_element_matrices_eq8_and_generic_equivalence():
    j = SpringJoint(k_w=2e6, k_t=3e3, c_w=1.0, c_t=0.1, mass=0.02, inertia=1e-6)
    M, C, K = j.matrices()
    T = relative_motion_matrix()
    assert np.allclose(K, T.T @ np.diag([2e6, 3e3]) @ T)
    assert np.allclose(C, T.T @ np.diag([1.0, 0.1]) @ T)
    assert np.allclose(np.diag(M), [0.01, 5e-7, 0.01, 5e-7])
    g = GenericJoint.from_springs(j)
    f_spring = modal_analysis(JointedBeam(0.42, SECTION, j), 3).frequencies_hz
    f_generic = modal_analysis(JointedBeam(0.42, SECTION, g), 3).frequencies_hz
    assert np.allclose(f_spring, f_generic, rtol=1e-12)
    fe = JointedBeam(0.42, SECTION, j).assemble()
    assert np.allclose(fe.C[np.ix_(fe.joint_dofs, fe.joint_dofs)], C)
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.K = None
    with pytest.raises(ValueError):
        g.K[0, 0] = 1.0  # read-only


def test_joint_mass_lowers_frequencies():
    base = seed_bolted_beam(120)
    heavy = base.with_parameters(m_j=0.05)
    assert np.all(modal_analysis(heavy, 3).frequencies_hz <= modal_analysis(base, 3).frequencies_hz + 1e-9)


def test_with_parameters_is_immutable_update():
    beam = seed_bolted_beam()
    new = beam.with_parameters(k_t=1234.0, k_c=5e3, E=200e9)
    assert beam.joint.k_t == 1e6 and math.isinf(beam.clamp_stiffness)
    assert new.parameter("k_t") == 1234.0 and new.parameter("k_c") == 5e3 and new.parameter("E") == 200e9
    with pytest.raises(dataclasses.FrozenInstanceError):
        new.length = 1.0
    with pytest.raises(StructureError, match="unknown model parameter 'k_x'"):
        beam.with_parameters(k_x=1.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(length=-0.42), "beam length"),
        (dict(length=0.42, joint=SpringJoint(1e6, 1e3), joint_position=0.5), "joint position"),
        (dict(length=0.42, n_elements=0), "n_elements"),
        (dict(length=0.42, clamp_stiffness=-1.0), "clamp_stiffness"),
    ],
)
def test_bad_beam_input(kwargs, match):
    with pytest.raises(StructureError, match=match):
        JointedBeam(**kwargs)


def test_bad_joint_and_section_input():
    with pytest.raises(StructureError, match="k_w"):
        SpringJoint(k_w=-1.0, k_t=1.0)
    with pytest.raises(StructureError, match="symmetric"):
        GenericJoint(M=np.zeros((4, 4)), K=np.triu(np.ones((4, 4))))
    with pytest.raises(StructureError, match="thickness"):
        BeamSection(thickness=0.0)
    with pytest.raises(StructureError, match="outside the beam"):
        seed_bolted_beam().assemble().interpolation_matrix([0.5])
    with pytest.raises(StructureError, match="preload"):
        seed_bolted_beam(300)
