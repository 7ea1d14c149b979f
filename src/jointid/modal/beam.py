"""Euler-Bernoulli beam finite elements, the jointed cantilever and its assembly.

The structure of the seed paper (Fig 1, Fig 8) is a cantilever (clamped at ``x = 0``,
free at ``x = L``) made of two identical beams joined at ``x_j`` by a joint element
(:mod:`jointid.modal.joint`).  Each beam is meshed with two-node Euler-Bernoulli
elements with two degrees of freedom per node, deflection ``w`` [m] and rotation
``theta = dw/dx`` [rad], cubic Hermite interpolation and the consistent mass matrix.

Mesh
    Without a joint the beam has ``n_elements`` equal elements.  With a joint the
    left beam ``[0, x_j]`` gets ``round(n_elements * x_j / L)`` equal elements and the
    right beam the rest; the two beam ends at ``x_j`` are separate, coincident nodes
    connected only by the joint element.  The seed model (35 beam elements, joint at
    mid-span) therefore has 18 elements of 11.67 mm on the left and 17 of 12.35 mm on
    the right: 35 identical elements (as in the paper) cannot put a node exactly at
    mid-span, and we prefer the joint exactly at ``L/2``.

Clamp
    ``w(0) = 0`` always.  ``clamp_stiffness = inf`` (default) is the ideal clamp
    ``theta(0) = 0``; a finite value is a rotational spring [N m/rad] to ground, which
    the seed data need (see :mod:`jointid.modal.updating`).

Degrees of freedom
    The assembled :class:`FEModel` works on the *free* DOFs only (constrained DOFs
    removed); :attr:`FEModel.dof_map` gives the free index of ``(w, theta)`` of each
    node (``-1`` if constrained).  Vectors of DOF values put the DOF on the first axis
    and time, if any, on the last.

Seed model
    :func:`seed_bolted_beam` builds the seed structure: two steel beams, overall length
    0.42 m (the paper's "0.42 cm" is a typo: a 4.2 mm cantilever cannot have a 26 Hz
    first mode), width 25.4 mm, thickness 6.36 mm, E = 210 GPa, rho = 7850 kg/m^3,
    joint at mid-span, force at 5 cm, accelerometers at 30 and 42 cm.  With
    ``preload=120`` or ``540`` the joint and clamp stiffnesses updated to Table 4 are
    filled in (:data:`SEED_UPDATED_PARAMETERS`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..errors import StructureError
from .joint import GenericJoint, SpringJoint, relative_motion_matrix

__all__ = [
    "BeamSection",
    "JointedBeam",
    "FEModel",
    "beam_element_matrices",
    "hermite_shape_functions",
    "cantilever_frequencies",
    "seed_bolted_beam",
    "PARAMETERS",
    "SEED_GEOMETRY",
    "SEED_TABLE4_HZ",
    "SEED_UPDATED_PARAMETERS",
]

#: Cantilever eigenvalues ``beta_n L`` of the first five bending modes.
#: Largest number of beam elements: the FE matrices are dense, 2 (n + 1) square (2000 elements: 0.26 GB for
#: the eigenproblem's working copies); a beam needs far fewer for the first modes.
MAX_ELEMENTS = 2000

_CANTILEVER_BETA_L = (1.8751040687, 4.6940911330, 7.8547574382, 10.9955407349, 14.1371683910)


def _positive(where: str, value, allow_inf: bool = False) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise StructureError(f"{where}: expected a positive number, got {value!r}") from None
    if math.isnan(value) or value <= 0.0 or (math.isinf(value) and not allow_inf):
        raise StructureError(f"{where}: expected a positive {'' if allow_inf else 'finite '}number, got {value!r}")
    return value


@dataclass(frozen=True)
class BeamSection:
    """Material and rectangular cross-section of a beam (SI units).

    Parameters
    ----------
    youngs_modulus : float
        Young's modulus ``E`` [Pa].
    density : float
        Density ``rho`` [kg/m^3].
    width, thickness : float
        Section width ``b`` and thickness (bending direction) ``h`` [m].

    Examples
    --------
    >>> s = BeamSection()
    >>> round(s.bending_stiffness, 3), round(s.mass_per_length, 4)
    (114.352, 1.2681)
    """

    youngs_modulus: float = 210e9
    density: float = 7850.0
    width: float = 0.0254
    thickness: float = 0.00636

    def __post_init__(self):
        for name in ("youngs_modulus", "density", "width", "thickness"):
            object.__setattr__(self, name, _positive(f"beam {name}", getattr(self, name)))

    @property
    def area(self) -> float:
        """Cross-section area ``A = b h`` [m^2]."""
        return self.width * self.thickness

    @property
    def second_moment(self) -> float:
        """Second moment of area ``I = b h^3 / 12`` [m^4]."""
        return self.width * self.thickness**3 / 12.0

    @property
    def bending_stiffness(self) -> float:
        """``E I`` [N m^2]."""
        return self.youngs_modulus * self.second_moment

    @property
    def mass_per_length(self) -> float:
        """``rho A`` [kg/m]."""
        return self.density * self.area


def beam_element_matrices(bending_stiffness: float, mass_per_length: float, length: float):
    """Stiffness and consistent mass matrices of one Euler-Bernoulli element.

    Parameters
    ----------
    bending_stiffness : float
        ``E I`` [N m^2].
    mass_per_length : float
        ``rho A`` [kg/m].
    length : float
        Element length ``l`` [m].

    Returns
    -------
    K, M : ndarray, shape (4, 4)
        On the element DOFs ``[w_a, theta_a, w_b, theta_b]``.
    """
    l = float(length)
    K = (bending_stiffness / l**3) * np.array(
        [
            [12.0, 6 * l, -12.0, 6 * l],
            [6 * l, 4 * l**2, -6 * l, 2 * l**2],
            [-12.0, -6 * l, 12.0, -6 * l],
            [6 * l, 2 * l**2, -6 * l, 4 * l**2],
        ]
    )
    M = (mass_per_length * l / 420.0) * np.array(
        [
            [156.0, 22 * l, 54.0, -13 * l],
            [22 * l, 4 * l**2, 13 * l, -3 * l**2],
            [54.0, 13 * l, 156.0, -22 * l],
            [-13 * l, -3 * l**2, -22 * l, 4 * l**2],
        ]
    )
    return K, M


def hermite_shape_functions(xi, length: float, derivative: int = 0) -> np.ndarray:
    """Cubic Hermite shape functions (or their x-derivatives) of an element.

    Parameters
    ----------
    xi : array_like
        Local coordinate ``(x - x_a) / l`` in ``[0, 1]``.
    length : float
        Element length ``l`` [m].
    derivative : {0, 1, 2}
        0 for ``w``, 1 for the slope ``dw/dx``, 2 for the curvature ``d2w/dx2``.

    Returns
    -------
    ndarray, shape (..., 4)
        Row(s) ``N`` with ``w(x) = N @ [w_a, theta_a, w_b, theta_b]``.
    """
    xi = np.asarray(xi, dtype=float)
    l = float(length)
    if derivative == 0:
        N = [1 - 3 * xi**2 + 2 * xi**3, l * (xi - 2 * xi**2 + xi**3), 3 * xi**2 - 2 * xi**3, l * (xi**3 - xi**2)]
    elif derivative == 1:
        N = [(-6 * xi + 6 * xi**2) / l, 1 - 4 * xi + 3 * xi**2, (6 * xi - 6 * xi**2) / l, 3 * xi**2 - 2 * xi]
    elif derivative == 2:
        N = [(-6 + 12 * xi) / l**2, (-4 + 6 * xi) / l, (6 - 12 * xi) / l**2, (6 * xi - 2) / l]
    else:
        raise ValueError(f"derivative must be 0, 1 or 2, got {derivative!r}")
    return np.stack(np.broadcast_arrays(*N), axis=-1)


def cantilever_frequencies(section: BeamSection, length: float, n_modes: int = 3) -> np.ndarray:
    """Closed-form natural frequencies [Hz] of a uniform Euler-Bernoulli cantilever.

    ``f_n = (beta_n L)^2 / (2 pi L^2) sqrt(E I / (rho A))`` with
    ``beta_n L = 1.8751, 4.6941, 7.8548, ...``.

    Examples
    --------
    >>> np.round(cantilever_frequencies(BeamSection(), 0.42), 2)
    array([ 30.12, 188.78, 528.6 ])
    """
    if not 1 <= n_modes <= len(_CANTILEVER_BETA_L):
        raise ValueError(f"n_modes must be 1..{len(_CANTILEVER_BETA_L)}, got {n_modes}")
    L = _positive("beam length", length)
    bl = np.array(_CANTILEVER_BETA_L[:n_modes])
    return bl**2 / (2 * np.pi * L**2) * np.sqrt(section.bending_stiffness / section.mass_per_length)


@dataclass(frozen=True, eq=False)
class FEModel:
    """An assembled finite element model on the free DOFs.

    Build it with :meth:`JointedBeam.assemble`.  Arrays are read-only.

    Attributes
    ----------
    M, C, K : ndarray, shape (n_dof, n_dof)
        Mass, damping (joint dashpots only) and stiffness matrices on the free DOFs.
    node_x : ndarray, shape (n_nodes,)
        Node positions [m]; the two joint nodes share one position.
    dof_map : ndarray of int, shape (n_nodes, 2)
        Free DOF index of ``(w, theta)`` of every node, ``-1`` where constrained.
    elements : ndarray of int, shape (n_elements, 2)
        Node pairs of the beam elements, ordered along ``x``.
    joint_nodes : tuple of int or None
        ``(left node, right node)`` of the joint element.
    length : float
        Overall beam length [m].
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    node_x: np.ndarray
    dof_map: np.ndarray
    elements: np.ndarray
    joint_nodes: tuple[int, int] | None
    length: float

    def __post_init__(self):
        for name in ("M", "C", "K", "node_x", "dof_map", "elements"):
            a = np.array(getattr(self, name))
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def n_dof(self) -> int:
        """Number of free DOFs."""
        return self.M.shape[0]

    @property
    def joint_dofs(self) -> np.ndarray:
        """Free DOF indices ``[w1, th1, w2, th2]`` of the joint element's two nodes."""
        if self.joint_nodes is None:
            raise StructureError("this model has no joint element")
        a, b = self.joint_nodes
        return np.concatenate([self.dof_map[a], self.dof_map[b]])

    @property
    def joint_dofs_full(self) -> np.ndarray:
        """Indices ``[w1, th1, w2, th2]`` of the joint nodes in the full numbering.

        The full numbering has ``2 * n_nodes`` DOFs, ``(w, theta)`` node by node,
        constrained DOFs included (see :meth:`nodal_values`).
        """
        if self.joint_nodes is None:
            raise StructureError("this model has no joint element")
        a, b = self.joint_nodes
        return np.array([2 * a, 2 * a + 1, 2 * b, 2 * b + 1])

    def relative_motion_matrix(self) -> np.ndarray:
        """Matrix ``T`` (2, n_dof) with ``[dw, dth] = T @ d`` at the joint.

        A joint force ``f`` and moment ``m`` on the relative motion contribute
        ``T.T @ [f, m]`` to the global nodal force vector.
        """
        T = np.zeros((2, self.n_dof))
        T[:, self.joint_dofs] = relative_motion_matrix()
        return T

    def relative_motion(self, d) -> tuple[np.ndarray, np.ndarray]:
        """Relative deflection ``w2 - w1`` and rotation ``th2 - th1`` at the joint.

        Parameters
        ----------
        d : array_like, shape (n_dof, ...) or (2 * n_nodes, ...)
            DOF values (displacements, velocities, mode shapes...), DOFs first, either
            on the free DOFs or in the full numbering with the constrained DOFs (the
            two lengths always differ).

        Returns
        -------
        dw, dth : ndarray, shape d.shape[1:]
        """
        d = np.asarray(d)
        n_full = 2 * self.node_x.size
        if d.ndim == 0 or d.shape[0] not in (self.n_dof, n_full):
            raise StructureError(
                f"expected {self.n_dof} (free) or {n_full} (full) DOF values on the first axis, got shape {d.shape}"
            )
        w1, t1, w2, t2 = self.joint_dofs if d.shape[0] == self.n_dof else self.joint_dofs_full
        return d[w2] - d[w1], d[t2] - d[t1]

    def interpolation_matrix(self, x, derivative: int = 0, side: str = "left") -> np.ndarray:
        """Matrix ``N`` (n_x, n_dof) with ``w(x) = N @ d`` (Hermite interpolation).

        Parameters
        ----------
        x : array_like
            Positions [m] in ``[0, L]``.
        derivative : {0, 1, 2}
            Deflection, slope or curvature.
        side : {"left", "right"}
            Which element to use at a node shared by two elements; it matters only at
            the joint (left or right beam end) and for curvatures.

        Notes
        -----
        ``N.T`` is also the consistent nodal load vector of a unit point force at ``x``.
        """
        x = np.atleast_1d(np.asarray(x, dtype=float))
        if side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}")
        tol = 1e-12 * self.length
        bad = ~np.isfinite(x) | (x < -tol) | (x > self.length + tol)
        if np.any(bad):
            raise StructureError(
                f"position {x[bad][0]!r} m is outside the beam [0, {self.length}] m"
            )
        xa = self.node_x[self.elements[:, 0]]
        xb = self.node_x[self.elements[:, 1]]
        inside = (xa[None, :] <= x[:, None] + tol) & (x[:, None] <= xb[None, :] + tol)
        if side == "left":
            e = np.argmax(inside, axis=1)
        else:
            e = inside.shape[1] - 1 - np.argmax(inside[:, ::-1], axis=1)
        le = xb[e] - xa[e]
        xi = np.clip((x - xa[e]) / le, 0.0, 1.0)
        N = np.zeros((x.size, self.n_dof))
        for k in range(x.size):
            Nk = hermite_shape_functions(xi[k], le[k], derivative)
            dofs = self.dof_map[self.elements[e[k]]].ravel()
            keep = dofs >= 0
            N[k, dofs[keep]] = Nk[keep]
        return N

    def nodal_values(self, d) -> np.ndarray:
        """DOF values per node, shape ``(n_nodes, 2, ...)``, zero at constrained DOFs."""
        d = np.asarray(d)
        out = np.zeros((self.node_x.size, 2) + d.shape[1:], dtype=d.dtype)
        free = self.dof_map >= 0
        out[free] = d[self.dof_map[free]]
        return out


