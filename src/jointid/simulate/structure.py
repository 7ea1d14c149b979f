"""The user's own structure: a linear model with joint elements between named degrees of freedom.

A :class:`LinearModel` holds mass and stiffness matrices with one name per degree of
freedom (DOF) and its damping (modal damping ratios, or Rayleigh ``C = alpha M + beta K``,
which is modal with ``zeta_r = alpha / (2 omega_r) + beta omega_r / 2``).  A
:class:`ModalModel` holds the same structure as modal data: natural frequencies, damping
ratios and mass-normalised mode shapes at the named DOFs that matter (joint, force and
sensor DOFs); :meth:`LinearModel.modal` computes it.

A :class:`JointElement` is a joint law (:mod:`jointid.joints`) acting on the relative motion
``u = x[dof_b] - x[dof_a]`` of two named DOFs (both translations or both rotations), or on
``x[dof_b]`` alone when ``dof_a`` is None (a joint to the ground).  ``k_model`` is the
joint's stiffness already in the linear model (for example the stuck joint of a model whose
matrices hold the joint as a spring), subtracted from the law.

:class:`StructureModel` puts them together with the force DOFs and computes nonlinear
frequency responses by the multi-mode harmonic balance of
:mod:`jointid.simulate.structure_hb`, reporting the response at named DOFs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from ..errors import StructureError, unknown_key_message
from .structure_hb import CondensedHB, HBCurve, HBPoint, default_n_time

__all__ = ["JointElement", "LinearModel", "ModalModel", "StructureModel", "modal_damping", "structure_from_spec"]


def modal_damping(omega, *, zeta=None, rayleigh=None) -> np.ndarray:
    """Damping ratio per mode: given ratios (one or one per mode) or Rayleigh ``(alpha, beta)``.

    A rigid-body mode (``omega = 0``) gets ratio 0 under Rayleigh damping.
    """
    om = np.asarray(omega, float)
    if (zeta is None) == (rayleigh is None):
        raise StructureError("damping: give either modal damping ratios (zeta) or Rayleigh (alpha, beta), not both")
    if zeta is not None:
        z = np.asarray(zeta, float).ravel()
        if z.size == 1:
            z = np.full(om.size, float(z[0]))
        if z.size < om.size:
            raise StructureError(f"damping: {z.size} modal damping ratios for {om.size} modes")
        z = z[: om.size]
        if not np.all(np.isfinite(z)) or np.any(z < 0):
            raise StructureError("damping: modal damping ratios must be finite and non-negative")
        return z
    try:
        a, b = (float(x) for x in rayleigh)
    except (TypeError, ValueError):
        raise StructureError(f"damping: Rayleigh needs two numbers (alpha, beta), got {rayleigh!r}") from None
    if not (math.isfinite(a) and math.isfinite(b)) or a < 0 or b < 0:
        raise StructureError(f"damping: Rayleigh alpha, beta must be finite and non-negative, got {a}, {b}")
    with np.errstate(divide="ignore"):
        z = np.where(om > 0, a / (2 * np.where(om > 0, om, 1.0)) + b * om / 2, 0.0)
    return z


def _names(dof_names, n, what):
    names = tuple(str(s) for s in dof_names)
    if len(names) != n:
        raise StructureError(f"{what}: {len(names)} DOF names for {n} degrees of freedom")
    seen = set()
    for s in names:
        if not s or s in seen:
            raise StructureError(f"{what}: DOF names must be non-empty and unique ({s!r})")
        seen.add(s)
    return names


@dataclass(frozen=True, eq=False)
class ModalModel:
    """Modal data of a linear structure at named DOFs.

    Attributes
    ----------
    omega : ndarray (n_modes,)
        Natural frequencies [rad/s] (0 for rigid-body modes).
    zeta : ndarray (n_modes,)
        Modal damping ratios.
    dof_names : tuple of str
    shapes : ndarray (n_dofs, n_modes)
        Mass-normalised mode shapes at those DOFs.
    """

    omega: np.ndarray
    zeta: np.ndarray
    dof_names: tuple
    shapes: np.ndarray

    def __post_init__(self):
        om = np.array(self.omega, float).ravel()
        ze = modal_damping(om, zeta=self.zeta)
        sh = np.array(self.shapes, float)
        if sh.ndim != 2 or sh.shape[1] != om.size:
            raise StructureError(f"mode shapes: expected shape (n_dofs, {om.size}), got {sh.shape}")
        names = _names(self.dof_names, sh.shape[0], "mode shapes")
        if not np.all(np.isfinite(om)) or np.any(om < 0) or not np.all(np.isfinite(sh)):
            raise StructureError("modal data: natural frequencies must be finite and >= 0, mode shapes finite")
        for k, v in (("omega", om), ("zeta", ze), ("shapes", sh)):
            v.setflags(write=False)
            object.__setattr__(self, k, v)
        object.__setattr__(self, "dof_names", names)

    @classmethod
    def from_hz(cls, frequencies_hz, zeta, dof_names, shapes):
        return cls(2 * np.pi * np.asarray(frequencies_hz, float), zeta, dof_names, shapes)

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    @property
    def n_modes(self) -> int:
        return self.omega.size

    def index(self, dof) -> int:
        try:
            return self.dof_names.index(str(dof))
        except ValueError:
            raise StructureError(unknown_key_message(str(dof), self.dof_names, "DOF")) from None

    def shape(self, dof) -> np.ndarray:
        """Mode shapes at one named DOF: (n_modes,)."""
        return self.shapes[self.index(dof)]


@dataclass(frozen=True, eq=False)
class LinearModel:
    """Mass and stiffness matrices with named DOFs and damping.

    Parameters
    ----------
    M, K : array (n, n)
        Symmetric; ``M`` positive definite, ``K`` positive semi-definite (rigid-body modes
        allowed).  Dense or scipy sparse.
    dof_names : sequence of str
    zeta : float or array, optional
        Modal damping ratios (one for every mode, or one per mode from the lowest).
    rayleigh : (alpha, beta), optional
        Rayleigh damping instead.
    """

    M: np.ndarray
    K: np.ndarray
    dof_names: tuple
    zeta: object = None
    rayleigh: object = None
    source: str = field(default="", compare=False)

    def __post_init__(self):
        where = f"{self.source}: " if self.source else ""
        mats = []
        for nm in ("M", "K"):
            a = getattr(self, nm)
            if hasattr(a, "toarray"):
                a = a.toarray()
            try:
                a = np.array(a, float)
            except (TypeError, ValueError):
                raise StructureError(f"{where}{nm}: expected a numeric matrix") from None
            if a.ndim != 2 or a.shape[0] != a.shape[1] or a.shape[0] == 0:
                raise StructureError(f"{where}{nm}: expected a square matrix, got shape {a.shape}")
            if not np.all(np.isfinite(a)):
                raise StructureError(f"{where}{nm}: has NaN or infinite entries")
            if not np.allclose(a, a.T, rtol=1e-9, atol=1e-12 * max(np.abs(a).max(), 1e-300)):
                raise StructureError(f"{where}{nm}: is not symmetric")
            a.setflags(write=False)
            mats.append(a)
        M, K = mats
        if M.shape != K.shape:
            raise StructureError(f"{where}M {M.shape} and K {K.shape} differ in size")
        names = _names(self.dof_names, M.shape[0], f"{where}dof_names")
        if (self.zeta is None) == (self.rayleigh is None):
            raise StructureError(f"{where}damping: give either modal damping ratios or Rayleigh (alpha, beta)")
        object.__setattr__(self, "M", M)
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "dof_names", names)

    @property
    def n_dofs(self) -> int:
        return self.M.shape[0]

    def modal(self, n_modes=None) -> ModalModel:
        """Lowest ``n_modes`` (default all) mass-normalised modes at every DOF."""
        where = f"{self.source}: " if self.source else ""
        n = self.n_dofs if n_modes is None else int(n_modes)
        if not 1 <= n <= self.n_dofs:
            raise StructureError(f"{where}n_modes = {n_modes} outside 1..{self.n_dofs}")
        try:
            lam, V = scipy.linalg.eigh(self.K, self.M, subset_by_index=[0, n - 1])
        except np.linalg.LinAlgError:
            raise StructureError(f"{where}M is not positive definite") from None
        scale = max(abs(float(lam[-1])), 1e-300)
        if np.any(lam < -1e-8 * scale):
            raise StructureError(f"{where}K is not positive semi-definite (eigenvalue {lam.min():.3g})")
        lam = np.where(lam < 1e-10 * scale, 0.0, lam)
        om = np.sqrt(lam)
        # sign convention: the largest entry of each mode positive (results independent of LAPACK)
        i = np.argmax(np.abs(V), axis=0)
        V = V * np.sign(V[i, np.arange(n)])
        return ModalModel(om, modal_damping(om, zeta=self.zeta, rayleigh=self.rayleigh), self.dof_names, V)


@dataclass(frozen=True, eq=False)
class JointElement:
    """A joint law on the relative motion ``x[dof_b] - x[dof_a]`` (``dof_a`` None: to ground)."""

    name: str
    dof_a: object
    dof_b: str
    law: object
    k_model: float = 0.0

    def shape(self, modal: ModalModel) -> np.ndarray:
        s = modal.shape(self.dof_b).copy()
        if self.dof_a is not None:
            s -= modal.shape(self.dof_a)
        return s


class StructureModel:
    """A linear structure with joint elements, excited at named DOFs.

    Parameters
    ----------
    modal : ModalModel or LinearModel
        (a LinearModel is reduced to its lowest ``n_modes`` modes, default all).
    joints : sequence of JointElement
    force : mapping DOF name -> weight
        The load vector per unit excitation ``F(t)`` (``{"tip": 1.0}``: a force at one DOF).
    n_modes : int, optional
    """

    def __init__(self, modal, joints, force, n_modes=None):
        if isinstance(modal, LinearModel):
            modal = modal.modal(n_modes)
        elif n_modes is not None:
            modal = ModalModel(modal.omega[:n_modes], modal.zeta[:n_modes], modal.dof_names,
                               modal.shapes[:, :n_modes])
        if not isinstance(modal, ModalModel):
            raise StructureError(f"structure: expected a LinearModel or ModalModel, got {type(modal).__name__}")
        self.modal = modal
        self.joints = tuple(joints)
        if not self.joints:
            raise StructureError("structure: at least one joint element is needed")
        if not hasattr(force, "items") or not force:
            raise StructureError("structure: force must map DOF names to weights")
        self.force = {str(k): float(v) for k, v in force.items()}
        pf = np.zeros(modal.n_modes)
        for dof, wgt in self.force.items():
            pf += wgt * modal.shape(dof)
        psi = np.array([j.shape(modal) for j in self.joints])
        self.engine = CondensedHB(modal.omega, modal.zeta, psi, pf, [j.law for j in self.joints],
                                  [j.k_model for j in self.joints])

    def response(self, point: HBPoint, dofs) -> dict:
        """Harmonic coefficients of the displacement at named DOFs: name -> (2H + 1,)."""
        return {str(d): self.modal.shape(d) @ point.modal for d in dofs}

    def solve(self, frequency_hz, force_amplitude, n_harmonics=9, n_time=None, **kw) -> HBPoint:
        """Steady state under ``F(t) = force_amplitude sin(2 pi f t)``."""
        return self.engine.solve(2 * np.pi * float(frequency_hz), [0.0, 0.0, float(force_amplitude)], n_harmonics,
                                 n_time=n_time, **kw)

    def frequency_response(self, f_start_hz, f_end_hz, force_amplitude, n_harmonics=9, n_time=None,
                           **kw) -> HBCurve:
        """Continued frequency response under ``F(t) = force_amplitude sin(2 pi f t)``."""
        N = default_n_time(n_harmonics) if n_time is None else n_time
        return self.engine.continuation(2 * np.pi * float(f_start_hz), 2 * np.pi * float(f_end_hz),
                                        [0.0, 0.0, float(force_amplitude)], n_harmonics, n_time=N, **kw)


def structure_from_spec(spec) -> tuple:
    """``(StructureModel, response DOFs)`` of a checked structure model file.

    ``spec`` is a :class:`jointid.io.structure_model.StructureSpec` (read by
    :func:`jointid.io.structure_model.read_structure_model`); only its attributes are used.
    """
    where = f"{spec.path}: "
    try:
        if spec.M is not None:
            base = LinearModel(spec.M, spec.K, spec.dof_names, zeta=spec.zeta, rayleigh=spec.rayleigh,
                               source=spec.path)
        else:
            base = ModalModel.from_hz(spec.frequencies_hz, spec.zeta, spec.dof_names, spec.shapes)
        joints = [JointElement(j.name, j.dof_a, j.dof_b, j.law, j.k_model) for j in spec.joints]
        st = StructureModel(base, joints, spec.force, n_modes=spec.n_modes)
    except StructureError as exc:
        msg = str(exc)
        raise StructureError(msg if msg.startswith(where) else where + msg) from None
    # what moves nothing: a joint whose relative motion is zero in every mode kept, a force that excites no mode
    # (zero to rounding of the shapes at the DOFs concerned)
    n, modal = st.modal.n_modes, st.modal
    for i, j in enumerate(joints):
        scale = sum(np.abs(modal.shape(d)) for d in (j.dof_a, j.dof_b) if d is not None)
        if np.all(np.abs(st.engine.joint_shapes[i]) <= 1e-12 * scale):
            dofs = " - ".join(d for d in (j.dof_b, j.dof_a) if d is not None)
            raise StructureError(f"{where}joint[{i}].dofs: joint {j.name!r} ({dofs}) does not move in any of the {n} "
                                 "modes: the joint is inert (check the mode shapes at its DOFs)")
    scale = sum(abs(w) * np.abs(modal.shape(d)) for d, w in st.force.items())
    if np.all(np.abs(st.engine.force_shape) <= 1e-12 * scale):
        raise StructureError(f"{where}force.dofs: the force DOFs {list(st.force)} do not move in any of the {n} modes: "
                             "the force excites nothing")
    return st, tuple(spec.response)
