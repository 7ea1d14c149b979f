"""Standard errors and 95 % intervals of simple estimates, shared by the application and the report.

* :func:`band_mean_resolution` -- the band average of single-record values (the seed paper's
  Table 5 method): its standard error from the values' scatter, its 95 % interval, whether it
  is resolved (the interval excludes zero) and whether it agrees with a pooled estimate.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Z95", "band_mean_resolution"]

#: Two-sided 95 % quantile of the normal distribution.
Z95 = 1.959963984540054


def _finite(x) -> bool:
    try:
        return x is not None and math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def band_mean_resolution(values, mean=None, pooled=None, pooled_stderr=None) -> dict:
    """Standard error and resolution of the mean of single-record estimates.

    Parameters
    ----------
    values : sequence of float or None
        One estimate per record (``None`` and non-finite values are left out).
    mean : float, optional
        The band average as computed elsewhere (default: the mean of ``values``).
    pooled, pooled_stderr : float, optional
        A pooled estimate of the same quantity and its standard error.

    Returns
    -------
    dict
        ``mean``, ``stderr`` (scatter over ``sqrt(n)``; NaN for one record), ``ci95``
        (``None`` without a finite standard error), ``n_records``, ``resolved`` (the 95 %
        interval excludes zero) and ``consistent`` (``|mean - pooled|`` within the combined
        95 % interval; ``None`` when either standard error is unknown).  ``{}`` without a
        finite value.
    """
    v = np.array([x for x in values if _finite(x)], float)
    if v.size == 0:
        return {}
    m = float(mean) if _finite(mean) else float(v.mean())
    se = float(v.std(ddof=1) / np.sqrt(v.size)) if v.size > 1 else float("nan")
    consistent = None
    if _finite(pooled) and _finite(pooled_stderr) and _finite(se):
        consistent = bool(abs(m - float(pooled)) <= Z95 * math.hypot(se, float(pooled_stderr)))
    return {"mean": m, "stderr": se, "ci95": [m - Z95 * se, m + Z95 * se] if _finite(se) else None,
            "n_records": int(v.size), "resolved": bool(_finite(se) and abs(m) > Z95 * se), "consistent": consistent}
