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
a check fails (``fits`` false) when ``p < P_LIMIT`` and ``chi2/dof > CHI2_DOF_LIMIT``:
very unlikely under the noise model *and* a scatter well above the stated errors, so
that a large campaign with a scatter a few per cent above its errors is not called a
misfit.  ``jointid identify`` says so on the console and in the report, and exits with
status 1 (finished with flagged results).
"""

from __future__ import annotations

import numpy as np

__all__ = ["P_LIMIT", "CHI2_DOF_LIMIT", "fit_checks", "misfits", "misfit_lines"]

#: A regression whose chi-square has a probability below this ... (module docstring).
P_LIMIT = 1e-4
#: ... and whose chi-square per degree of freedom exceeds this does not fit its data.
CHI2_DOF_LIMIT = 2.0


def _p_value(chi2, dof) -> float:
    from scipy.stats import chi2 as _chi2

    return float(_chi2.sf(chi2, dof)) if dof > 0 and np.isfinite(chi2) else float("nan")


def _check(kind, label, preload, chi2, dof, data, consequence) -> dict:
    chi2_dof = chi2 / dof
    p = _p_value(chi2, dof)
    fits = not (p < P_LIMIT and chi2_dof > CHI2_DOF_LIMIT)
    stats = f"chi²/dof {chi2_dof:.3g} on {dof} dof, p = {p:.2g}"
    if fits:
        message = f"the {label} fits {data} ({stats})"
    else:
        message = (f"the {label} does not fit {data}: they scatter {np.sqrt(chi2_dof):.3g} times their standard "
                   f"errors about it ({stats}); {consequence}")
    return {"check": kind, "preload": preload, "label": label, "chi2": float(chi2), "dof": int(dof),
            "chi2_dof": float(chi2_dof), "p_value": p, "fits": bool(fits), "p_limit": P_LIMIT,
            "chi2_dof_limit": CHI2_DOF_LIMIT, "message": message}


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
        ``message`` sentence.
    """
    out = []
    for preload, law in (getattr(result, "damping_laws", None) or {}).items():
        chi2, dof = getattr(law, "chi2", np.nan), int(getattr(law, "dof", 0) or 0)
        if law is None or dof <= 0 or not np.isfinite(chi2):
            continue
        out.append(_check("damping_law", f"damping law c(q_max) of preload {preload}", preload, chi2, dof,
                          "the per-record damping", "its standard errors hold the noise only and understate its "
                          "uncertainty"))
    d = getattr(result, "channel_delay", None)
    if d is not None and getattr(d, "source", "") == "estimated":
        dof = int(d.dof or 0)
        if dof > 0 and np.isfinite(d.reduced_chi2):
            out.append(_check("channel_delay", "channel-delay model (damping law plus delay)", None,
                              d.reduced_chi2 * dof, dof, "the per-dwell damping",
                              "the delay's standard error is scaled by that factor, and the delay absorbs what the "
                              "damping law misses"))
    return out


def misfits(checks) -> list:
    """The failed entries of :func:`fit_checks` (or of a ``results.json`` ``fit_checks`` list)."""
    return [c for c in checks or () if c.get("fits") is False]


def misfit_lines(summary) -> list:
    """Console lines for the regressions that do not fit (empty when all fit): from a
    ``results.json`` summary (``fit_checks``)."""
    bad = misfits(summary.get("fit_checks"))
    if not bad:
        return []
    return ([f"{len(bad)} regression(s) where the model does not fit the data to their errors:"]
            + [f"  {c['message']}" for c in bad])
