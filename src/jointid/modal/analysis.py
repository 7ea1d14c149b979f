"""Modal analysis of the assembled beam: frequencies, mass-normalised shapes, MAC.

The undamped generalised eigenproblem ``K phi = omega^2 M phi`` is solved with
:func:`scipy.linalg.eigh`; the shapes are mass-normalised, ``Phi^T M Phi = I``, so the
modal mass of every mode is one (the convention of :mod:`jointid.conventions`).  The
sign of each shape is fixed so that the free-end deflection is positive.

Shapes are known at the DOFs; :meth:`ModalModel.shape_at` evaluates them, their slopes
or curvatures anywhere along the beam with the elements' Hermite shape functions,
which is exact within the FE approximation.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..errors import StructureError
from .beam import FEModel, JointedBeam

__all__ = ["ModalModel", "modal_analysis", "mac", "simulate_beam_response"]


@dataclass(frozen=True, eq=False)
class ModalModel:
    """Natural frequencies and mass-normalised mode shapes of an FE model.

    Attributes
    ----------
    fe : FEModel
        The assembled model the modes belong to.
    omega : ndarray, shape (n_modes,)
        Natural angular frequencies [rad/s], ascending.
    shapes : ndarray, shape (n_dof, n_modes)
        Mass-normalised mode shapes on the free DOFs (columns).
    """

    fe: FEModel
    omega: np.ndarray
    shapes: np.ndarray

    def __post_init__(self):
        for name in ("omega", "shapes"):
            a = np.array(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def n_modes(self) -> int:
        return self.omega.size

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Natural frequencies [Hz]."""
        return self.omega / (2 * np.pi)

    def shape_at(self, x, modes=None, derivative: int = 0, side: str = "left") -> np.ndarray:
        """Mode shape values (or slopes, curvatures) at positions ``x``.

        Parameters
        ----------
        x : array_like
            Positions along the beam [m].
        modes : int or sequence of int, optional
            Zero-based mode indices; default all.  An int gives a 1-D result.
        derivative : {0, 1, 2}
            Deflection, slope or curvature of the shape.
        side : {"left", "right"}
            At the joint position: the left or right beam end.

        Returns
        -------
        ndarray, shape (n_x, n_selected) or (n_x,) for an int ``modes``
        """
        N = self.fe.interpolation_matrix(x, derivative=derivative, side=side)
        if modes is None:
            return N @ self.shapes
        if np.ndim(modes) == 0:
            return N @ self.shapes[:, int(modes)]
        return N @ self.shapes[:, list(modes)]

    def mass_normalisation_error(self) -> float:
        """``max |Phi^T M Phi - I|`` (zero for exactly mass-normalised shapes)."""
        G = self.shapes.T @ self.fe.M @ self.shapes
        return float(np.max(np.abs(G - np.eye(self.n_modes))))

    def joint_shape(self, modes=None) -> np.ndarray:
        """``[phi(l1), phi'(l1), phi(l2), phi'(l2)]`` at the joint (seed Eq 12), per mode."""
        idx = self.fe.joint_dofs
        S = self.shapes[idx]
        return S if modes is None else S[:, modes]

    def summary(self) -> dict:
        """JSON-safe summary."""
        return {
            "frequencies_hz": [float(f) for f in self.frequencies_hz],
            "n_dof": int(self.fe.n_dof),
            "mass_normalisation_error": self.mass_normalisation_error(),
        }

    def report(self) -> str:
        """A short text table of the modes."""
        lines = ["mode  f [Hz]", "----  ---------"]
        lines += [f"{i + 1:4d}  {f:9.3f}" for i, f in enumerate(self.frequencies_hz)]
        lines.append(f"mass normalisation error {self.mass_normalisation_error():.1e}")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        rows = "".join(f"<tr><td>{i + 1}</td><td>{f:.3f}</td></tr>" for i, f in enumerate(self.frequencies_hz))
        return f"<table><tr><th>mode</th><th>f [Hz]</th></tr>{rows}</table>"

    def to_json(self) -> str:
        return json.dumps(self.summary())

    def plot(self, ax=None, modes=None, **kwargs):
        """Plot the mode shapes (see :func:`jointid.report.modal_plots.plot_mode_shapes`)."""
        from .. import plotting  # drawing lives in report, reached by name

        return plotting.draw("modal_plots.plot_mode_shapes", self, modes=modes, ax=ax, **kwargs)


