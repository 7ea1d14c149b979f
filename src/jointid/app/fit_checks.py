"""Goodness of fit of the campaign-level regressions: does the model fit the data to their errors?

A campaign identification ends with regressions that carry a chi-square: the damping law
``c(q_max)`` of each preload fitted to the per-record damping with its covariance
(:func:`jointid.identify.laws.fit_damping_law`), and the channel delay fitted with the
damping law to the per-dwell damping (:mod:`jointid.identify.delay`).  Under the model and
the stated errors the chi-square has ``dof`` degrees of freedom; a very small probability
``p`` of a value at least as large means the model does not describe the data to their
errors: the scatter is the model's, not the noise's, and the standard errors computed
from the noise understate the uncertainty.

:func:`fit_checks` gives one entry per regression (``results.json`` key ``fit_checks``);
a check fails (``fits`` false) when ``p < P_LIMIT``, ``chi2/dof > CHI2_DOF_LIMIT`` and
the rms residual about the law is at least ``RELATIVE_FLOOR`` of the rms of the fitted
values: very unlikely under the noise model, a scatter well above the stated errors (a
large campaign with a scatter a few per cent above its errors is not called a misfit),
and a misfit of material size (on noise-free simulated data the standard errors are at
rounding level and the method's own approximations, far below a per mille, would
otherwise dominate the chi-square).  ``jointid identify`` says so on the console and in the report, and exits with
status 1 (finished with flagged results).
"""

from __future__ import annotations

import numpy as np

from ..io.results import misfits

__all__ = ["P_LIMIT", "CHI2_DOF_LIMIT", "RELATIVE_FLOOR", "fit_checks", "misfits", "misfit_lines"]

#: A regression whose chi-square has a probability below this ... (module docstring).
P_LIMIT = 1e-4
#: ... and whose chi-square per degree of freedom exceeds this ...
CHI2_DOF_LIMIT = 2.0
#: ... and whose rms residual is at least this fraction of the rms of its data does not fit.
RELATIVE_FLOOR = 1e-3


def _p_value(chi2, dof) -> float:
    from scipy.stats import chi2 as _chi2

    return float(_chi2.sf(chi2, dof)) if dof > 0 and np.isfinite(chi2) else float("nan")


def _relative_residual(law) -> float:
    """rms of the law's residuals over the rms of its per-record values."""
    c = np.asarray(law.c, float)
    r = c - law(np.asarray(law.q_max, float))
    ok = np.isfinite(r) & np.isfinite(c)
    scale = np.sqrt(np.mean(c[ok] ** 2)) if ok.any() else 0.0
    return float(np.sqrt(np.mean(r[ok] ** 2)) / scale) if scale > 0 else float("nan")


def _check(kind, label, preload, chi2, dof, data, consequence, relative=None) -> dict:
    chi2_dof = chi2 / dof
    p = _p_value(chi2, dof)
    material = relative is None or not np.isfinite(relative) or relative >= RELATIVE_FLOOR
    fits = not (p < P_LIMIT and chi2_dof > CHI2_DOF_LIMIT and material)
    stats = f"chi²/dof {chi2_dof:.3g} on {dof} dof, p = {p:.2g}"
    if fits and not material and p < P_LIMIT and chi2_dof > CHI2_DOF_LIMIT:
        message = (f"the {label} fits {data} to {relative:.2g} of their values (rms); its {stats} says only that "
                   "their standard errors are below the method's own approximations (noise-free data)")
    elif fits:
        message = f"the {label} fits {data} ({stats})"
    else:
        message = (f"the {label} does not fit {data}: they scatter {np.sqrt(chi2_dof):.3g} times their standard "
                   f"errors about it ({stats}); {consequence}")
    return {"check": kind, "preload": preload, "label": label, "chi2": float(chi2), "dof": int(dof),
            "chi2_dof": float(chi2_dof), "p_value": p, "fits": bool(fits), "p_limit": P_LIMIT,
            "chi2_dof_limit": CHI2_DOF_LIMIT, "relative_rms_residual": _finite(relative),
            "relative_floor": RELATIVE_FLOOR, "message": message}


def _finite(x):
    return float(x) if x is not None and np.isfinite(x) else None


def fit_checks(result) -> list:
    """One goodness-of-fit entry per campaign-level regression with a chi-square (module docstring).

    Parameters
    ----------
    result : CampaignResult

    Returns
    -------
    list of dict
        ``check`` (``"damping_law"`` or ``"channel_delay"``), ``preload``, ``label``,
        ``chi2``, ``dof``, ``chi2_dof``, ``p_value``, ``fits``, the two limits and a
        ``message`` sentence; ``stand_in`` (true) on the damping law of a preload whose selected
        model is a hysteretic law (the law then belongs to the polynomial stand-in and is not a misfit).
    """
    out, relatives = [], []
    selections = getattr(result, "selections", None) or {}
    for preload, law in (getattr(result, "damping_laws", None) or {}).items():
        chi2, dof = getattr(law, "chi2", np.nan), int(getattr(law, "dof", 0) or 0)
        if law is None or dof <= 0 or not np.isfinite(chi2):
            continue
        rel = _relative_residual(law)
        relatives.append(rel)
        if getattr(selections.get(preload), "hysteretic_model", None) is not None:
            # a hysteretic law was selected: this damping law is the polynomial stand-in's, not the model's
            c = _check("damping_law", f"damping law c(q_max) of preload {preload}'s polynomial stand-in (the "
                       "selected hysteretic law has no such law; not counted as a misfit)", preload, chi2, dof,
                       "the per-record damping", "a hysteretic joint's equivalent damping need not follow it", rel)
            out.append({**c, "stand_in": True})
            continue
        out.append(_check("damping_law", f"damping law c(q_max) of preload {preload}", preload, chi2, dof,
                          "the per-record damping", "its standard errors hold the noise only and understate its "
                          "uncertainty", rel))
    d = getattr(result, "channel_delay", None)
    if d is not None and getattr(d, "source", "") == "estimated":
        dof = int(d.dof or 0)
        if dof > 0 and np.isfinite(d.reduced_chi2):
            # the corrected dwells' scatter about the damping law is the regression's residual
            rel = max((r for r in relatives if np.isfinite(r)), default=None)
            out.append(_check("channel_delay", "channel-delay model (damping law plus delay)", None,
                              d.reduced_chi2 * dof, dof, "the per-dwell damping",
                              "the delay's standard error is scaled by that factor, and the delay absorbs what the "
                              "damping law misses", rel))
    return out


def misfit_lines(summary) -> list:
    """Console lines for the regressions that do not fit (empty when all fit): from a
    ``results.json`` summary (``fit_checks``)."""
    bad = misfits(summary.get("fit_checks"))
    if not bad:
        return []
    return ([f"{len(bad)} regression(s) where the model does not fit the data to their errors:"]
            + [f"  {c['message']}" for c in bad])
