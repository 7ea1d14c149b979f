"""What a campaign identification returns: :class:`CampaignResult` and its groups' :class:`GroupResult`.

These classes hold what :mod:`jointid.app.campaign_fit` and :mod:`jointid.app.workflow`
computed; ``summary()`` writes it out (the content of ``results.json``) and computes nothing
of the identification: a record's measured energy per cycle, for instance, is computed by
the campaign fit and only read here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..identify.fsm import PooledFit
from ..identify.laws import PowerLaw
from ..identify.uncertainty import ci95
from .records import IdentifySettings

__all__ = ["GroupResult", "CampaignResult", "group_key"]


@dataclass(frozen=True)
class GroupResult:
    """One (preload, force level) group: pooled fit, band average (with the standard error and
    resolution of its ``k3``, :func:`jointid.numerics.intervals.band_mean_resolution`) and power law."""

    preload: object
    force_level: object
    record_indices: tuple
    pooled: PooledFit | None
    band: dict | None
    power_law: PowerLaw | None = None
    power_law_error: str | None = None
    gain: object = None  # GainFit when the force gain was identified
    band_resolution: dict | None = None  # standard error and resolution of the band-average k3

    def summary(self) -> dict:
        d = {"preload": self.preload, "force_level": self.force_level, "records": list(self.record_indices)}
        if self.gain is not None:
            g, se = self.gain.derived()["gain"]
            d.update(force_gain=g, force_gain_stderr=se, force_gain_ci95=ci95(g, se),
                     omega1_per_record=list(self.gain.omega1_per_record))
        if self.pooled is not None:
            d.update(
                omega1=self.pooled.omega1,
                omega1_stderr=self.pooled.omega1_stderr,
                f1_hz=self.pooled.omega1 / (2 * np.pi),
                k3=self.pooled.k3,
                k3_stderr=self.pooled.get_stderr("k3") if "k3" in self.pooled.shared_names else None,
                omega1_ci95=ci95(self.pooled.omega1, self.pooled.omega1_stderr),
                k3_ci95=ci95(self.pooled.k3, self.pooled.get_stderr("k3")) if "k3" in self.pooled.shared_names else None,
                method="paper (Table 5): pooled fit per force level, omega1 and k3 shared, one c per record",
                pooled=self.pooled.summary(),
            )
        if self.band is not None:
            d.update(
                omega1_mean=self.band["omega1"],
                f1_hz_mean=self.band["omega1"] / (2 * np.pi),
                k3_mean=self.band.get("k3"),
                band_average=self.band,
            )
        if self.band_resolution:
            d["band_resolution"] = dict(self.band_resolution)
        return d

    def __repr__(self):
        k3 = f", k3={self.pooled.k3:.4g}" if self.pooled is not None and self.pooled.k3 is not None else ""
        w1 = f", omega1={self.pooled.omega1:.6g} rad/s" if self.pooled is not None else ""
        return f"GroupResult(preload={self.preload!r}, force_level={self.force_level!r}: " \
               f"{len(self.record_indices)} records{w1}{k3})"

    def _repr_html_(self):
        from ..report.notebook import result_html

        return result_html(self)


@dataclass(frozen=True)
class CampaignResult:
    """Everything identified from a campaign.

    ``summary()`` is the content of ``results.json``; ``report()`` prints the tables.
    """

    name: str
    root: str
    settings: IdentifySettings
    records: tuple
    groups: tuple
    damping_laws: dict
    damping_law_errors: dict = field(default_factory=dict)
    repredictions: tuple = ()  # Reprediction per group (jointid.app.reprediction)
    loops: tuple = ()  # measured vs identified hysteresis loop errors per group
    structures: dict = field(default_factory=dict)  # preload -> Structure (physical campaigns; Table 4)
    channel_delay: object = None  # ChannelDelay applied to every record (jointid.identify.delay)
    channel_delay_error: str | None = None
    broadband: tuple = ()  # BroadbandGroup per group of multisine / random records (jointid.app.broadband_records)
    models: dict = field(default_factory=dict)  # PreloadModel per preload (one regression over its records)
    model_errors: dict = field(default_factory=dict)
    backbones: object = None  # CampaignBackbones (jointid.app.backbones): omega(a), zeta(a), joint laws
    adequacy: dict = field(default_factory=dict)  # AdequacyResult per preload (jointid.identify.adequacy)
    adequacy_errors: dict = field(default_factory=dict)
    selections: dict = field(default_factory=dict)  # SelectionResult per preload (terms="auto")
    selection_errors: dict = field(default_factory=dict)
    fit_checks: tuple = ()  # goodness of fit of the campaign-level regressions (jointid.app.fit_checks)
    hysteresis_loops: tuple = ()  # GroupLoops per group (jointid.app.reprediction): measured and identified loops

    @property
    def failed(self):
        return [r for r in self.records if not r.ok]

    @property
    def flagged(self):
        """Identified records flagged by a plausibility check (left out of the pooled fits unless
        ``settings.keep_flagged``)."""
        return [r for r in self.records if r.ok and r.flags]

    @property
    def misfits(self) -> list:
        """Campaign-level regressions whose model does not fit the data to their errors
        (:mod:`jointid.app.fit_checks`; ``results.json`` key ``fit_checks``)."""
        from .fit_checks import misfits

        return misfits(self.fit_checks)

    @property
    def force_level_unit(self):
        """Unit of the force levels (``results.json`` key ``force_level_unit``): ``"N"`` (the force channel
        with its known gain), ``"V"`` (the recorded excitation, the force gain identified), ``None`` when a
        level is a label (text) or there are no groups."""
        levels = [g.force_level for g in self.groups]
        if not levels or not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                                 for v in levels):
            return None
        return "V" if str(getattr(self.settings, "force_gain", "known")) == "unknown" else "N"

    def group(self, preload, force_level) -> GroupResult:
        for g in self.groups:
            if g.preload == preload and g.force_level == force_level:
                return g
        raise KeyError((preload, force_level))

    def summary(self) -> dict:
        from .. import __version__

        return {
            "jointid_version": __version__,
            "campaign": {"name": self.name, "folder": self.root},
            "settings": self.settings.summary(),
            "records": [_record_summary(r) for r in self.records],
            "groups": [g.summary() for g in self.groups],
            "force_level_unit": self.force_level_unit,
            "damping_law": [
                {"preload": p, **law.summary()} if law is not None else {"preload": p, "coefficients": None,
                                                                          "error": self.damping_law_errors.get(p)}
                for p, law in self.damping_laws.items()
            ],
            "power_law": [
                {"preload": g.preload, "force_level": g.force_level,
                 **(g.power_law.summary() if g.power_law else {"alpha": None, "n": None, "error": g.power_law_error})}
                for g in self.groups
            ],
            "models": [
                self.models[p].summary() if self.models.get(p) is not None
                else {"preload": p, "omega1": None, "error": self.model_errors.get(p)}
                for p in sorted(set(self.models) | set(self.model_errors), key=group_key)
            ],
            "n_records": len(self.records),
            "n_failed": len(self.failed),
            "reprediction": {"groups": [r.summary() for r in self.repredictions], "loops": list(self.loops)},
            "structures": [{"preload": p, **s.summary()} for p, s in self.structures.items()],
            "channel_delay": (self.channel_delay.summary() if self.channel_delay is not None
                              else {"delay_s": None, "error": self.channel_delay_error}),
            "broadband": [b.summary() for b in self.broadband],
            "flagged": [{"index": r.spec.index, "file": r.spec.file, "flags": [f.name for f in r.flags],
                         "in_pooled_fits": self.settings.keep_flagged} for r in self.flagged],
            "backbones": None if self.backbones is None else self.backbones.summary(),
            "adequacy": [self.adequacy[p].summary() if self.adequacy.get(p) is not None
                         else {"preload": p, "adequate": None, "error": self.adequacy_errors.get(p)}
                         for p in sorted(set(self.adequacy) | set(self.adequacy_errors), key=group_key)],
            "fit_checks": list(self.fit_checks),
            "selection": [self.selections[p].summary() if self.selections.get(p) is not None
                          else {"preload": p, "selected": None, "error": self.selection_errors.get(p)}
                          for p in sorted(set(self.selections) | set(self.selection_errors), key=group_key)],
        }

    def report(self) -> str:
        from ..report.tables import campaign_report

        return campaign_report(self)

    def __repr__(self):
        preloads = ", ".join(str(p) for p in self.damping_laws)
        return (f"CampaignResult({self.name!r}: {len(self.records)} records, {len(self.failed)} failed, "
                f"{len(self.flagged)} flagged, {len(self.groups)} groups, preloads [{preloads}])")

    def _repr_html_(self):
        from ..report.notebook import result_html

        return result_html(self)


def group_key(value):
    """Sort key of a preload or force level: numbers first, in order, then the rest as text."""
    return (0, value) if isinstance(value, (int, float)) else (1, str(value))


def _record_summary(r) -> dict:
    """A record's summary with the 95 % intervals of its estimates and its measured energy per cycle."""
    d = r.summary()
    fit = r.fit
    if fit is None:
        return d
    gain_free = getattr(r, "omega1_own", None) is not None
    c_se = r.c_pooled_stderr if gain_free else fit.c_stderr
    d.update(
        c_stderr=c_se,
        c_ci95=ci95(d.get("c"), c_se),
        c_pooled_ci95=ci95(r.c_pooled, r.c_pooled_stderr),
    )
    if not gain_free:
        d.update(
            omega1_stderr=fit.omega1_stderr,
            omega1_ci95=ci95(fit.omega1, fit.omega1_stderr),
            ci95={n: ci95(v, s) for n, v, s in zip(fit.coefficient_names, fit.coefficients, fit.stderr)},
        )
    measured = getattr(r, "energy_measured", None)  # computed by the campaign fit
    if measured is not None:
        d["energy_measured"] = measured
    return d
