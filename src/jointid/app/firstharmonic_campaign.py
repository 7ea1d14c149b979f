"""Identify a campaign of first-harmonic records (stepped-sine controller exports) and force-free ring-downs.

A campaign whose records are ``excitation = "first-harmonic"`` (one line per frequency,
:mod:`jointid.io.firsth`), possibly with ``excitation = "ringdown"`` records that have no
force column, is identified per preload by :mod:`jointid.identify.firstharmonic`:

1. every first-harmonic record is read and checked; one that cannot be read fails alone;
2. the pair of amplitude laws is chosen by leave-one-level-out prediction
   (:func:`~jointid.identify.firstharmonic.select_laws`) unless given;
3. the single-nonlinear-mode model is fitted on all lines of all levels together, every
   level is re-predicted from its measured forces, each level is also predicted from the
   other levels alone (leave one level out), and the residuals are checked;
4. the ring-downs are band-limited around the identified mode and their backbones drawn
   against the same amplitude, the first-harmonic acceleration amplitude at the driving
   point (``accel`` column of the ring-down record: the driving point's accelerometer).

The result writes the identify set (``results.json`` with the identify keys, ``report.txt``,
``report.html``, figures) through :func:`jointid.report.output.write_results`.
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import IdentificationError, JointidError, JointidWarning, nearest_name, where
from ..identify.backbone import Backbone
from ..identify.firstharmonic import (
    AMPLITUDE_UNIT,
    DEFAULT_CANDIDATES,
    FirstHarmonicLevel,
    adequacy,
    fit_first_harmonic,
    leave_one_level_out,
    select_laws,
)
from ..io.campaign import Campaign, load_campaign
from ..signal.ringdown import modal_ringdown, monotone_check

__all__ = ["is_first_harmonic_campaign", "identify_first_harmonic_campaign", "FirstHarmonicCampaignResult",
           "FirstHarmonicPreload", "RecordOutcome", "ringdown_backbone", "compare_with_model"]


def _raw_entry(campaign: Campaign, spec) -> dict:
    """The ``[[record]]`` table of a record as written in the manifest (empty when not at hand)."""
    entries = (campaign.manifest or {}).get("record")
    if isinstance(entries, list) and 0 <= spec.index < len(entries) and isinstance(entries[spec.index], dict):
        return entries[spec.index]
    return {}


def _nearest(value, choices):
    """The valid choice nearest to a misspelt ``value`` (None when none is near)."""
    if not isinstance(value, str):
        return None
    close = nearest_name(value, choices)
    return close if close != value else None


def _intended_kind(campaign: Campaign, spec):
    """The kind of a record: its excitation, or for an entry the manifest refused (its error fails that record
    alone) the kind it was meant to be (a valid excitation, the nearest to a misspelt one, or
    ``"first-harmonic"`` when it has a ``control`` key); None when it cannot be told."""
    if not spec.error:
        return spec.excitation
    from ..io.campaign import EXCITATIONS

    raw = _raw_entry(campaign, spec)
    kind = raw.get("excitation", EXCITATIONS[0])
    if isinstance(kind, str) and kind in EXCITATIONS:
        return kind
    near = _nearest(kind, EXCITATIONS)
    if near is not None:
        return near
    return "first-harmonic" if "control" in raw else None


def _manifest_hint(campaign: Campaign, spec) -> str:
    """``"; did you mean 'first-harmonic'?"`` for a misspelt ``excitation`` or ``control`` of an entry."""
    from ..io.campaign import CONTROLS, EXCITATIONS

    raw = _raw_entry(campaign, spec)
    hints = []
    for key, choices in (("excitation", EXCITATIONS), ("control", CONTROLS)):
        value = raw.get(key)
        if value is None or value in choices:
            continue
        near = _nearest(value, choices)
        if near is not None:  # the manifest's message names the key, the value and the valid ones
            hints.append(f"{key} = {value!r}: did you mean {near!r}?")
    return ("; " + "; ".join(hints)) if hints else ""


def is_first_harmonic_campaign(campaign: Campaign) -> bool:
    """Whether the campaign holds first-harmonic records (with, at most, force-free ring-downs besides).

    A record whose manifest entry was refused (a misspelt ``excitation`` or a bad ``control``)
    counts as the kind it was meant to be: it fails alone, the campaign goes on.

    Raises
    ------
    IdentificationError
        First-harmonic records mixed with time records of stepped sines or broadband tests; a
        campaign of ring-down records only (nothing to fit a model on); a first-harmonic
        campaign with ``coordinates = "physical"`` (its ``[structure]`` would not be used).
    """
    manifest = campaign.root / "campaign.toml"
    kinds = {_intended_kind(campaign, r) for r in campaign.records} - {None}
    if kinds == {"ringdown"}:
        raise IdentificationError(
            f"{manifest}: the campaign holds only ring-down records ({len(campaign.records)}): nothing to identify "
            "from; a ring-down is identified beside the first-harmonic (or stepped-sine) records of its preload, "
            "whose model gives the mode it is band-limited around and compared with: add those records")
    if "first-harmonic" not in kinds:
        return False
    other = kinds - {"first-harmonic", "ringdown"}
    if other:
        raise IdentificationError(f"{manifest}: first-harmonic records are identified on "
                                  f"their own (with ring-downs); this campaign also has {sorted(other)} records: "
                                  f"put them in a campaign of their own")
    if campaign.coordinates == "physical":
        raise IdentificationError(
            f"{manifest}: [campaign] coordinates = \"physical\" with a [structure] table does not apply to "
            "first-harmonic records: they hold the force and the acceleration at the driving point (one nonlinear "
            "mode's accelerance) and the structure's mode shapes and sensors would be ignored; write coordinates = "
            "\"modal\" and remove [structure]")
    return True


@dataclass(frozen=True)
class RecordOutcome:
    """What became of one record of a first-harmonic campaign."""

    spec: object
    ok: bool
    error: str | None = None
    kind: str = "first-harmonic"
    n_lines: int = 0
    flags: tuple = ()
    warnings: tuple = ()

    def summary(self) -> dict:
        s = self.spec
        return {"index": s.index, "file": s.file, "preload": s.preload, "force_level": s.force_level,
                "excitation": s.excitation, "control": s.extra.get("control", "force") if self.kind ==
                "first-harmonic" else None, "status": "ok" if self.ok else "failed", "error": self.error,
                "n_lines": self.n_lines, "flags": [], "warnings": list(self.warnings)}


def ringdown_backbone(t, accel, frequency_hz, label="", **options):
    """Band-limited ring-down backbone of the mode near ``frequency_hz``, against the acceleration amplitude.

    Returns ``(Backbone, DecayFit, monotone check dict)``.
    """
    hw = RINGDOWN_HALF_WIDTH
    d = modal_ringdown(t, accel, f_range=((1 - hw) * frequency_hz, (1 + hw) * frequency_hz), **options)
    b = d.backbone(label=label, measure="signal", amplitude_unit=AMPLITUDE_UNIT)
    mono = monotone_check(b.amplitude, b.omega, b.omega_stderr) if len(b) >= 3 else {"monotone": None}
    floor = d.signal_amplitude[d.below_noise_floor]
    mono["noise_floor_amplitude"] = float(floor.max()) if floor.size else None
    if len(b):  # noise-floor bias of the amplitude at the lowest window kept: (se / a)^2 (fit_decay)
        k = int(np.argmin(b.amplitude))
        snr = float(b.amplitude[k] / b.amplitude_stderr[k]) if b.amplitude_stderr[k] > 0 else np.inf
        mono["lowest_window_snr"] = snr
        mono["amplitude_bias_rel_at_lowest"] = float(1 / snr**2)
        mono["floor_amplitude_estimate"] = float(d.snr_min * np.median(d.signal_amplitude_stderr))
    return b, d, mono


def compare_with_model(fit, ring: Backbone) -> dict:
    """Ring-down backbone against the stepped-sine model where their amplitudes overlap.

    ``delta_f_hz``: ring-down minus model natural frequency (mean, smallest, largest over the
    overlapping windows) with the combined standard error at the window of largest
    difference; ``zeta_ratio``: ring-down over model damping ratio.
    """
    lo, hi = fit.amplitude_range
    if not len(ring):
        return {"overlap": None, "n_windows": 0,
                "note": f"no overlap: the ring-down has no window above the noise floor, stepped sine "
                        f"{lo:.3g}..{hi:.3g}"}
    m = (ring.amplitude >= lo) & (ring.amplitude <= hi)
    if not m.any():
        return {"overlap": None, "n_windows": 0,
                "note": f"no overlap: ring-down {ring.amplitude.min():.3g}..{ring.amplitude.max():.3g}, "
                        f"stepped sine {lo:.3g}..{hi:.3g}"}
    a = ring.amplitude[m]
    mb = fit.backbone(amplitudes=a)
    df = (ring.omega[m] - mb.omega) / (2 * np.pi)
    se = np.hypot(ring.omega_stderr[m], mb.omega_stderr) / (2 * np.pi)
    zr = ring.zeta[m] / mb.zeta
    k = int(np.argmax(np.abs(df)))
    return {"overlap": [float(a.min()), float(a.max())], "n_windows": int(m.sum()),
            "delta_f_hz": {"mean": float(df.mean()), "min": float(df.min()), "max": float(df.max()),
                           "stderr_at_max": float(se[k]), "at_amplitude": float(a[k])},
            "delta_f_rel_max": float(np.max(np.abs(df)) / (mb.omega[k] / (2 * np.pi))),
            "zeta_ratio": {"mean": float(zr.mean()), "min": float(zr.min()), "max": float(zr.max())}}


@dataclass(frozen=True, eq=False)
class FirstHarmonicPreload:
    """The identification of one preload: fit, selection, leave-one-level-out, adequacy, ring-downs."""

    preload: object
    fit: object = None  # FirstHarmonicFit
    selection: dict | None = None
    lolo: tuple = ()
    adequacy: dict | None = None
    ringdowns: tuple = ()  # (record index, Backbone, DecayFit summary, monotone dict)
    errors: dict = field(default_factory=dict)

    def backbones(self):
        """:class:`~jointid.app.backbones.PreloadBackbones`: model, stepped-sine lines, ring-downs."""
        from .backbones import PreloadBackbones

        model = stepped = None
        if self.fit is not None:
            model = self.fit.backbone(label=f"preload {self.preload} model")
            stepped = self.fit.line_points(label=f"preload {self.preload} lines")
        return PreloadBackbones(self.preload, model=model, stepped=stepped,
                                ringdown=tuple(r[1] for r in self.ringdowns), errors=dict(self.errors))

    def model_name(self) -> str:
        """The model in words: one nonlinear mode whose frequency and damping depend on the amplitude."""
        if self.fit is None:
            return "nonlinear-mode (amplitude-dependent natural frequency and damping ratio)"
        m = self.fit.model
        return (f"nonlinear-mode (amplitude-dependent natural frequency, law {m.frequency_law.kind}, and damping "
                f"ratio, law {m.damping_law.kind})")

    def adequacy_entry(self) -> dict:
        """results.json ``adequacy`` entry: the model, whether it holds (``adequate``) and why (``verdict``)."""
        if self.adequacy is None:
            why = "no model fitted" if self.fit is None else "no adequacy check"
            return {"preload": self.preload, "model": self.model_name(), "adequate": None,
                    "verdict": f"not assessed: {why}"}
        return {"preload": self.preload, "model": self.model_name(), **self.adequacy}

    def lolo_summary(self) -> list:
        out = []
        for e in self.lolo:
            if "error" in e:
                out.append({"label": e["label"], "error": e["error"]})
            else:
                out.append({"label": e["label"], "peak": e["peaks"], "amplitude_rms_rel": e["amplitude_rms_rel"],
                            "phase_rms_deg": e["phase_rms_deg"], "complex_rms_rel": e["complex_rms_rel"]})
        return out

    def summary(self) -> dict:
        return {"preload": self.preload, "fit": None if self.fit is None else self.fit.summary(),
                "selection": self.selection, "leave_one_level_out": self.lolo_summary(), "adequacy": self.adequacy,
                "ringdowns": [{"index": i, "decay": d, "monotone": m, "backbone": b.summary()}
                              for i, b, d, m in self.ringdowns],
                "errors": dict(self.errors)}


@dataclass(frozen=True, eq=False)
class FirstHarmonicCampaignResult:
    """Everything identified from a first-harmonic campaign (``summary()`` is ``results.json``)."""

    name: str
    root: str
    settings: object  # IdentifySettings (only keep_flagged is used)
    records: tuple
    preloads: tuple
    laws: tuple | None = None
    groups: tuple = ()  # no force-state groups: the keys of a stepped-sine identification stay empty
    models: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)  # more top-level keys of results.json (worked examples)
    notes: tuple = ()  # run-level messages (options that do not apply ...)

    @property
    def failed(self):
        return [r for r in self.records if not r.ok]

    @property
    def flagged(self):
        return [r for r in self.records if r.ok and r.flags]

    @property
    def backbones(self):
        from .backbones import CampaignBackbones

        return CampaignBackbones(tuple(p.backbones() for p in self.preloads))

    def stage_line(self) -> str:
        """The progress line of ``jointid identify`` once the campaign is identified."""
        n_levels = sum(1 for r in self.records if r.ok and r.kind == "first-harmonic")
        n_rings = sum(len(p.ringdowns) for p in self.preloads)
        n_models = sum(p.fit is not None for p in self.preloads)
        return (f"identified {len(self.records)} records ({n_levels} first-harmonic level(s), {n_rings} ring-down(s) "
                f"used, {len(self.failed)} failed), {n_models} nonlinear-mode model(s) of {len(self.preloads)} "
                f"preload(s): {'laws given' if self.laws else 'laws by leave-one-level-out'}, fit, re-prediction of "
                "every level from its forces, adequacy, backbones")

    def preload(self, label) -> FirstHarmonicPreload:
        for p in self.preloads:
            if p.preload == label:
                return p
        raise KeyError(label)

    def summary(self) -> dict:
        from .. import __version__

        bb = self.backbones.summary()
        for entry in bb["preloads"]:
            entry["amplitude_unit"] = AMPLITUDE_UNIT
            for key in ("model", "stepped_sine"):
                if entry.get(key):
                    entry[key]["amplitude_unit"] = AMPLITUDE_UNIT
            for r in entry.get("ringdown") or []:
                r["amplitude_unit"] = AMPLITUDE_UNIT
        fits = [(p.preload, p.fit) for p in self.preloads if p.fit is not None]
        return {
            "jointid_version": __version__,
            "campaign": {"name": self.name, "folder": self.root},
            "record_type": "first-harmonic",
            "settings": {"record_type": "first-harmonic", "laws": list(self.laws) if self.laws else "auto",
                         "amplitude": AMPLITUDE_UNIT},
            "records": [r.summary() for r in self.records],
            "groups": [],
            "damping_law": [],
            "power_law": [],
            "models": [{"preload": p, **f.summary()} for p, f in fits]
            + [{"preload": p.preload, "omega1": None, "error": "; ".join(p.errors.values())}
               for p in self.preloads if p.fit is None],
            "n_records": len(self.records),
            "n_failed": len(self.failed),
            "reprediction": {"groups": [{"preload": p, **pr.summary()} for p, f in fits for pr in f.predictions],
                             "loops": []},
            "structures": [],
            "channel_delay": {"delay_s": None, "error": "not applicable to first-harmonic records"},
            "broadband": [],
            "flagged": [],
            "backbones": bb,
            "adequacy": [p.adequacy_entry() for p in self.preloads],
            "selection": [{"preload": p.preload, **(p.selection or {"selected": list(self.laws or ())})}
                          for p in self.preloads],
            "first_harmonic": [p.summary() for p in self.preloads],
            "warnings": list(self.notes),
            **self.extra,
        }

    def report(self) -> str:
        lines = [f"Campaign {self.name!r}: {len(self.records)} records (first harmonics), {len(self.failed)} failed"]
        for r in self.failed:
            lines.append(f"  failed: {r.error}")
        lines += [f"  note: {n}" for n in self.notes]
        for p in self.preloads:
            lines.append("")
            lines.append(f"Preload {p.preload}:")
            if p.selection:
                lines.append(f"  laws chosen by leave-one-level-out: wn {p.selection['selected'][0]}, zeta "
                             f"{p.selection['selected'][1]} ({p.selection['criterion']})")
            if p.fit is not None:
                lines.append("  " + p.fit.report().replace("\n", "\n  "))
            if p.lolo:
                lines.append("  leave one level out (fit on the others, predict this level from its forces):")
                lines.append(f"    {'level':<12} {'peak a err %':>13} {'peak f err %':>13} {'amp rms %':>10} "
                             f"{'phase rms deg':>14}")
                for e in p.lolo:
                    if "error" in e:
                        lines.append(f"    {e['label']:<12} failed: {e['error']}")
                        continue
                    pk = e["peaks"]
                    lines.append(f"    {e['label']:<12} {100 * pk['amplitude_error_rel']:13.2f} "
                                 f"{100 * pk['frequency_error_rel']:13.4f} {100 * e['amplitude_rms_rel']:10.2f} "
                                 f"{e['phase_rms_deg']:14.2f}")
            if p.adequacy is not None:
                verdict = "adequate" if p.adequacy["adequate"] else "NOT adequate"
                lines.append(f"  residuals: {verdict}: {p.adequacy_entry()['verdict']}")
            for i, b, d, m in p.ringdowns:
                lines.append(f"  ring-down record {i}: {len(b)} windows above the noise floor, amplitude "
                             f"{b.amplitude.min():.3g} .. {b.amplitude.max():.3g} m/s^2, frequency "
                             f"{b.frequency_hz.min():.4f} .. {b.frequency_hz.max():.4f} Hz, "
                             f"{'monotone' if m.get('monotone') else 'not monotone'} in amplitude")
                c = m.get("vs_stepped_sine") or {}
                if c.get("overlap"):
                    lines.append(f"    against the stepped-sine model over {c['overlap'][0]:.3g} .. {c['overlap'][1]:.3g} "
                                 f"m/s^2: frequency {c['delta_f_hz']['min']:+.4f} .. {c['delta_f_hz']['max']:+.4f} Hz "
                                 f"(largest {100 * c['delta_f_rel_max']:.3f} %), damping ratio x "
                                 f"{c['zeta_ratio']['min']:.2f} .. {c['zeta_ratio']['max']:.2f}")
            for k, e in p.errors.items():
                lines.append(f"  {k}: {e}")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"

    def figures(self) -> list:
        """``(file name, caption, figure)`` of each preload: FRFs measured vs re-predicted, backbones."""
        from ..report.firstharmonic_plots import plot_first_harmonic_backbones, plot_level_predictions
        from ..report.formatting import slug

        out = []
        for p in self.preloads:
            if p.fit is None:
                continue
            fig, _ = plot_level_predictions(p.fit.predictions, title=f"preload {p.preload}: measured vs re-predicted")
            out.append((f"frf_{slug(p.preload)}.png", f"Preload {p.preload}: every level's first harmonics, "
                        "measured (points) and re-predicted from each line's measured force (lines)", fig))
            bbs = p.backbones()
            fig, _ = plot_first_harmonic_backbones([bbs.model, bbs.stepped] + list(bbs.ringdown),
                                                   title=f"preload {p.preload}: backbones")
            out.append((f"backbone_{slug(p.preload)}.png", f"Preload {p.preload}: backbones against the "
                        "first-harmonic acceleration amplitude at the driving point (95 % band and bars)", fig))
        return out

    def write_set(self, out, run_id, figures=True, html=True) -> dict:
        """The files of the identify set (called by :func:`jointid.report.output.write_results`)."""
        from ..io.results import atomic_write, write_csv, write_json
        from ..report.html import Section, figure_to_png, page_meta, write_html

        summary = self.summary()
        summary["run_id"] = run_id
        paths = {"results": write_json(out / "results.json", summary),
                 "report": atomic_write(out / "report.txt", self.report() + f"\n\nrun id {run_id}\n")}
        rows = []
        for p in self.preloads:
            if p.fit is None:
                continue
            for n, v, s in zip(p.fit.names, p.fit.params, p.fit.stderr):
                rows.append({"preload": p.preload, "parameter": n, "value": float(v), "stderr": float(s),
                             "ci95_low": float(v - 1.96 * s), "ci95_high": float(v + 1.96 * s)})
        paths["parameters"] = write_csv(out / "parameters.csv", rows)
        paths["records"] = write_csv(out / "records.csv", [
            {k: v for k, v in r.summary().items() if k not in ("flags", "warnings")} for r in self.records])
        figs = [(n, c, figure_to_png(f, dpi=110)) for n, c, f in self.figures()] if figures else []
        if figures:
            paths["figures"] = [atomic_write(out / "figures" / n, png) for n, _, png in figs]
        if html:
            paras, tables = [], [("Parameters with standard errors and 95 % intervals", rows, None)]
            for p in self.preloads:
                if p.fit is None:
                    paras.append(f"Preload {p.preload}: " + "; ".join(p.errors.values()))
                    continue
                mm, mse = p.fit.modal_mass
                paras.append(f"Preload {p.preload}: laws wn {p.fit.model.frequency_law.kind}, zeta "
                             f"{p.fit.model.damping_law.kind}; modal mass at the driving point {mm:.4g} +- "
                             f"{1.96 * mse:.2g} kg (95 %); amplitude a = {AMPLITUDE_UNIT}; residuals "
                             + ("adequate" if (p.adequacy or {}).get("adequate") else "not adequate (not white)"))
                tables.append((f"Preload {p.preload}: every level re-predicted from its measured forces", [
                    {"level": pr.label, "amplitude rms [%]": round(100 * pr.amplitude_rms_rel, 2),
                     "phase rms [deg]": round(pr.phase_rms_deg, 2),
                     "peak a error [%]": round(100 * pr.peaks()["amplitude_error_rel"], 2),
                     "peak f error [%]": round(100 * pr.peaks()["frequency_error_rel"], 4)}
                    for pr in p.fit.predictions], None))
                if p.lolo:
                    tables.append((f"Preload {p.preload}: each level predicted from the other levels", [
                        {"level": e["label"], "peak a error [%]": round(100 * e["peaks"]["amplitude_error_rel"], 2),
                         "peak f error [%]": round(100 * e["peaks"]["frequency_error_rel"], 4),
                         "amplitude rms [%]": round(100 * e["amplitude_rms_rel"], 2),
                         "phase rms [deg]": round(e["phase_rms_deg"], 2)} if "peaks" in e else
                        {"level": e["label"], "error": e["error"]} for e in p.lolo], None))
                if p.selection:
                    tables.append((f"Preload {p.preload}: laws scored by leave-one-level-out prediction "
                                   f"(chosen: {' / '.join(p.selection['selected'])}, the fewest parameters within one "
                                   "standard error of the best)", [
                                       {"wn law": t["frequency_law"], "zeta law": t["damping_law"],
                                        "parameters": t["n_parameters"],
                                        "complex error [%]": round(100 * t["lolo_complex_rms_rel"], 2),
                                        "stderr [%]": round(100 * t["lolo_stderr"], 2)}
                                       for t in sorted(p.selection["table"], key=lambda t: t["lolo_complex_rms_rel"])],
                                   None))
                if p.ringdowns:
                    rows_r = []
                    for i, b, d, m in p.ringdowns:
                        c = m.get("vs_stepped_sine") or {}
                        rows_r.append({
                            "record": i, "windows": len(b),
                            "a range [m/s^2]": f"{b.amplitude.min():.3g} .. {b.amplitude.max():.3g}",
                            "f range [Hz]": f"{b.frequency_hz.min():.4f} .. {b.frequency_hz.max():.4f}",
                            "monotone": m.get("monotone"),
                            "f - f_model [Hz]": (f"{c['delta_f_hz']['min']:+.4f} .. {c['delta_f_hz']['max']:+.4f}"
                                                 if c.get("overlap") else "no overlap"),
                            "zeta / zeta_model": (f"{c['zeta_ratio']['min']:.2f} .. {c['zeta_ratio']['max']:.2f}"
                                                  if c.get("overlap") else "")})
                    tables.append((f"Preload {p.preload}: ring-downs (band-limited, windows above the noise floor) "
                                   "against the stepped-sine model at the same amplitude", rows_r, None))
            sec = Section("First-harmonic identification", paragraphs=paras, tables=tables,
                          figures=[(c, png) for _, c, png in figs])
            paths["html"] = out / "report.html"
            write_html(paths["html"], f"jointid: {self.name}", [sec],
                       intro=f"{len(self.records)} records, {len(self.failed)} failed.", meta=page_meta(run_id))
        return paths


#: Largest relative scatter of a level's accelerance about one linear mode for lines taken as a
#: resonance (the strongly nonlinear Brake-Reuss beam, level by level: 0.08 to 0.16; lines of pure
#: noise: about 0.9).  Beyond it the laws are not chosen or fitted: the fit would return numbers
#: (or search for minutes) on lines that hold no mode.
MAX_LINEAR_SCATTER = 0.5


def linear_mode_scatter(level) -> float:
    """Relative RMS misfit of one level's accelerance by one linear mode ``-w^2 m / (a - w^2 + i c w)``.

    The mode starts from one linear least-squares step (the equation multiplied by its
    denominator, each line weighted by ``1 / |H|``) and is refined, with a complex constant for
    the other modes and a complex modal constant, by a short nonlinear least-squares fit.
    """
    w = 2 * np.pi * np.asarray(level.frequency_hz, float)
    H = np.asarray(level.frf, complex)
    if w.size < 3:
        return 0.0
    g = 1.0 / np.abs(H)
    # H a + i w H c + w^2 m = w^2 H, real and imaginary parts, unknowns (a, c, m)
    M = np.column_stack([H, 1j * w * H, w**2 + 0j]) * g[:, None]
    rhs = w**2 * H * g
    A = np.vstack([M.real, M.imag])
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    x = np.linalg.lstsq(A / scale, np.concatenate([rhs.real, rhs.imag]), rcond=None)[0] / scale
    from scipy.optimize import least_squares

    def resid(p):  # the mode and a constant residual term, relative to |H| (a few dozen evaluations)
        a, c, mr, mi, rr, ri = p
        r = (-(w**2) * (mr + 1j * mi) / (a - w**2 + 1j * c * w) + (rr + 1j * ri) - H) * g
        return np.concatenate([r.real, r.imag])

    x0 = np.array([x[0], x[1], x[2], 0.0, 0.0, 0.0])
    with np.errstate(all="ignore"):
        if not np.all(np.isfinite(resid(x0))):
            return np.inf
        sol = least_squares(resid, x0, x_scale="jac", max_nfev=200)
    r = sol.fun
    return float(np.sqrt(2 * np.mean(r**2))) if np.all(np.isfinite(r)) else np.inf


def _check_one_resonance(levels) -> None:
    """Raise an IdentificationError when a level's lines show no resonance of one mode."""
    bad = [(lv.label, x) for lv in levels if not (x := linear_mode_scatter(lv)) <= MAX_LINEAR_SCATTER]
    if bad:
        raise IdentificationError(
            "the lines of " + ", ".join(f"level {label} scatter by {x:.3g}" for label, x in bad) +
            f" of the accelerance about one linear mode (at most {MAX_LINEAR_SCATTER:g} is taken as a resonance); "
            "they show no resonance of one mode (noise, a response away from the driving point, or the wrong "
            "columns), so the preload is not identified")


