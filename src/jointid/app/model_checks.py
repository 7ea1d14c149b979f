"""Model selection and adequacy over a campaign (``jointid identify --terms auto``; results.json
``selection`` and ``adequacy``).

* :func:`campaign_adequacy` runs the checks of :mod:`jointid.identify.adequacy` on every
  preload of an identified campaign: its force levels' pooled fits, its preload model and
  its usable records;
* :func:`campaign_selection` ranks the candidate models of every preload
  (:func:`jointid.identify.selection.select_model`) from the records of a first pass;
* :func:`identify_auto` is ``identify_campaign`` with the terms chosen by the data: a
  first pass with the seed's terms gives the records' state signals, the selection per
  preload picks the model, and the campaign is identified again with the selected terms
  (the union over the preloads), each preload's model being its own selection; the
  groups' FRFs are re-predicted with the selected models.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

from ..errors import IdentificationError, JointidWarning
from ..identify.terms import SEED_TERMS, library

__all__ = ["AUTO", "is_auto", "campaign_adequacy", "campaign_selection", "identify_auto", "silverbox_multilevel_selection"]

#: The ``terms`` value that asks for model selection.
AUTO = "auto"


def is_auto(terms) -> bool:
    return isinstance(terms, str) and terms.strip().lower() == AUTO


def _preload_records(result, preload):
    keep = result.settings.keep_flagged
    return [o for o in result.records if o.spec.preload == preload and (o.ok if keep else o.usable)]


def campaign_adequacy(result) -> dict:
    """:class:`~jointid.identify.adequacy.AdequacyResult` per preload (``None`` where it cannot be assessed).

    A failing check never loses the campaign: its reason is kept as ``adequacy_errors``.
    """
    from ..identify.adequacy import assess_preload
    from ..identify.fsm import own_fits

    out, errors = {}, {}
    for preload, model in result.models.items():
        recs = _preload_records(result, preload)
        level_fits = [(g.force_level, g.pooled) for g in result.groups if g.preload == preload]
        try:
            fits = [o.fit for o in recs]
            sigs = [o.signals for o in recs]
            if model is not None and any(tuple(f.terms) != tuple(model.terms) for f in fits):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", JointidWarning)
                    fits = own_fits(library(list(model.terms)), sigs, None, True)
            out[preload] = assess_preload(model, fits if model is not None else [], sigs,
                                          [o.spec.force_level for o in recs], level_fits,
                                          [o.spec.index for o in recs], result.settings.weighting, preload)
        except (IdentificationError, ValueError, ArithmeticError) as exc:
            out[preload] = None
            errors[preload] = f"preload {preload}: adequacy not assessed: {exc}"
    return out, errors


def campaign_selection(result, **kw) -> tuple:
    """:func:`~jointid.identify.selection.select_model` per preload of an identified campaign.

    Returns ``({preload: SelectionResult or None}, {preload: error})``.
    """
    from ..identify.selection import select_model

    out, errors = {}, {}
    preloads = list(dict.fromkeys(o.spec.preload for o in result.records if o.ok))
    for preload in preloads:
        recs = _preload_records(result, preload)
        try:
            if result.settings.force_gain != "known":
                raise IdentificationError("model selection needs a known force gain (the restoring force is "
                                          "force minus acceleration)")
            if len({o.spec.force_level for o in recs}) < 2:
                raise IdentificationError("cross-validation needs at least two force levels")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", JointidWarning)
                out[preload] = select_model([o.signals for o in recs], [o.spec.force_level for o in recs],
                                            damping_order=result.settings.damping_order,
                                            weighting=result.settings.weighting, preload=preload, **kw)
        except IdentificationError as exc:
            out[preload] = None
            errors[preload] = f"preload {preload}: no model selection: {exc}"
    return out, errors


def _union_terms(selections) -> str:
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


def identify_auto(campaign, settings):
    """Identify a campaign with the restoring-force model chosen per preload by the data.

    The records are processed with the seed's terms, the candidate models of each preload
    are ranked (:func:`campaign_selection`), and the campaign is identified again with the
    selected terms; each preload's model (results.json ``models``) is its selected model
    with its amplitude laws, and the groups' FRFs are re-predicted with it.  A campaign where
    no preload can be selected (a single force level) keeps the seed's terms and says why
    under ``selection``.
    """
    from ..io.campaign import Campaign, load_campaign
    from .workflow import identify_campaign

    if not isinstance(campaign, Campaign):
        campaign = load_campaign(campaign)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        first = identify_campaign(campaign, replace(settings, terms=" + ".join(SEED_TERMS), repredict=False))
    selections, errors = campaign_selection(first)
    for e in errors.values():
        warnings.warn(e, JointidWarning, stacklevel=5)  # past _identify_campaign, identify_campaign, its wrapper
    terms = _union_terms(selections)
    result = identify_campaign(campaign, replace(settings, terms=terms, repredict=False))
    models = dict(result.models)
    for p, sel in selections.items():
        if sel is not None and sel.model is not None:
            models[p] = sel.model
    result = replace(result, models=models, selections=selections, selection_errors=errors)
    adequacy, adequacy_errors = campaign_adequacy(result)
    result = replace(result, adequacy=adequacy, adequacy_errors=adequacy_errors)
    if settings.repredict:  # with the selected models (jointid.app.reprediction.identified_model)
        from .reprediction import with_repredictions

        result = with_repredictions(result)
    return result


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