@dataclass(frozen=True)
class JointedBeam:
    """A cantilever made of two beams joined by a joint element (or one beam without).

    Parameters
    ----------
    length : float
        Overall length ``L`` [m].
    section : BeamSection
        Material and section of both beams.
    joint : SpringJoint or GenericJoint or None
        The joint element; ``None`` gives a continuous (monolithic) cantilever.
    joint_position : float, optional
        Position ``x_j`` of the joint [m]; default ``L / 2``.
    n_elements : int
        Total number of beam elements (the joint element is extra).
    clamp_stiffness : float
        Rotational stiffness of the clamp [N m/rad]; ``inf`` is an ideal clamp.

    Examples
    --------
    >>> b = JointedBeam(0.42, joint=SpringJoint(k_w=1e7, k_t=3e3))
    >>> fe = b.assemble()
    >>> fe.n_dof, fe.joint_dofs.tolist()
    (72, [34, 35, 36, 37])
    """

    length: float
    section: BeamSection = field(default_factory=BeamSection)
    joint: SpringJoint | GenericJoint | None = None
    joint_position: float | None = None
    n_elements: int = 35
    clamp_stiffness: float = math.inf

    def __post_init__(self):
        object.__setattr__(self, "length", _positive("beam length", self.length))
        if not isinstance(self.section, BeamSection):
            raise StructureError(f"section: expected a BeamSection, got {type(self.section).__name__}")
        if self.joint is not None and not isinstance(self.joint, (SpringJoint, GenericJoint)):
            raise StructureError(f"joint: expected SpringJoint, GenericJoint or None, got {type(self.joint).__name__}")
        n = self.n_elements
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < (2 if self.joint is not None else 1):
            raise StructureError(f"n_elements: expected an integer >= 2, got {n!r}")
        if n > MAX_ELEMENTS:
            raise StructureError(
                f"n_elements: expected at most {MAX_ELEMENTS} (dense matrices of 2 (n + 1) DOFs), got {n!r}"
            )
        object.__setattr__(self, "n_elements", int(n))
        object.__setattr__(self, "clamp_stiffness", _positive("clamp_stiffness", self.clamp_stiffness, allow_inf=True))
        if self.joint_position is not None:
            xj = float(self.joint_position)
            if not (0.0 < xj < self.length):
                raise StructureError(
                    f"joint position: expected a value strictly inside (0, {self.length}) m, got {xj!r}"
                )
            object.__setattr__(self, "joint_position", xj)

    @property
    def x_joint(self) -> float | None:
        """Joint position [m] (``None`` without a joint)."""
        if self.joint is None:
            return None
        return self.length / 2 if self.joint_position is None else self.joint_position

    def _mesh(self):
        L, n = self.length, self.n_elements
        if self.joint is None:
            x = np.linspace(0.0, L, n + 1)
            elements = np.column_stack([np.arange(n), np.arange(1, n + 1)])
            return x, elements, None
        xj = self.x_joint
        nl = int(min(max(round(n * xj / L), 1), n - 1))
        nr = n - nl
        x = np.concatenate([np.linspace(0.0, xj, nl + 1), np.linspace(xj, L, nr + 1)])
        left = np.column_stack([np.arange(nl), np.arange(1, nl + 1)])
        right = np.column_stack([np.arange(nl + 1, nl + 1 + nr), np.arange(nl + 2, nl + 2 + nr)])
        return x, np.vstack([left, right]), (nl, nl + 1)

    def assemble(self) -> FEModel:
        """Assemble the FE model (beam elements, joint element, clamp)."""
        x, elements, joint_nodes = self._mesh()
        n_full = 2 * x.size
        K = np.zeros((n_full, n_full))
        M = np.zeros((n_full, n_full))
        C = np.zeros((n_full, n_full))
        EI, rA = self.section.bending_stiffness, self.section.mass_per_length
        lengths = x[elements[:, 1]] - x[elements[:, 0]]
        dofs = np.column_stack([2 * elements[:, 0], 2 * elements[:, 0] + 1, 2 * elements[:, 1], 2 * elements[:, 1] + 1])
        rows = np.repeat(dofs, 4, axis=1).ravel()
        cols = np.tile(dofs, (1, 4)).ravel()
        for le in np.unique(lengths):  # few distinct element lengths
            ke, me = beam_element_matrices(EI, rA, le)
            sel = np.flatnonzero(lengths == le)
            r = rows.reshape(-1, 16)[sel].ravel()
            c = cols.reshape(-1, 16)[sel].ravel()
            np.add.at(K, (r, c), np.tile(ke.ravel(), sel.size))
            np.add.at(M, (r, c), np.tile(me.ravel(), sel.size))
        if joint_nodes is not None:
            a, b = joint_nodes
            d = [2 * a, 2 * a + 1, 2 * b, 2 * b + 1]
            mj, cj, kj = self.joint.matrices()
            K[np.ix_(d, d)] += kj
            M[np.ix_(d, d)] += mj
            C[np.ix_(d, d)] += cj
        constrained = [0]
        if math.isinf(self.clamp_stiffness):
            constrained.append(1)
        else:
            K[1, 1] += self.clamp_stiffness
        free = np.setdiff1d(np.arange(n_full), constrained)
        full_to_free = -np.ones(n_full, dtype=int)
        full_to_free[free] = np.arange(free.size)
        ix = np.ix_(free, free)
        return FEModel(
            M=M[ix], C=C[ix], K=K[ix], node_x=x, dof_map=full_to_free.reshape(-1, 2),
            elements=elements, joint_nodes=joint_nodes, length=self.length,
        )

    # --- named parameters (used by model updating) ---------------------------------
    def parameter(self, name: str) -> float:
        """Value of a named parameter (see :data:`PARAMETERS`)."""
        owner, attr = _parameter_path(name)
        if owner == "joint":
            if not isinstance(self.joint, SpringJoint):
                raise StructureError(f"parameter {name!r} needs a SpringJoint, the model has {self.joint!r}")
            return getattr(self.joint, attr)
        if owner == "section":
            return getattr(self.section, attr)
        return getattr(self, attr)

    def with_parameters(self, **values: float) -> "JointedBeam":
        """A copy with named parameters changed, e.g. ``with_parameters(k_w=1e7, k_c=4e3)``."""
        joint_changes, section_changes, own = {}, {}, {}
        for name, value in values.items():
            owner, attr = _parameter_path(name)
            {"joint": joint_changes, "section": section_changes, "beam": own}[owner][attr] = float(value)
        beam = self
        if joint_changes:
            if not isinstance(self.joint, SpringJoint):
                raise StructureError(
                    f"parameters {sorted(joint_changes)} need a SpringJoint, the model has {self.joint!r}"
                )
            own["joint"] = dataclasses.replace(self.joint, **joint_changes)
        if section_changes:
            own["section"] = dataclasses.replace(self.section, **section_changes)
        return dataclasses.replace(beam, **own) if own else beam


