"""Joint elements connecting the two beam ends at the lap joint (seed Eq 8, Eq 9, Figs 2-3).

A joint element acts on the four degrees of freedom ``[w1, th1, w2, th2]`` of two
coincident nodes, node 1 being the end of the left beam and node 2 the start of the
right beam.  It contributes 4 x 4 mass, damping and stiffness matrices ``M_j, C_j, K_j``
to the assembled structure (seed Eq 9, the generic joint element).

Two forms are provided:

* :class:`SpringJoint` -- the lumped interface model of seed Fig 2 / Eq 8: a
  translational spring ``k_w`` and a rotational spring ``k_t`` (with optional dashpots
  ``c_w``, ``c_t``) acting on the relative deflection ``w2 - w1`` and relative rotation
  ``th2 - th1``, plus an optional lumped joint mass ``mass`` and rotary inertia
  ``inertia`` (bolt, nut, washers and the doubled overlap, seed Fig 3), split equally
  between the two nodes.
* :class:`GenericJoint` -- any symmetric 4 x 4 ``M_j, C_j, K_j`` (seed Eq 9).

Sign convention: relative motion is *right minus left*, ``dw = w2 - w1`` and
``dth = th2 - th1``; a joint force ``f`` and moment ``m`` acting on that relative motion
enter the nodal force vector as ``[-f, -m, +f, +m]``
(see :func:`relative_motion_matrix`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import StructureError

__all__ = ["SpringJoint", "GenericJoint", "relative_motion_matrix"]


def relative_motion_matrix() -> np.ndarray:
    """The 2 x 4 matrix ``T`` with ``[dw, dth] = T @ [w1, th1, w2, th2]``.

    A joint force ``f`` and moment ``m`` acting on the relative motion give the
    element nodal forces ``T.T @ [f, m]``.

    Examples
    --------
    >>> relative_motion_matrix() @ [0.0, 0.0, 1e-3, 2e-3]
    array([0.001, 0.002])
    """
    return np.array([[-1.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 1.0]])


def _nonneg(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value) or value < 0.0:
        raise StructureError(f"joint {name}: expected a finite value >= 0, got {value!r}")
    return value


def _readonly(name: str, a) -> np.ndarray:
    arr = np.array(a, dtype=float)
    if arr.shape != (4, 4):
        raise StructureError(f"joint matrix {name}: expected shape (4, 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise StructureError(f"joint matrix {name}: contains non-finite values")
    scale = max(np.max(np.abs(arr)), 1e-300)
    if np.max(np.abs(arr - arr.T)) > 1e-12 * scale:
        raise StructureError(f"joint matrix {name}: expected a symmetric matrix")
    if np.min(np.linalg.eigvalsh(0.5 * (arr + arr.T))) < -1e-10 * scale:
        raise StructureError(f"joint matrix {name}: expected a positive semi-definite matrix")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class SpringJoint:
    """Lumped spring joint (seed Eq 8) with optional dashpots, mass and rotary inertia.

    Parameters
    ----------
    k_w : float
        Translational (shear) stiffness between the beam ends [N/m].
    k_t : float
        Rotational (bending) stiffness between the beam ends [N m/rad].
    c_w, c_t : float, optional
        Viscous translational [N s/m] and rotational [N m s/rad] damping.
    mass : float, optional
        Lumped joint mass [kg], half on each node.
    inertia : float, optional
        Lumped joint rotary inertia [kg m^2], half on each node.

    Examples
    --------
    >>> j = SpringJoint(k_w=1e6, k_t=3e3)
    >>> M, C, K = j.matrices()
    >>> K[0], K[1]
    (array([ 1000000.,        0., -1000000.,        0.]), array([    0.,  3000.,     0., -3000.]))
    """

    k_w: float
    k_t: float
    c_w: float = 0.0
    c_t: float = 0.0
    mass: float = 0.0
    inertia: float = 0.0

    def __post_init__(self):
        for name in ("k_w", "k_t", "c_w", "c_t", "mass", "inertia"):
            object.__setattr__(self, name, _nonneg(name, getattr(self, name)))

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Element matrices ``(M_j, C_j, K_j)``, each 4 x 4 on ``[w1, th1, w2, th2]``."""
        T = relative_motion_matrix()
        K = T.T @ np.diag([self.k_w, self.k_t]) @ T
        C = T.T @ np.diag([self.c_w, self.c_t]) @ T
        M = np.diag([self.mass, self.inertia, self.mass, self.inertia]) / 2.0
        return M, C, K


@dataclass(frozen=True, eq=False)
class GenericJoint:
    """Generic two-node joint element (seed Eq 9): explicit 4 x 4 ``M_j, C_j, K_j``.

    Parameters
    ----------
    M, C, K : array_like, shape (4, 4)
        Symmetric positive semi-definite mass, damping and stiffness matrices acting on
        ``[w1, th1, w2, th2]``.  ``C`` defaults to zero.

    Examples
    --------
    >>> g = GenericJoint.from_springs(SpringJoint(k_w=1e6, k_t=3e3, mass=0.01))
    >>> float(g.M[0, 0])
    0.005
    """

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "M", _readonly("M", self.M))
        object.__setattr__(self, "K", _readonly("K", self.K))
        object.__setattr__(self, "C", _readonly("C", np.zeros((4, 4)) if self.C is None else self.C))

    @classmethod
    def from_springs(cls, joint: SpringJoint) -> "GenericJoint":
        """The generic element equivalent to a :class:`SpringJoint`."""
        M, C, K = joint.matrices()
        return cls(M=M, K=K, C=C)

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Element matrices ``(M_j, C_j, K_j)``, each 4 x 4 on ``[w1, th1, w2, th2]``."""
        return np.array(self.M), np.array(self.C), np.array(self.K)