def modal_analysis(model: JointedBeam | FEModel, n_modes: int = 6) -> ModalModel:
    """Natural frequencies and mass-normalised mode shapes.

    Parameters
    ----------
    model : JointedBeam or FEModel
        The structure (assembled if needed).
    n_modes : int
        Number of lowest modes to return.

    Returns
    -------
    ModalModel

    Examples
    --------
    >>> from jointid.modal import JointedBeam
    >>> m = modal_analysis(JointedBeam(0.42), n_modes=3)
    >>> np.round(m.frequencies_hz, 1)
    array([ 30.1, 188.8, 528.6])
    >>> m.mass_normalisation_error() < 1e-10
    True
    """
    fe = model.assemble() if isinstance(model, JointedBeam) else model
    if not isinstance(fe, FEModel):
        raise StructureError(f"expected a JointedBeam or FEModel, got {type(model).__name__}")
    n = int(n_modes)
    if not 1 <= n <= fe.n_dof:
        raise StructureError(f"n_modes: expected 1..{fe.n_dof}, got {n_modes!r}")
    lam, phi = scipy.linalg.eigh(fe.K, fe.M, subset_by_index=[0, n - 1])
    if np.any(lam < -1e-8 * max(abs(lam[-1]), 1.0)):
        raise StructureError(f"negative eigenvalue {lam.min():.3g}: the stiffness matrix is not positive semi-definite")
    lam = np.clip(lam, 0.0, None)
    # enforce M-normalisation exactly (eigh is already close) and a sign convention
    norms = np.sqrt(np.einsum("ij,ik,kj->j", phi, fe.M, phi))
    phi = phi / norms
    tip = fe.interpolation_matrix([fe.length])[0] @ phi
    largest = phi[np.argmax(np.abs(phi), axis=0), np.arange(n)]
    ref = np.where(np.abs(tip) > 1e-12 * np.abs(largest), tip, largest)  # free end, else largest DOF
    phi = phi * np.where(ref < 0, -1.0, 1.0)
    return ModalModel(fe=fe, omega=np.sqrt(lam), shapes=phi)


def mac(a, b=None) -> np.ndarray:
    """Modal assurance criterion between two sets of shapes.

    ``MAC_ij = |a_i^H b_j|^2 / ((a_i^H a_i)(b_j^H b_j))``.

    Parameters
    ----------
    a : array_like, shape (n_points,) or (n_points, n_a)
        Shapes as columns, sampled at the same points as ``b``.
    b : array_like, shape (n_points,) or (n_points, n_b), optional
        Default ``a`` (auto-MAC).

    Returns
    -------
    ndarray, shape (n_a, n_b)

    Examples
    --------
    >>> mac([[1.0, 0.0], [0.0, 1.0]], [[2.0], [0.0]]).ravel()
    array([1., 0.])
    """
    A = np.asarray(a)
    B = A if b is None else np.asarray(b)
    A = A.reshape(A.shape[0], -1)
    B = B.reshape(B.shape[0], -1)
    if A.shape[0] != B.shape[0]:
        raise ValueError(f"shapes must share the number of points, got {A.shape[0]} and {B.shape[0]}")
    cross = np.abs(A.conj().T @ B) ** 2
    na = np.real(np.sum(A.conj() * A, axis=0))
    nb = np.real(np.sum(B.conj() * B, axis=0))
    denom = np.outer(na, nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(denom > 0, cross / np.where(denom > 0, denom, 1.0), 0.0)
    return out


def simulate_beam_response(
    modes: ModalModel,
    force,
    fs: float,
    force_position: float,
    positions,
    damping_ratio=0.01,
    n_modes: int | None = None,
    output: str = "acceleration",
    method: str = "foh",
):
    """Response of the linear beam to a point force by modal superposition.

    A thin wrapper of :func:`jointid.signal.frf.simulate_modal_response` that takes the
    modal forces ``phi_r(x_f) F`` and output shapes ``phi_r(x_k)`` from ``modes``.

    Parameters
    ----------
    modes : ModalModel
    force : array_like, shape (n_t,)
        Force samples [N] at the sample rate ``fs``.
    fs : float
        Sample rate [Hz].
    force_position : float
        Force position [m].
    positions : sequence of float
        Output positions [m].
    damping_ratio : float or array_like
        Modal damping ratio(s).
    n_modes : int, optional
        Number of modes to superpose (default all of ``modes``).
    output : {"acceleration", "velocity", "displacement"}
    method : {"foh", "fft"}
        Time-stepping from rest or periodic steady state.

    Returns
    -------
    ModalResponse
        See :func:`jointid.signal.frf.simulate_modal_response`.
    """
    from ..signal.frf import simulate_modal_response

    n = modes.n_modes if n_modes is None else int(n_modes)
    sel = list(range(n))
    phi_f = modes.shape_at([force_position], sel)[0]
    phi_out = modes.shape_at(np.atleast_1d(positions), sel)
    return simulate_modal_response(
        modes.omega[:n], damping_ratio, phi_f, phi_out, force, fs, output=output, method=method
    )