#: Named model parameters: name -> (owner, attribute, unit, description).
PARAMETERS: Mapping[str, tuple[str, str, str, str]] = MappingProxyType(
    {
        "k_w": ("joint", "k_w", "N/m", "joint translational stiffness"),
        "k_t": ("joint", "k_t", "N m/rad", "joint rotational stiffness"),
        "m_j": ("joint", "mass", "kg", "lumped joint mass"),
        "J_j": ("joint", "inertia", "kg m^2", "lumped joint rotary inertia"),
        "c_w": ("joint", "c_w", "N s/m", "joint translational damping"),
        "c_t": ("joint", "c_t", "N m s/rad", "joint rotational damping"),
        "k_c": ("beam", "clamp_stiffness", "N m/rad", "clamp rotational stiffness"),
        "E": ("section", "youngs_modulus", "Pa", "Young's modulus of the beams"),
        "rho": ("section", "density", "kg/m^3", "density of the beams"),
    }
)


def _parameter_path(name: str) -> tuple[str, str]:
    try:
        owner, attr, _, _ = PARAMETERS[name]
    except KeyError:
        raise StructureError(f"unknown model parameter {name!r}; expected one of {sorted(PARAMETERS)}") from None
    return owner, attr


#: Geometry of the seed's bolted beam (seed section 5, Fig 8), SI units.
SEED_GEOMETRY: Mapping[str, float] = MappingProxyType(
    {
        "length": 0.42,
        "width": 0.0254,
        "thickness": 0.00636,
        "joint_position": 0.21,
        "force_position": 0.05,
        "accel_30": 0.30,
        "accel_42": 0.42,
    }
)

