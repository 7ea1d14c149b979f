"""The backbone curve as a result: amplitude-dependent natural frequency ``omega(a)`` and damping
ratio ``zeta(a)`` with their standard errors and 95 % bands.

One type for every source: ring-down windows (:meth:`jointid.signal.ringdown.DecayFit.backbone`),
stepped-sine records and identified models (:mod:`jointid.identify.backbone`, which computes
them and re-exports this class), the virtual rig.  It is plain data (arrays, a label, JSON-safe
metadata), so it lives on the signal floor where the first of those sources is.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field

import numpy as np

from ..numerics.intervals import Z95

__all__ = ["Backbone", "Z95"]


def _readonly(a):
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Backbone:
    """``omega(a)`` and ``zeta(a)`` with standard errors and 95 % bands.

    Attributes
    ----------
    amplitude : ndarray
        First-harmonic amplitude ``a`` of the modal displacement.
    omega : ndarray
        Natural frequency at ``a`` [rad/s].
    zeta : ndarray
        Damping ratio at ``a``.
    omega_stderr, zeta_stderr : ndarray
        Standard errors (``nan`` when unknown).
    source : str
        ``"model"``, ``"stepped-sine"``, ``"phase-resonance"``, ``"ringdown"`` or ``"rig"``.
    amplitude_stderr : ndarray
        Standard error of ``a`` (measured points; zero for a model).
    label : str
        Free text (preload, force level ...).
    meta : dict
        Per-source extras (force level of each point, flags ...), JSON-safe.
    """

    amplitude: np.ndarray
    omega: np.ndarray
    zeta: np.ndarray
    omega_stderr: np.ndarray
    zeta_stderr: np.ndarray
    source: str
    amplitude_stderr: np.ndarray | None = None
    label: str = ""
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        a = _readonly(np.atleast_1d(self.amplitude))
        object.__setattr__(self, "amplitude", a)
        for name in ("omega", "zeta", "omega_stderr", "zeta_stderr"):
            v = _readonly(np.broadcast_to(np.asarray(getattr(self, name), float), a.shape))
            object.__setattr__(self, name, v)
        ase = np.zeros_like(a) if self.amplitude_stderr is None else self.amplitude_stderr
        object.__setattr__(self, "amplitude_stderr", _readonly(np.broadcast_to(np.asarray(ase, float), a.shape)))

    def __len__(self):
        return int(self.amplitude.size)

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    @property
    def omega_band(self) -> np.ndarray:
        """95 % band of ``omega``: shape ``(2, n)`` (lower, upper)."""
        return np.array([self.omega - Z95 * self.omega_stderr, self.omega + Z95 * self.omega_stderr])

    @property
    def zeta_band(self) -> np.ndarray:
        """95 % band of ``zeta``: shape ``(2, n)``."""
        return np.array([self.zeta - Z95 * self.zeta_stderr, self.zeta + Z95 * self.zeta_stderr])

    @classmethod
    def from_summary(cls, d) -> "Backbone":
        """Rebuild a backbone from its :meth:`summary` (a ``results.json`` entry)."""
        def arr(key):
            return np.array([np.nan if v is None else v for v in d.get(key) or []], float)

        a = arr("amplitude")
        ase = arr("amplitude_stderr") if d.get("amplitude_stderr") else np.zeros_like(a)
        return cls(a, arr("omega"), arr("zeta"), arr("omega_stderr"), arr("zeta_stderr"), d.get("source", ""),
                   ase, d.get("label", ""), dict(d.get("meta") or {}))

    def select(self, mask) -> "Backbone":
        """The points where ``mask`` is true (meta lists of the same length are filtered too)."""
        m = np.asarray(mask, bool)
        meta = {k: ([x for x, keep in zip(v, m) if keep] if isinstance(v, list) and len(v) == m.size else v)
                for k, v in self.meta.items()}
        return Backbone(self.amplitude[m], self.omega[m], self.zeta[m], self.omega_stderr[m], self.zeta_stderr[m],
                        self.source, self.amplitude_stderr[m], self.label, meta)

    def sorted(self) -> "Backbone":
        """The points in increasing amplitude."""
        order = np.argsort(self.amplitude, kind="stable")
        meta = {k: ([v[i] for i in order] if isinstance(v, list) and len(v) == order.size else v)
                for k, v in self.meta.items()}
        return Backbone(self.amplitude[order], self.omega[order], self.zeta[order], self.omega_stderr[order],
                        self.zeta_stderr[order], self.source, self.amplitude_stderr[order], self.label, meta)

    def decades(self) -> float:
        """Amplitude range covered, in decades (``log10(max / min)``)."""
        a = self.amplitude[self.amplitude > 0]
        return float(np.log10(a.max() / a.min())) if a.size else 0.0

    def summary(self) -> dict:
        def lst(x):
            return [None if not np.isfinite(v) else float(v) for v in x]

        return {
            "source": self.source,
            "label": self.label,
            "n_points": len(self),
            "amplitude": lst(self.amplitude),
            "amplitude_stderr": lst(self.amplitude_stderr),
            "frequency_hz": lst(self.frequency_hz),
            "omega": lst(self.omega),
            "omega_stderr": lst(self.omega_stderr),
            "zeta": lst(self.zeta),
            "zeta_stderr": lst(self.zeta_stderr),
            "decades": self.decades(),
            **({"meta": self.meta} if self.meta else {}),
        }

    def report(self) -> str:
        lines = [f"Backbone ({self.source}{', ' + self.label if self.label else ''}): {len(self)} points, "
                 f"{self.decades():.2f} decades of amplitude",
                 f"  {'a':>11} {'f [Hz]':>12} {'± (95%)':>10} {'zeta [%]':>10} {'± (95%)':>10}"]
        idx = range(len(self)) if len(self) <= 12 else np.unique(np.linspace(0, len(self) - 1, 12).astype(int))
        for i in idx:
            lines.append(f"  {self.amplitude[i]:11.4e} {self.frequency_hz[i]:12.6f} "
                         f"{Z95 * self.omega_stderr[i] / (2 * np.pi):10.2g} {100 * self.zeta[i]:10.4f} "
                         f"{100 * Z95 * self.zeta_stderr[i]:10.2g}")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"

    def plot(self, ax=None, **kwargs):
        """Draw with :func:`jointid.report.backbone_plots.plot_backbone`; returns ``(fig, axes)``."""
        from .. import plotting

        return plotting.draw("backbone_plots.plot_backbone", self, ax=ax, **kwargs)
