"""Joint laws from a backbone: Segalman's four-parameter Iwan model and the seed's cubic + viscous law.

The backbone ``omega(a)``, ``zeta(a)`` of mode 1 maps to the joint through the finite
element mode shape: ``psi`` is the joint element's relative motion (rotation [rad] or
deflection [m]) per unit modal amplitude (:meth:`jointid.modal.beam.FEModel.relative_motion`
of the mass-normalised mode).  With the linear model holding the joint's small-amplitude
stiffness and the joint's nonlinear force ``f_nl(u)`` acting through ``psi``, first-harmonic
balance of one mode at joint amplitude ``u0 = |psi| a`` gives

``omega(a)^2 = Omega^2 + psi^2 (k_1(u0) - K_T)``,
``zeta(a) = zeta_0 Omega / omega + psi^2 D(u0) / (2 pi omega^2 u0^2)``

with ``k_1`` the in-phase first-harmonic stiffness of the joint law, ``D`` its energy
dissipated per cycle, ``Omega`` and ``zeta_0`` the small-amplitude frequency and
(viscous, structural) damping ratio of the mode.

Iwan (micro-slip)
    A parallel set of Jenkins elements with the slip-displacement density ``R phi^chi``
    (Segalman 2005).  While every amplitude stays below the largest slip displacement
    ``phi_max`` (micro-slip), elements with ``phi < u0`` slip and

    ``k_1(u0) - K_T = -R I(chi) u0^(chi + 1)``,  ``I(chi) = int_0^1 s^chi (1 - g(s)) ds``,
    ``D(u0) = 4 R u0^(chi + 3) / ((chi + 2)(chi + 3))``,

    where ``g(s) = (t - sin(2 t) / 2) / pi``, ``cos t = 1 - 2 s``, is the first-harmonic
    stiffness of one Jenkins element of unit stiffness slipping at ``s u0`` (Caughey's
    bilinear hysteresis).  A cubic part ``-k3 u^3`` (the seed's sign) adds
    ``-3/4 k3 u0^2`` to ``k_1``.  The data then determine ``Omega``, ``zeta_0``, the
    micro-slip coefficient ``R`` [force / rad^(chi + 2) or N / m^(chi + 2)], the exponent
    ``chi`` and ``k3``.  They do not determine ``F_S``, ``beta`` or the stuck stiffness
    ``K_T`` apart: with ``K_T`` given (e.g. from the updated joint stiffness) they fix one
    relation between ``F_S`` and ``beta`` (:meth:`JointLawFit.slip_force`).

Cubic + viscous (seed Eq 19-20 in joint coordinates)
    ``f = K_T u - k3 u^3 + c(u0) u'`` with ``c(u0) = c1 u0 + c2 u0^2`` (the constant part
    merges with the structural damping): ``omega^2 = Omega^2 - 3/4 psi^2 k3 u0^2``,
    ``2 omega zeta = 2 zeta_0 Omega + psi^2 c(u0)``.  Linear least squares.

Adequacy: reduced chi-square (residuals over the backbone's standard errors), relative
RMS residuals of ``omega`` and ``zeta``, AIC and BIC (Gaussian likelihood with the
stated errors) for comparing the laws on the same backbone.
"""

from __future__ import annotations

import functools
import html
from dataclasses import dataclass, field

import numpy as np
from scipy import integrate, optimize

from ..errors import IdentificationError
from ..rounding import format_estimate, format_value

__all__ = ["JointLawFit", "JointModes", "fit_iwan", "fit_cubic_viscous", "fit_joint_laws", "iwan_harmonic_stiffness_integral"]


def _jenkins_g(s):
    """First-harmonic stiffness of a unit Jenkins element slipping at ``s`` times the amplitude."""
    s = np.clip(np.asarray(s, float), 0.0, 1.0)
    t = np.arccos(1.0 - 2.0 * s)
    return (t - 0.5 * np.sin(2.0 * t)) / np.pi


