"""Backbones of the public measured data (``../shared/data``), discussed in ``docs/public-data.md``.

:func:`unesp_backbone`
    UNESP bolted lap-joint beam, sine dwells 17-20 Hz: each dwell's equivalent
    linearisation at its tip amplitude.  The recorded "force" is the shaker voltage, so
    the force is the voltage times the gain identified by the pooled fit of
    :func:`jointid.app.public_data.unesp_sine_dwells`, and the response is re-timed by
    that example's channel-delay estimate (the response leads the voltage there, so it is
    moved later).
:func:`silverbox_backbone`
    Silverbox multilevel multisine: the backbone of each level's identified model
    (gain-free coefficients, bands from the fit's covariance) over that level's amplitude
    range.

Both return plain results with ``summary()`` / ``report()``; the data are read in place.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field

import numpy as np

from ..identify.backbone import Backbone, _fundamental, model_backbone

__all__ = ["PublicBackbones", "unesp_backbone", "silverbox_backbone"]


@dataclass(frozen=True, eq=False)
class PublicBackbones:
    """Backbones of one data set beside its published values."""

    dataset: str
    backbones: tuple = field(repr=False)
    reference: dict = field(default_factory=dict)
    notes: tuple = ()

    def summary(self) -> dict:
        return {"dataset": self.dataset, "reference": dict(self.reference), "notes": list(self.notes),
                "backbones": [b.summary() for b in self.backbones]}

    def report(self) -> str:
        lines = [f"{self.dataset}: reference {self.reference}"]
        lines += [b.report() for b in self.backbones]
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"

    def plot(self, ax=None):
        from ..report.backbone_plots import plot_backbones

        return plot_backbones(self.backbones, ax=ax, title=self.dataset)


def unesp_backbone(freqs=(17.0, 18.0, 19.0, 20.0), response="laser_velocity") -> PublicBackbones:
    """Equivalent linearisation of the UNESP dwells (tip coordinate, gain and delay from the pooled fit)."""
    from ..io.datasets import load_unesp_sine
    from .public_data import unesp_sine_dwells

    ex = unesp_sine_dwells(freqs, response=response, sensitivity=False)
    fit = ex.corrected if ex.corrected is not None else ex.fit
    tau = ex.delay_s if ex.corrected is not None and np.isfinite(ex.delay_s) else 0.0
    gain = fit.gain
    a, w_eq, z, a_se, w_se, z_se, fr = ([] for _ in range(7))
    for f in freqs:
        rec = load_unesp_sine(f)
        w = 2 * np.pi * f
        V1, sv = _fundamental(rec.time, rec["voltage"], w)
        Y1, sy = _fundamental(rec.time, rec[response], w)
        p = 1 if response == "laser_velocity" else 2
        X = Y1 / (1j * w) ** p * np.exp(1j * w * tau)  # q(t) = q_m(t + tau): moved later by |tau| when it leads
        sx = sy / w**p
        G = (gain * V1 + w**2 * X) / X
        gs = np.hypot(gain * sv / abs(X), abs(gain * V1) * sx / abs(X) ** 2)
        k, D = G.real, G.imag
        we = np.sqrt(k) if k > 0 else np.nan
        a.append(abs(X))
        a_se.append(sx)
        w_eq.append(we)
        z.append(D / (2 * w * we))
        w_se.append(gs / (2 * np.sqrt(2) * we))
        z_se.append(gs / np.sqrt(2) / (2 * w * we))
        fr.append(f)
    pts = Backbone(np.array(a), np.array(w_eq), np.array(z), np.array(w_se), np.array(z_se), "stepped-sine",
                   np.array(a_se), "UNESP 5 Nm, tip", {"frequency_hz": fr, "gain": float(gain), "delay_s": float(tau)})
    notes = (
        f"force = {gain:.4g} x shaker voltage (pooled-fit gain, tip-coordinate units), response re-timed by the "
        f"example's phase diagnostic tau = {1e3 * tau:.3f} ms (the response "
        f"{'leads' if tau < 0 else 'lags'} the voltage by {abs(1e3 * tau):.3f} ms): the damping ratios inherit "
        "both choices",
        "the stated errors hold the noise only, not the error of the gain and of the delay",
    )
    return PublicBackbones("UNESP bolted beam, sine dwells", (pts,), {"f1_hz_random_test": 18.75}, notes)


def silverbox_backbone(levels=None, n_points=15) -> PublicBackbones:
    """Backbone of the identified model at each Silverbox level (gain-free, with 95 % bands)."""
    from .public_data import SILVERBOX_REFERENCE, silverbox_multilevel

    res = silverbox_multilevel(levels)
    out = []
    for lv, fit in zip(res.levels, res.fits):
        names = list(fit.coefficient_names)
        im = names.index("m")
        m = fit.coefficients[im]
        keep = [i for i in range(len(names)) if i != im]
        theta = fit.coefficients[keep] / m
        # d(theta_j / m): 1/m on theta_j, -theta_j / m^2 on m
        J = np.zeros((len(keep), len(names)))
        for r, i in enumerate(keep):
            J[r, i] = 1.0 / m
            J[r, im] = -fit.coefficients[i] / m**2
        cov = J @ fit.covariance @ J.T
        amp = np.geomspace(fit.q_max / 30, fit.q_max, int(n_points))
        out.append(model_backbone(fit.terms, theta, amp, covariance=cov, label=f"{lv} mV"))
    notes = ("amplitude: first harmonic of the output voltage about its mean; each level's backbone spans 1.5 decades "
             "below that level's largest output",)
    ref = {k: SILVERBOX_REFERENCE[k] for k in ("f1_hz", "zeta") if k in SILVERBOX_REFERENCE}
    return PublicBackbones("Silverbox multilevel (Noel)", tuple(out), ref, notes)