#: Largest ratio between the resonance frequency of one level and the median over the levels of a
#: preload for the levels to be taken as the same mode (the Brake-Reuss beam's levels: 1.004;
#: frequencies of one level written in rad/s: 2 pi).
MAX_LEVEL_FREQUENCY_RATIO = 1.5
#: Smallest ratio of a ring-down's largest spectral peak in the band of the identified mode to its
#: largest peak anywhere: below it the record rings at another mode (or another point).
MIN_RINGDOWN_BAND_PEAK = 0.01
#: Half width of the ring-down band around the identified mode, as a fraction of its frequency.
RINGDOWN_HALF_WIDTH = 0.15


def _frequency_outliers(levels, outcomes, preload) -> list:
    """``(outcome index, message)`` of each level whose resonance is far from the other levels' one.

    Raises
    ------
    IdentificationError
        When the levels disagree and at least half of them are off: which are right cannot be told.
    """
    if len(levels) < 2:
        return []
    peaks = np.array([float(lv.frequency_hz[int(np.argmax(np.abs(lv.frf)))]) for _, lv in levels])
    ref = float(np.median(peaks))
    ratio = np.maximum(peaks / ref, ref / peaks)
    off = ratio > MAX_LEVEL_FREQUENCY_RATIO
    if not off.any():
        return []
    if 2 * int(off.sum()) >= len(levels):
        raise IdentificationError(
            "the levels' resonances are not those of one mode: " + ", ".join(
                f"level {lv.label} at {f:.4g} Hz" for (_, lv), f in zip(levels, peaks)) +
            f" (more than x{MAX_LEVEL_FREQUENCY_RATIO:g} apart; frequencies of a level in rad/s?), so the preload "
            "is not identified")
    out = []
    for (i, lv), f, r, bad in zip(levels, peaks, ratio, off):
        if not bad:
            continue
        spec = outcomes[i].spec
        unit = "; a factor near 2 pi: frequencies in rad/s where Hz are expected?" if abs(r / (2 * np.pi) - 1) < 0.05 \
            else ""
        out.append((i, f"{where(spec.file, spec.index, 'frequency_hz')}the resonance of this level is at {f:.4g} Hz, "
                       f"x{r:.3g} from that of the other levels of preload {preload} ({ref:.4g} Hz, median; at most "
                       f"x{MAX_LEVEL_FREQUENCY_RATIO:g} apart is taken as the same mode){unit} The record is left out"))
    return out