@functools.lru_cache(maxsize=4096)
def _I_cached(chi: float) -> float:
    val, _ = integrate.quad(lambda s: s**chi * (1.0 - _jenkins_g(s)), 0.0, 1.0, limit=200, epsabs=0, epsrel=1e-12)
    return float(val)


def iwan_harmonic_stiffness_integral(chi) -> float:
    """``I(chi) = int_0^1 s^chi (1 - g(s)) ds`` of the micro-slip first-harmonic stiffness."""
    chi = float(chi)
    if not -1.0 < chi < 1.0:
        raise IdentificationError(f"chi must lie in (-1, 1), got {chi}")
    return _I_cached(round(chi, 12))


@dataclass(frozen=True, eq=False)
class JointLawFit:
    """A joint law fitted to a backbone.

    Attributes
    ----------
    law : {"iwan", "cubic-viscous"}
    names : tuple of str
        Parameter names (``Omega``, ``zeta_0``, ``R``, ``chi``, ``k3`` or ``c1``, ``c2``).
    values, stderr : ndarray
    covariance : ndarray
    determined : tuple of str
        The parameters the backbone determines (all of ``names``); ``not_determined``
        lists those it does not.
    not_determined : tuple of str
    joint_shape : float
        ``psi``: joint relative motion per unit modal amplitude.
    units : dict
        Unit of each parameter.
    adequacy : dict
        ``chi2_red``, ``rms_omega_rel``, ``rms_zeta_rel``, ``aic``, ``bic``, ``n_points``,
        ``n_parameters``.
    amplitude : ndarray
        The backbone amplitudes used.
    joint_amplitude_range : (float, float)
        ``|psi| a`` over the data.
    K_T : float or None
        The stuck joint stiffness given to derive ``F_S(beta)``.
    """

    law: str
    names: tuple
    values: np.ndarray
    stderr: np.ndarray
    covariance: np.ndarray = field(repr=False)
    determined: tuple
    not_determined: tuple
    joint_shape: float
    units: dict
    adequacy: dict
    amplitude: np.ndarray = field(repr=False)
    joint_amplitude_range: tuple = ()
    K_T: float | None = None
    modes: "JointModes | None" = field(default=None, repr=False)
    u_ref: float | None = None

    def get(self, name) -> float:
        return float(self.values[self.names.index(name)])

    def get_stderr(self, name) -> float:
        return float(self.stderr[self.names.index(name)])

    def predict(self, amplitudes):
        """``(omega, zeta)`` of the fitted law at modal amplitudes ``a``."""
        return _MODELS[self.law](self.values[:5], np.atleast_1d(np.asarray(amplitudes, float)), self.modes)

    def backbone(self, amplitudes, label=""):
        """The fitted law's backbone with 95 % bands (linear propagation of the covariance)."""
        from .backbone import Backbone

        a = np.atleast_1d(np.asarray(amplitudes, float))
        w, z = self.predict(a)
        Jw = np.zeros((a.size, self.values.size))
        Jz = np.empty_like(Jw)
        for j in range(5):
            h = 1e-6 * max(abs(self.values[j]), self.stderr[j] if np.isfinite(self.stderr[j]) else 0.0, 1e-12)
            p = self.values[:5].copy()
            p[j] += h
            wp, zp = _MODELS[self.law](p, a, self.modes)
            p[j] -= 2 * h
            wm, zm = _MODELS[self.law](p, a, self.modes)
            Jw[:, j], Jz[:, j] = (wp - wm) / (2 * h), (zp - zm) / (2 * h)
        Jw[:, 5:] = Jz[:, 5:] = 0.0
        cov = np.nan_to_num(self.covariance)
        ws = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", Jw, cov, Jw), 0, None))
        zs = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", Jz, cov, Jz), 0, None))
        return Backbone(a, w, z, ws, zs, "model", 0.0, label or f"{self.law} joint law", {"law": self.law})

    def slip_force(self, beta):
        """Iwan only: the macro-slip force ``F_S`` the fitted ``R``, ``chi`` imply for a given ``beta`` and ``K_T``.

        ``R = F_S (chi + 1) / (phi_max^(chi + 2) d)`` with ``phi_max = F_S (1 + beta) / (K_T d)``
        and ``d = beta + (chi + 1) / (chi + 2)`` (Segalman 2005).
        """
        if self.law != "iwan" or self.K_T is None:
            raise IdentificationError("slip_force needs an Iwan fit with the stuck stiffness K_T given")
        R, chi = self.get("R"), self.get("chi")
        beta = np.asarray(beta, float)
        d = beta + (chi + 1) / (chi + 2)
        return ((chi + 1) * self.K_T ** (chi + 2) * d ** (chi + 1) / (R * (1 + beta) ** (chi + 2))) ** (1 / (chi + 1))

    def summary(self) -> dict:
        d = {
            "law": self.law,
            "parameters": {n: {"value": float(v), "stderr": float(s), "unit": self.units.get(n, "")}
                           for n, v, s in zip(self.names, self.values, self.stderr)},
            "determined": list(self.determined),
            "not_determined": list(self.not_determined),
            "joint_shape": self.joint_shape,
            "joint_amplitude_range": [float(x) for x in self.joint_amplitude_range],
            "adequacy": {k: (float(v) if v is not None else None) for k, v in self.adequacy.items()},
        }
        if self.law == "iwan" and self.K_T is not None:
            betas = [0.0, 0.5, 1.0, 2.0]
            d["K_T"] = self.K_T
            d["slip_force_given_beta"] = {str(b): float(self.slip_force(b)) for b in betas}
        return d

    def report(self) -> str:
        ad = self.adequacy
        lines = [f"Joint law {self.law}: {ad['n_points']} backbone points, joint amplitude "
                 f"{format_value(self.joint_amplitude_range[0], 3)} .. {format_value(self.joint_amplitude_range[1], 3)}"]
        for n, v, s in zip(self.names, self.values, self.stderr):
            lines.append(f"  {n:>8} = {format_estimate(v, s, self.units.get(n, ''))}")
        lines.append(f"  not determined by this backbone: {', '.join(self.not_determined) or '-'}")
        lines.append(f"  chi2/dof {format_value(ad['chi2_red'], 3)}; rms residual omega "
                     f"{format_value(ad['rms_omega_rel'], 3)} (relative), zeta {format_value(ad['rms_zeta_rel'], 3)}; "
                     f"AIC {format_value(ad['aic'], 6)}, BIC {format_value(ad['bic'], 6)}")
        if self.law == "iwan" and self.K_T is not None:
            fs = ", ".join(f"beta={format_value(b)}: {format_value(self.slip_force(b))}" for b in (0.0, 0.5, 1.0))
            lines.append(f"  with K_T = {format_value(self.K_T, 6)}: F_S {fs}")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"


