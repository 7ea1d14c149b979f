"""Model selection and adequacy over a campaign (``jointid identify --terms auto``; results.json
``selection`` and ``adequacy``).

* :func:`campaign_adequacy` runs the checks of :mod:`jointid.identify.adequacy` on every
  preload of an identified campaign: its force levels' pooled fits, its preload model and
  its usable records;
* :func:`preload_selections` ranks the candidate models of every preload
  (:func:`jointid.identify.selection.select_model`) from a campaign's processed records, and
  :func:`campaign_selection` does so for an identified campaign;
* :func:`union_terms` is the terms the campaign is identified with once the models are
  selected (the union over the preloads; each preload's model is its own selection).
  :func:`jointid.app.workflow.identify_campaign` with ``terms="auto"`` runs these steps.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

from ..errors import IdentificationError, JointidWarning
from ..identify.terms import SEED_TERMS, library
from .campaign_fit import in_pooled_fits

__all__ = ["AUTO", "is_auto", "campaign_adequacy", "preload_selections", "campaign_selection", "union_terms",
           "silverbox_multilevel_selection"]

#: The ``terms`` value that asks for model selection.
AUTO = "auto"


def is_auto(terms) -> bool:
    return isinstance(terms, str) and terms.strip().lower() == AUTO


def _preload_records(records, settings, preload):
    return [o for o in records if o.spec.preload == preload and in_pooled_fits(o, settings)]


def campaign_adequacy(result) -> dict:
    """:class:`~jointid.identify.adequacy.AdequacyResult` per preload (``None`` where it cannot be assessed).

    A failing check never loses the campaign: its reason is kept as ``adequacy_errors``.  When the
    preload's selection picked a hysteretic law, its adequacy is that of the hysteretic fit
    (:func:`~jointid.identify.adequacy.assess_hysteretic`) and the polynomial stand-in's is kept
    under its ``stand_in`` (results.json ``stand_in_adequacy``), never as the selected model's verdict.
    """
    from ..identify.adequacy import assess_hysteretic, assess_preload
    from ..identify.fsm import own_fits

    out, errors = {}, {}
    for preload, model in result.models.items():
        recs = _preload_records(result.records, result.settings, preload)
        level_fits = [(g.force_level, g.pooled) for g in result.groups if g.preload == preload]
        try:
            fits = [o.fit for o in recs]
            sigs = [o.signals for o in recs]
            if model is not None and any(tuple(f.terms) != tuple(model.terms) for f in fits):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", JointidWarning)
                    fits = own_fits(library(list(model.terms)), sigs, None, True)
            levels, labels = [o.spec.force_level for o in recs], [o.spec.index for o in recs]
            out[preload] = assess_preload(model, fits if model is not None else [], sigs, levels, level_fits,
                                          labels, result.settings.weighting, preload)
            sel = (getattr(result, "selections", None) or {}).get(preload)
            hyst = getattr(sel, "hysteretic_model", None)
            if hyst is not None:  # the selected law is judged on its own fit; the stand-in's verdict kept apart
                out[preload] = replace(assess_hysteretic(hyst, sigs, levels, labels, preload), stand_in=out[preload])
        except (IdentificationError, ValueError, ArithmeticError) as exc:
            out[preload] = None
            errors[preload] = f"preload {preload}: adequacy not assessed: {exc}"
    return out, errors


def preload_selections(records, settings, **kw) -> tuple:
    """:func:`~jointid.identify.selection.select_model` per preload over a campaign's processed records
    (those that enter the pooled fits with ``settings``).

    Returns ``({preload: SelectionResult or None}, {preload: error})``.
    """
    from ..identify.selection import select_model

    out, errors = {}, {}
    preloads = list(dict.fromkeys(o.spec.preload for o in records if o.ok))
    for preload in preloads:
        recs = _preload_records(records, settings, preload)
        try:
            if settings.force_gain != "known":
                raise IdentificationError("model selection needs a known force gain (the restoring force is "
                                          "force minus acceleration)")
            if len({o.spec.force_level for o in recs}) < 2:
                raise IdentificationError("cross-validation needs at least two force levels")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", JointidWarning)
                out[preload] = select_model([o.signals for o in recs], [o.spec.force_level for o in recs],
                                            damping_order=settings.damping_order,
                                            weighting=settings.weighting, preload=preload, **kw)
        except IdentificationError as exc:
            out[preload] = None
            errors[preload] = f"preload {preload}: no model selection: {exc}"
    return out, errors


def campaign_selection(result, **kw) -> tuple:
    """:func:`preload_selections` of an identified campaign (its records and settings).

    Returns ``({preload: SelectionResult or None}, {preload: error})``.
    """
    return preload_selections(result.records, result.settings, **kw)


def union_terms(selections) -> str:
    """The terms of every selected model (their union, in a fixed order); the seed's terms when none."""
    names = []
    for sel in selections.values():
        if sel is not None:
            for n in sel.candidate.library.names:
                if n not in names:
                    names.append(n)
    if not names:
        return " + ".join(SEED_TERMS)
    order = {n: i for i, n in enumerate(("q", "q^2", "-q^3", "|q|q", "q^5", "q'", "|q'|q'", "q'^3", "sign(q')"))}
    return " + ".join(sorted(names, key=lambda n: order.get(n, 99)))


def silverbox_multilevel_selection(levels=None, *, skip_periods=5, criterion="bic"):
    """Model selection on the Silverbox multilevel multisines (``../shared/data/silverbox_multilevel_noel``).

    Each level's periods after ``skip_periods`` are averaged (as in
    :func:`jointid.app.public_data.silverbox_multilevel`) and the broadband candidates are
    ranked by :func:`jointid.identify.selection.select_broadband`, the levels being the
    cross-validation folds.
    """
    from ..identify.selection import select_broadband
    from ..io.datasets import load_silverbox_multilevel
    from ..signal.broadband import average_periods
    from .public_data import silverbox_multilevel_levels

    levels = tuple(silverbox_multilevel_levels() if levels is None else levels)
    states = []
    for lv in levels:
        rec = load_silverbox_multilevel(lv)
        avg = average_periods({"u": rec["u"], "y": rec["y"]}, rec.fs, period=rec.meta["samples_per_period"],
                              skip_periods=skip_periods, input="u")
        states.append(avg.states("u", "y", measured="displacement"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        return select_broadband(states, levels, criterion=criterion, preload="Silverbox multilevel")