def _ringdown_of(spec, fit, ringdown_options=None):
    """Backbone of a ring-down record around the identified mode, or a RecordError saying why it is not usable.

    Refused: a record whose largest spectral peak lies outside the band of the mode and dwarfs
    what is in the band (a ring-down of another mode), a decay fit that is noise, grows, does not
    decay or gives too few windows (:func:`jointid.signal.ringdown_checks.ringdown_flags`), and a
    backbone with no window above the noise floor.
    """
    from ..errors import RecordError
    from ..io.campaign import read_record
    from ..signal.ringdown_checks import ringdown_flags

    data = read_record(spec, required=("time", "accel"))
    f0 = float(fit.backbone(amplitudes=[fit.amplitude_range[0]]).frequency_hz[0])
    t, x = data.time, data.channels["accel"]
    b, d, mono = ringdown_backbone(t, x, f0, label=f"ring-down {spec.index}", **(ringdown_options or {}))
    loc = where(spec.file, spec.index, "accel")
    band = ((1 - RINGDOWN_HALF_WIDTH) * f0, (1 + RINGDOWN_HALF_WIDTH) * f0)
    f_peak, in_band = _spectral_peaks(t, x, band)
    if not band[0] <= f_peak <= band[1] and not in_band >= MIN_RINGDOWN_BAND_PEAK:
        raise RecordError(f"{loc}the ring-down's largest spectral peak is at {f_peak:.4g} Hz, far from the identified "
                          f"mode at {f0:.4g} Hz; in the mode's band {band[0]:.4g}..{band[1]:.4g} Hz the largest peak is "
                          f"{in_band:.2g} of it (at least {MIN_RINGDOWN_BAND_PEAK:g}): a ring-down of another mode (or "
                          "another point), not used")
    flags = ringdown_flags(d, "accel")
    if flags:
        raise RecordError(f"{loc}not a usable free decay of the mode at {f0:.4g} Hz: "
                          + "; ".join(f.report() for f in flags))
    if not len(b):
        raise RecordError(f"{loc}no window of the decay in {band[0]:.4g}..{band[1]:.4g} Hz rises above the noise floor")
    mono["vs_stepped_sine"] = compare_with_model(fit, b)
    return b, d, mono