@dataclass(frozen=True, eq=False)
class JointModes:
    """The linear modes seen by a joint: stuck natural frequencies, damping ratios, joint shapes.

    Parameters
    ----------
    omega : array, shape (n,)
        Natural frequencies of the structure with the joint stuck [rad/s] (mode 1 first;
        the fit replaces ``omega[0]`` and ``zeta[0]`` by its own ``Omega`` and ``zeta_0``).
    zeta : array, shape (n,)
    shapes : array, shape (n,)
        Joint relative motion (rotation [rad] or deflection [m]) per unit modal amplitude of
        each mass-normalised mode.
    direction : {"rotation", "transverse"}
    """

    omega: np.ndarray
    zeta: np.ndarray
    shapes: np.ndarray
    direction: str = "rotation"

    def __post_init__(self):
        om = np.atleast_1d(np.asarray(self.omega, float))
        ze = np.broadcast_to(np.asarray(self.zeta, float), om.shape).copy()
        ps = np.atleast_1d(np.asarray(self.shapes, float))
        if ps.shape != om.shape or not np.all(np.isfinite(ps)) or ps[0] == 0:
            raise IdentificationError(f"joint shapes: expected {om.size} finite values with a non-zero first, got {ps}")
        if self.direction not in ("rotation", "transverse"):
            raise IdentificationError(f"direction must be 'rotation' or 'transverse', got {self.direction!r}")
        for n, v in (("omega", om), ("zeta", ze), ("shapes", ps)):
            v.setflags(write=False)
            object.__setattr__(self, n, v)

    @classmethod
    def single(cls, joint_shape, direction="rotation"):
        """Mode 1 alone (its frequency and damping are fitted)."""
        return cls([1.0], [0.0], [float(joint_shape)], direction)

    @classmethod
    def from_modal_model(cls, modes, direction="rotation", zeta=0.0):
        """From a :class:`jointid.modal.analysis.ModalModel` (mass-normalised FE modes)."""
        dw, dth = modes.fe.relative_motion(modes.shapes)
        shapes = dth if direction == "rotation" else dw
        return cls(modes.omega, zeta, shapes, direction)

    @property
    def psi(self) -> float:
        return float(self.shapes[0])

    def summary(self) -> dict:
        return {"omega": self.omega.tolist(), "zeta": self.zeta.tolist(), "shapes": self.shapes.tolist(),
                "direction": self.direction}