#: Measured linear natural frequencies [Hz] of the seed, Table 4, by bolt preload [N].
SEED_TABLE4_HZ: Mapping[int, tuple[float, float, float]] = MappingProxyType(
    {120: (26.4, 157.6, 471.8), 540: (26.6, 159.1, 472.4)}
)

#: Parameters updated to Table 4 with ``update_to_frequencies(seed_bolted_beam(),
#: SEED_TABLE4_HZ[p], ("k_w", "k_t", "k_c"))`` (see ``tests/test_modal_updating.py``,
#: which re-runs the updating and checks these values).
SEED_UPDATED_PARAMETERS: Mapping[int, Mapping[str, float]] = MappingProxyType(
    {
        120: MappingProxyType({"k_w": 2.88809e6, "k_t": 2841.845, "k_c": 4284.843}),
        540: MappingProxyType({"k_w": 2.67934e6, "k_t": 3026.784, "k_c": 4590.750}),
    }
)


def seed_bolted_beam(preload: int | None = None, n_elements: int = 35) -> JointedBeam:
    """The seed's bolted steel beam (section 5, Fig 8).

    Parameters
    ----------
    preload : {None, 120, 540}
        Bolt preload [N].  ``None`` gives the nominal model: ideal clamp and a nearly
        rigid joint (``k_w = 1e9 N/m``, ``k_t = 1e6 N m/rad``), the starting point of
        updating.  120 or 540 give the model updated to Table 4
        (:data:`SEED_UPDATED_PARAMETERS`: joint ``k_w``, ``k_t`` and clamp ``k_c``).
    n_elements : int
        Number of beam elements (35 in the seed).

    Examples
    --------
    >>> b = seed_bolted_beam(120)
    >>> b.x_joint, b.clamp_stiffness
    (0.21, 4284.843)
    """
    beam = JointedBeam(
        length=SEED_GEOMETRY["length"],
        section=BeamSection(210e9, 7850.0, SEED_GEOMETRY["width"], SEED_GEOMETRY["thickness"]),
        joint=SpringJoint(k_w=1e9, k_t=1e6),
        joint_position=SEED_GEOMETRY["joint_position"],
        n_elements=n_elements,
    )
    if preload is None:
        return beam
    try:
        params = SEED_UPDATED_PARAMETERS[int(preload)]
    except (KeyError, TypeError, ValueError):
        raise StructureError(
            f"seed preload: expected one of {sorted(SEED_UPDATED_PARAMETERS)} N, got {preload!r}"
        ) from None
    return beam.with_parameters(**params)
