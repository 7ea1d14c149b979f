"""The Brake-Reuss beam: first-harmonic stepped sine at four force levels and a hammer ring-down (public data).

The recipe is what a user with the exports does (``examples/brb_import.toml``): import the
controller's first harmonics (``FRdata.ForceControl``, four levels) and the impact's
driving-point acceleration (no force channel) into a campaign, identify it
(:mod:`jointid.app.firstharmonic_campaign`), then check the identified model:

* every level re-predicted from its measured forces (amplitude and phase errors);
* each level predicted from the other three (leave one level out): the peaks;
* the standard errors by a Monte Carlo of synthetic campaigns with the same lines, forces
  and noise (:func:`jointid.identify.firstharmonic.simulate_levels`): std(z) per parameter;
* the hammer backbone (band-limited around mode 1) against the stepped-sine one, at the
  same amplitude: the first-harmonic acceleration amplitude at the driving point.

:func:`brb_example` returns a :class:`BrbResult`; ``jointid public-data --out DIR`` writes
its identify set to ``DIR/brb`` (``results.json``, ``report.html``, figures).
"""

from __future__ import annotations

import html
import tempfile
import warnings
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import JointidWarning
from ..identify.firstharmonic import fit_first_harmonic, simulate_levels

__all__ = ["brb_example", "BrbResult", "BRB_DESCRIPTION", "BRB_GOALS"]

#: The import description of the example (package data, ``examples/brb_import.toml``).
BRB_DESCRIPTION = "brb_import.toml"
#: What the worked example is held to (docs/public-data.md).
BRB_GOALS = {"amplitude_rms_rel": 0.05, "phase_rms_deg": 4.0, "lolo_top_peak_amplitude_rel": 0.03,
             "lolo_top_peak_frequency_rel": 5e-4, "std_z": (0.8, 1.25)}


def monte_carlo_std_z(fit, n_campaigns=100, seed=2023) -> dict:
    """std(z) of every parameter over synthetic campaigns with the fit's lines, forces and noise."""
    rng = np.random.default_rng(seed)
    zs = []
    fl, dl = fit.model.frequency_law.kind, fit.model.damping_law.kind
    for _ in range(int(n_campaigns)):
        levels = simulate_levels(fit, rng)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            f = fit_first_harmonic(levels, fl, dl, a_ref=fit.model.a_ref, repredict=False, low_level=False)
        zs.append((f.params - fit.params) / f.stderr)
    zs = np.array(zs)
    sd = zs.std(axis=0, ddof=1)
    return {"n_campaigns": int(n_campaigns), "seed": int(seed), "parameters": fit.names,
            "std_z": [float(v) for v in sd], "mean_z": [float(v) for v in zs.mean(axis=0)],
            "std_z_range": [float(sd.min()), float(sd.max())]}


@dataclass(frozen=True, eq=False)
class BrbResult:
    """The BRB worked example: the identified campaign and its checks."""

    campaign: object  # FirstHarmonicCampaignResult (with the checks in its extra keys)
    checks: dict = field(default_factory=dict)

    @property
    def preload(self):
        return self.campaign.preloads[0]

    def summary(self) -> dict:
        return {"campaign": self.campaign.name, **self.checks}

    def report(self) -> str:
        c = self.checks
        lines = ["Brake-Reuss beam: force-controlled stepped sine (first harmonics, 4 levels) and a hammer ring-down",
                 self.campaign.report(), "", "Checks:"]
        for lv in c["levels"]:
            lines.append(f"  {lv['level']:<12} re-predicted: amplitude {100 * lv['amplitude_rms_rel']:.2f} % rms, "
                         f"phase {lv['phase_rms_deg']:.2f} deg rms")
        t = c["lolo_top"]
        lines.append(f"  top level from the other three: peak amplitude {100 * t['amplitude_error_rel']:+.2f} %, "
                     f"peak frequency {100 * t['frequency_error_rel']:+.4f} %")
        mc = c["monte_carlo"]
        lines.append(f"  Monte Carlo ({mc['n_campaigns']} campaigns): std(z) {mc['std_z_range'][0]:.2f} .. "
                     f"{mc['std_z_range'][1]:.2f}")
        h = c["hammer"]
        lines.append(f"  hammer backbone: {'monotone' if h['monotone'] else 'NOT monotone'} over "
                     f"{h['amplitude_range'][0]:.3g} .. {h['amplitude_range'][1]:.3g} m/s^2 above the noise floor")
        return "\n".join(lines)

    def report_parts(self):
        return [line.strip() for line in self.report().splitlines() if line.strip()], []

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"

    def plot(self):
        """The backbones of both tests on one pair of axes."""
        figs = self.campaign.figures()
        return [f for n, _, f in figs if n.startswith("backbone")][0]

    def write(self, folder) -> dict:
        """The identify set of the campaign (``results.json`` with the checks, report, figures) in ``folder``."""
        from ..report.output import write_results

        return write_results(self.campaign, folder)


def brb_example(*, n_monte_carlo=100, seed=2023, laws=None) -> BrbResult:
    """Import, identify and check the BRB data (module docstring).

    Raises
    ------
    RecordFileNotFoundError, ManifestError
        When the shared data folder (``brb_cenedese``) is missing.
    """
    from dataclasses import replace

    from ..io.importer import import_campaign
    from .firstharmonic_campaign import identify_first_harmonic_campaign

    desc = resources.files("jointid.examples") / BRB_DESCRIPTION
    with resources.as_file(desc) as path, tempfile.TemporaryDirectory(prefix="jointid-brb-") as tmp:
        import_campaign(Path(path), Path(tmp) / "campaign")
        res = identify_first_harmonic_campaign(Path(tmp) / "campaign", laws=laws)
    p = res.preloads[0]
    fit = p.fit
    levels = [{"level": pr.label, "amplitude_rms_rel": pr.amplitude_rms_rel, "phase_rms_deg": pr.phase_rms_deg,
               "peak": pr.peaks()} for pr in fit.predictions]
    top = max(range(len(fit.levels)), key=lambda j: float(np.max(fit.levels[j].accel)))
    lolo_top = p.lolo[top]["peaks"] if "peaks" in p.lolo[top] else {"error": p.lolo[top].get("error")}
    mc = monte_carlo_std_z(fit, n_monte_carlo, seed)
    if not p.ringdowns:
        warnings.warn("the hammer ring-down could not be analysed", JointidWarning, stacklevel=2)
        hammer = {"monotone": None, "amplitude_range": [np.nan, np.nan]}
    else:
        _, b, d, m = p.ringdowns[0]
        hammer = {**m, "n_windows": len(b), "frequency_hz_range": [float(b.frequency_hz.min()),
                                                                   float(b.frequency_hz.max())],
                  "zeta_range": [float(b.zeta.min()), float(b.zeta.max())]}
    checks = {"goals": {k: list(v) if isinstance(v, tuple) else v for k, v in BRB_GOALS.items()},
              "levels": levels, "lolo_top": lolo_top, "lolo": p.lolo_summary(), "monte_carlo": mc, "hammer": hammer,
              "amplitude": "first-harmonic acceleration amplitude at the driving point (accelerometer 3) [m/s^2]"}
    res = replace(res, extra={"public_data_checks": checks})
    return BrbResult(res, checks)