def _eigen_backbone(modes, Om, z0, a, joint):
    """``(omega, zeta)`` of mode 1 with the joint's first-harmonic stiffness and damping in the linear modes.

    ``joint(u0) -> (dk, dc)``: complex stiffness change (in-phase + i hysteretic) and
    viscous damping added at the joint, for an array of joint amplitudes.  The joint acts
    through the rank-one ``Psi Psi^T``, so the eigenvalue ``lambda`` of mode 1 solves the
    scalar equation ``1 + (dk + lambda dc) sum_m psi_m^2 / d_m(lambda) = 0`` with
    ``d_m = lambda^2 + 2 zeta_m Omega_m lambda + Omega_m^2`` (Newton, all amplitudes at
    once), and the mode ``v_m ~ psi_m / d_m`` gives the joint amplitude
    ``u0 = |sum_m psi_m v_m| a`` with ``v_1 = 1`` (updated in the same iteration).
    """
    om = modes.omega.copy()
    ze = modes.zeta.copy()
    om[0], ze[0] = Om, z0
    psi2 = modes.shapes**2
    c = 2 * ze * om
    a = np.asarray(a, float)
    lam = np.full(a.size, complex(-z0 * Om, Om * np.sqrt(max(1 - z0 * z0, 0.0))))
    u0 = abs(modes.shapes[0]) * a
    for _ in range(100):
        dk, dc = joint(u0)
        D = lam[:, None] ** 2 + c * lam[:, None] + om**2
        dD = 2 * lam[:, None] + c
        Sr = (psi2[1:] / D[:, 1:]).sum(axis=1)  # the other modes
        dSr = -(psi2[1:] * dD[:, 1:] / D[:, 1:] ** 2).sum(axis=1)
        g = dk + lam * dc
        # d_1 (1 + g S) = d_1 + g psi_1^2 + g d_1 S_r: smooth where g -> 0
        F = D[:, 0] + g * (psi2[0] + D[:, 0] * Sr)
        dF = dD[:, 0] + dc * (psi2[0] + D[:, 0] * Sr) + g * (dD[:, 0] * Sr + D[:, 0] * dSr)
        step = F / dF
        lam = lam - step
        u_new = np.abs((psi2[0] + D[:, 0] * Sr) / modes.shapes[0]) * a
        du = np.abs(u_new - u0)
        u0 = u_new
        if np.all(np.abs(step) <= 1e-14 * Om) and np.all(du <= 1e-12 * np.maximum(u0, 1e-300)):
            break
    w = np.abs(lam)
    return w, -lam.real / w