def _spectral_peaks(t, x, band) -> tuple:
    """``(frequency of the largest spectral peak [Hz], largest peak in band / largest peak)`` of a record."""
    x = np.asarray(x, float) - np.mean(x)
    dt = (t[-1] - t[0]) / (t.size - 1)
    n = 1 << int(np.ceil(np.log2(2 * t.size)))
    X = np.abs(np.fft.rfft(x * np.hanning(x.size), n))
    f = np.fft.rfftfreq(n, dt)
    X[0] = 0.0
    k = int(np.argmax(X))
    sel = (f >= band[0]) & (f <= band[1])
    top = float(X[k])
    return float(f[k]), (float(X[sel].max()) / top if sel.any() and top > 0 else 0.0)


def _label(spec):
    if spec.force_level is not None:
        return str(spec.force_level)
    return spec.file


def identify_first_harmonic_campaign(campaign, settings=None, *, laws=None, candidates=DEFAULT_CANDIDATES,
                                     lolo=True, ringdown_options=None) -> FirstHarmonicCampaignResult:
    """Identify a first-harmonic campaign (module docstring).

    Parameters
    ----------
    campaign : path or Campaign
    settings : IdentifySettings, optional
        Kept on the result (``keep_flagged``); the first-harmonic model has no other setting there.
    laws : (str, str), optional
        Frequency and damping laws (``"poly4"``, ``"power"`` ...); chosen by leave-one-level-out
        prediction among ``candidates`` when not given.
    lolo : bool
        Predict each level from the others (for the report).
    ringdown_options : dict, optional
        Passed to :func:`jointid.signal.ringdown.modal_ringdown`.
    """
    from ..io.firsth import read_first_harmonic_record

    if not isinstance(campaign, Campaign):
        campaign = load_campaign(campaign)
    from .records import IdentifySettings

    if settings is None:
        settings = IdentifySettings()
    default = IdentifySettings()
    unused = [k for k in ("terms", "n_harmonics", "damping_order", "force_gain", "channel_delay")
              if getattr(settings, k) != getattr(default, k) and not (k == "terms" and settings.terms == "auto")]
    run_notes = []
    if unused:  # said, not ignored silently: these choices belong to the force-state mapping of time records
        run_notes.append(f"{', '.join(unused)} not used: a first-harmonic campaign is identified as one nonlinear "
                         f"mode with amplitude laws chosen by leave-one-level-out")
    outcomes, levels_of, ring_of = [], {}, {}
    for spec in campaign.records:
        if spec.excitation == "ringdown":
            outcomes.append(RecordOutcome(spec, True, kind="ringdown"))
            ring_of.setdefault(spec.preload, []).append((len(outcomes) - 1, spec))
            continue
        try:
            rec = read_first_harmonic_record(spec)
        except JointidError as exc:  # a refused manifest entry: the misspelt choice and the nearest valid one
            hint = _manifest_hint(campaign, spec) if spec.error else ""
            outcomes.append(RecordOutcome(spec, False, str(exc) + hint))
            continue
        outcomes.append(RecordOutcome(spec, True, n_lines=len(rec)))
        level = FirstHarmonicLevel.from_record(rec, _label(spec))
        levels_of.setdefault(spec.preload, []).append((len(outcomes) - 1, level))
    preloads = []
    for preload in list(dict.fromkeys([r.spec.preload for r in outcomes])):
        errors = {}
        fit = sel = adq = None
        lo = ()
        try:  # a level whose resonance is far from the others' (a unit mistake) fails its record alone
            for i, message in _frequency_outliers(levels_of.get(preload, []), outcomes, preload):
                outcomes[i] = RecordOutcome(outcomes[i].spec, False, message)
            levels = [lv for i, lv in levels_of.get(preload, []) if outcomes[i].ok]
        except IdentificationError as exc:
            errors["fit"] = str(exc)
            preloads.append(FirstHarmonicPreload(preload, errors=errors))
            continue
        if not levels:
            if preload in ring_of:
                errors["fit"] = "no first-harmonic record could be read for this preload"
            preloads.append(FirstHarmonicPreload(preload, errors=errors))
            continue
        chosen = tuple(laws) if laws else None
        try:
            _check_one_resonance(levels)
            if chosen is None:
                if len(levels) >= 2:
                    sel = select_laws(levels, candidates)
                    chosen = sel["selected"]
                else:
                    chosen = ("poly2", "poly1")
                    errors["selection"] = "one level: laws poly2/poly1 taken (selection needs two levels)"
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                fit = fit_first_harmonic(levels, *chosen)
                if lolo and len(levels) >= 2:
                    lo = tuple(leave_one_level_out(levels, *chosen, a_ref=fit.model.a_ref))
            adq = adequacy(fit)
        except (IdentificationError, ValueError, np.linalg.LinAlgError) as exc:
            errors["fit"] = str(exc)
        rings = []
        for i, spec in ring_of.get(preload, []):
            if fit is None:
                break
            used = False
            with warnings.catch_warnings(record=True) as caught:  # a refused record's own warnings: in its error
                warnings.simplefilter("always")
                try:
                    b, d, mono = _ringdown_of(spec, fit, ringdown_options)
                    rings.append((spec.index, b, d.summary(), mono))
                    used = True
                except JointidError as exc:
                    loc = where(spec.file, spec.index)
                    text = str(exc) if str(exc).startswith(str(spec.file)) else f"{loc}{exc}"
                    outcomes[i] = RecordOutcome(spec, False, text, kind="ringdown")
            for w in caught:
                if used or not issubclass(w.category, JointidWarning):
                    warnings.warn(w.message, w.category, stacklevel=1)
        preloads.append(FirstHarmonicPreload(preload, fit, sel, lo, adq, tuple(rings), errors))
    notes = run_notes + [f"preload {p.preload}: {k}: {e}" for p in preloads for k, e in p.errors.items()]
    notes += [f"record failed: {o.error}" for o in outcomes if not o.ok]
    if notes:  # one summary warning; every message stays on its record and in results.json
        warnings.warn(f"{len(notes)} problem(s) in the first-harmonic campaign:\n  " + "\n  ".join(notes),
                      JointidWarning, stacklevel=2)
    return FirstHarmonicCampaignResult(campaign.name, str(campaign.root), settings, tuple(outcomes), tuple(preloads),
                                       tuple(laws) if laws else None, notes=tuple(run_notes))