def _iwan_joint(R, chi, k3):
    Ic = iwan_harmonic_stiffness_integral(chi)
    c_d = 4.0 / ((chi + 2.0) * (chi + 3.0) * np.pi)

    def joint(u0):
        uc = np.where(u0 > 0, np.abs(u0) ** (chi + 1.0), 0.0)
        return -R * Ic * uc - 0.75 * k3 * u0**2 + 1j * R * c_d * uc, 0.0

    return joint


def _iwan_model(p, a, modes, u_ref=1.0):
    """Iwan parameters ``(Omega, zeta_0, R, chi, k3)``."""
    Om, z0, R, chi, k3 = p
    return _eigen_backbone(modes, Om, z0, a, _iwan_joint(R, chi, k3))


def _cubic_viscous_model(p, a, modes, u_ref=1.0):
    """Parameters ``(Omega, zeta_0, k3, c1, c2)``: ``c(u0) = c1 u0 + c2 u0^2`` acts at the joint."""
    Om, z0, k3, c1, c2 = p
    return _eigen_backbone(modes, Om, z0, a, lambda u0: (-0.75 * k3 * u0**2 + 0j, c1 * u0 + c2 * u0**2))


_MODELS = {"iwan": _iwan_model, "cubic-viscous": _cubic_viscous_model}


def _weights(backbone):
    a = np.asarray(backbone.amplitude, float)
    w = np.asarray(backbone.omega, float)
    z = np.asarray(backbone.zeta, float)
    ok = np.isfinite(a) & np.isfinite(w) & np.isfinite(z) & (a > 0)
    sw = np.asarray(backbone.omega_stderr, float)
    sz = np.asarray(backbone.zeta_stderr, float)
    sw = np.where(np.isfinite(sw) & (sw > 0), sw, 0.0)
    sz = np.where(np.isfinite(sz) & (sz > 0), sz, 0.0)
    # floors: a backbone without errors (a model's) is fitted in relative terms
    sw = np.maximum(sw, 1e-7 * np.abs(w))
    sz = np.maximum(sz, 1e-4 * np.abs(z))
    return a[ok], w[ok], z[ok], sw[ok], sz[ok]


def _adequacy(r, n, k):
    chi2 = float(r @ r)
    dof = max(n - k, 1)
    return {"chi2_red": chi2 / dof, "aic": chi2 + 2 * k, "bic": chi2 + k * np.log(max(n, 1)),
            "n_points": n // 2, "n_parameters": k}


def _as_modes(modes, direction):
    if isinstance(modes, JointModes):
        return modes
    psi = float(modes)
    if not (np.isfinite(psi) and psi != 0):
        raise IdentificationError(f"joint shape must be a finite, non-zero relative motion per modal unit, got {modes!r}")
    return JointModes.single(psi, direction)


def _units(direction):
    unit = "rad" if direction == "rotation" else "m"
    force = "N m" if direction == "rotation" else "N"
    return unit, force


def _finish(law, names, sol_fun, J, G, p, a, w, z, modes, units, determined, not_determined, K_T, u_ref):
    """Covariance (scaled by the reduced chi-square when above 1), adequacy and the result object."""
    k = J.shape[1]
    ad = _adequacy(sol_fun, sol_fun.size, k)
    col = np.linalg.norm(J, axis=0)
    col[col == 0] = 1.0
    Js = J / col  # column scaling: the parameters differ by many orders of magnitude
    cov_x = np.linalg.pinv(Js.T @ Js) / np.outer(col, col) * max(ad["chi2_red"], 1.0)
    cov = G @ cov_x @ G.T
    wm, zm = _MODELS[law](p[:5], a, modes)
    ad.update(rms_omega_rel=float(np.sqrt(np.mean((wm / w - 1) ** 2))),
              rms_zeta_rel=float(np.sqrt(np.mean((zm / z - 1) ** 2))))
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    u0 = abs(modes.psi) * a
    return JointLawFit(law, names, p, se, cov, determined, not_determined, modes.psi, units, ad, a,
                       (float(u0.min()), float(u0.max())), K_T, modes, u_ref)


def fit_iwan(backbone, modes, *, cubic=True, K_T=None, direction="rotation") -> JointLawFit:
    """Fit the micro-slip Iwan law (plus an optional cubic part) to a backbone.

    Parameters
    ----------
    backbone : Backbone
        ``omega(a)``, ``zeta(a)`` of mode 1 with standard errors (points from stepped sine,
        ring-downs, or a model).
    modes : JointModes or float
        The linear modes and their joint shapes (from the updated FE model), or ``psi``
        of mode 1 alone.  The joint's other modes stiffen or soften mode 1 at second order
        in the joint's nonlinearity (4 % of ``zeta`` at the top of the seed rig's range).
    cubic : bool
        Include ``-k3 u^3`` (the rig's law has one); without it ``k3 = 0``.
    K_T : float, optional
        Stuck joint stiffness, only to report the ``F_S(beta)`` relation.
    direction : {"rotation", "transverse"}
        Sets the units (when ``modes`` is a number).

    Returns
    -------
    JointLawFit
        Parameters ``Omega``, ``zeta_0``, ``R``, ``chi``, ``k3`` and ``D_ref``: the energy
        dissipated per cycle at the reference joint amplitude ``u_ref`` (the geometric mean
        of the data's), the best-determined measure of the micro-slip level (``R`` itself
        is the level extrapolated to a unit amplitude and carries ``chi``'s error).
    """
    modes = _as_modes(modes, direction)
    psi = modes.psi
    a, w, z, sw, sz = _weights(backbone)
    if a.size < 4:
        raise IdentificationError(f"an Iwan fit needs at least 4 backbone points, got {a.size}")
    u0 = abs(psi) * a
    u_ref = float(np.exp(np.mean(np.log(u0))))
    i_lo = int(np.argmin(a))
    Om0, z_0 = float(w[i_lo]), float(z[i_lo])
    nk = 5 if cubic else 4

    # scaled unknowns: x = (Omega / Om0 - 1) / 1e-4, zeta0 / z_0, ln kappa, chi, k3 / k3s with
    # kappa = R u_ref^(chi + 1); differences then step sensibly in every direction
    def unpack(x):
        chi = x[3]
        k3 = x[4] * k3s if cubic else 0.0
        return np.array([Om0 * (1 + 1e-4 * x[0]), z_0 * x[1], np.exp(x[2]) / u_ref ** (chi + 1.0), chi, k3])

    def resid(x):
        wm, zm = _iwan_model(unpack(x), a, modes)
        return np.concatenate([(wm - w) / sw, (zm - z) / sz])

    # starting values: chi and the micro-slip level from the growth of the damping
    dz = np.maximum(z - 0.9 * z_0, 1e-12)
    slope = np.polyfit(np.log(u0), np.log(dz), 1)[0] if np.ptp(np.log(u0)) > 0 else 0.7
    chi0 = float(np.clip(slope - 1.0, -0.9, 0.9))
    cd = 4.0 / ((chi0 + 2.0) * (chi0 + 3.0) * np.pi)
    order = np.argsort(u0)
    kap0 = float(np.interp(u_ref, u0[order], dz[order]) * 2 * Om0**2 / (psi**2 * cd))
    k3s = max(kap0, 1e-300) / u_ref**2  # a cubic as strong as the micro-slip at u_ref
    x0 = np.array([0.0, 0.9, np.log(max(kap0, 1e-300)), chi0, 0.0][:nk])
    lo = np.array([-5e3, 0.0, -np.inf, -0.99, -np.inf][:nk])
    hi = np.array([5e3, 1e3, np.inf, 0.99, np.inf][:nk])
    sol = optimize.least_squares(resid, x0, bounds=(lo, hi), method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12,
                                 max_nfev=4000)
    x = sol.x
    p = unpack(x)
    G = np.zeros((6, nk))  # (Omega, zeta0, R, chi, k3, D_ref) from the scaled unknowns
    G[0, 0] = 1e-4 * Om0
    G[1, 1] = z_0
    G[3, 3] = 1.0
    G[2, 2] = p[2]
    G[2, 3] = -p[2] * np.log(u_ref)
    if cubic:
        G[4, 4] = k3s
    kappa = float(np.exp(x[2]))
    D_ref = 4.0 * kappa * u_ref**2 / ((p[3] + 2.0) * (p[3] + 3.0))
    G[5, 2] = D_ref
    G[5, 3] = -D_ref * (1.0 / (p[3] + 2.0) + 1.0 / (p[3] + 3.0))
    unit, force = _units(modes.direction)
    units = {"Omega": "rad/s", "zeta_0": "", "R": f"{force} / {unit}^(chi+2)", "chi": "", "k3": f"{force} / {unit}^3",
             "D_ref": f"J at u_ref = {u_ref:.4g} {unit}"}
    names = ("Omega", "zeta_0", "R", "chi", "k3", "D_ref")
    det = names if cubic else tuple(n for n in names if n != "k3")
    return _finish("iwan", names, sol.fun, sol.jac, G, np.append(p, D_ref), a, w, z, modes, units, det,
                   ("F_S", "K_T", "beta"), None if K_T is None else float(K_T), u_ref)


def fit_cubic_viscous(backbone, modes, *, direction="rotation") -> JointLawFit:
    """Fit the seed's cubic stiffness + amplitude-dependent viscous damping in joint coordinates.

    Started from the single-mode closed forms (linear least squares), then refined with
    the same multi-mode first-harmonic model as :func:`fit_iwan`.
    """
    modes = _as_modes(modes, direction)
    psi = modes.psi
    a, w, z, sw, sz = _weights(backbone)
    if a.size < 4:
        raise IdentificationError(f"a cubic + viscous fit needs at least 4 backbone points, got {a.size}")
    u0 = abs(psi) * a
    A1 = np.column_stack([np.ones_like(u0), -0.75 * psi**2 * u0**2])
    c1, *_ = np.linalg.lstsq(A1, w**2, rcond=None)
    A2 = np.column_stack([np.ones_like(u0), psi**2 * u0, psi**2 * u0**2])
    c2, *_ = np.linalg.lstsq(A2, 2 * w * z, rcond=None)
    Om = float(np.sqrt(max(c1[0], 1e-300)))
    p0 = np.array([Om, c2[0] / (2 * Om), c1[1], c2[1], c2[2]])
    scale = np.where(p0 != 0, np.abs(p0), 1.0)
    scale[0] = 1e-4 * Om

    def unpack(x):  # scaled unknowns around the closed-form start
        return np.concatenate([[Om + scale[0] * x[0]], scale[1:] * x[1:]])

    def resid(x):
        wm, zm = _cubic_viscous_model(unpack(x), a, modes)
        return np.concatenate([(wm - w) / sw, (zm - z) / sz])

    x0 = np.concatenate([[0.0], p0[1:] / scale[1:]])
    sol = optimize.least_squares(resid, x0, method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=4000)
    p_fit = unpack(sol.x)
    unit, force = _units(modes.direction)
    units = {"Omega": "rad/s", "zeta_0": "", "k3": f"{force} / {unit}^3", "c1": f"{force} s / {unit}^2",
             "c2": f"{force} s / {unit}^3"}
    names = ("Omega", "zeta_0", "k3", "c1", "c2")
    return _finish("cubic-viscous", names, sol.fun, sol.jac, np.diag(scale), p_fit, a, w, z, modes, units,
                   names, ("K_T",), None, None)


def fit_joint_laws(backbone, modes, *, K_T=None, direction="rotation") -> dict:
    """Both laws on the same backbone: ``{"iwan": JointLawFit, "cubic-viscous": JointLawFit}``."""
    return {"iwan": fit_iwan(backbone, modes, K_T=K_T, direction=direction),
            "cubic-viscous": fit_cubic_viscous(backbone, modes, direction=direction)}
