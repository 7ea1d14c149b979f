"""Benchmark: the hysteretic force-state mapping's fit, exact Jacobian against finite differences.

On the time-integrated Jenkins and discrete-Iwan campaigns of tests/test_hysteretic_fsm.py
(3 levels x 13 dwells, 0.5 % noise), each law is fitted twice in the same process: with
``jacobian="3-point"`` (the finite-difference path the searches used before) and with the
default exact variable-projection Jacobian; once with the estimator's defaults and once with
the settings of the model selection (``n_time`` 256, 30 / 60 evaluations).  Prints the
times, their ratio, and how far the exact path's parameters and standard errors lie from the
finite-difference path's (in standard errors) and both paths' weighted residual rms.

    python benchmarks/bench_hysteretic.py
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_hysteretic_fsm import IWAN, IWAN_LEVELS, JENKINS, JENKINS_LEVELS, campaign, noisy  # noqa: E402

from jointid.identify.hysteretic import HystereticForceStateMapping  # noqa: E402

SELECTION = dict(n_time=256, search_evaluations=30, max_evaluations=60)


def timed(law, sigs, repeat=2, **kw):
    best, fit = np.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit = HystereticForceStateMapping(law, **kw).fit(sigs).result_
        best = min(best, time.perf_counter() - t)
    return best, fit


def main():
    t0 = time.perf_counter()
    data = {"jenkins": campaign(JENKINS, JENKINS_LEVELS, 0.06), "iwan4": campaign(IWAN, IWAN_LEVELS, 0.05)}
    print(f"campaigns by time integration: {time.perf_counter() - t0:.1f} s")
    total = {"3-point": 0.0, "exact": 0.0}
    for law in ("jenkins", "iwan4", "jenkins+cubic", "iwan4+cubic"):
        sigs = noisy(data[law.removesuffix("+cubic")], np.random.default_rng(11))
        for label, kw in (("defaults", {}), ("selection", SELECTION)):
            t_fd, fd = timed(law, sigs, jacobian="3-point", **kw)
            t_ex, ex = timed(law, sigs, **kw)
            total["3-point"] += t_fd
            total["exact"] += t_ex
            dv = np.max(np.abs(ex.values - fd.values) / fd.stderr)
            ds = np.max(np.abs(ex.stderr / fd.stderr - 1))
            print(f"{law:>14} {label:>9}: 3-point {t_fd:6.2f} s, exact {t_ex:6.2f} s, ratio {t_fd / t_ex:5.2f}x; "
                  f"max |d value| {dv:.2g} SE, max |d SE| {ds:.2g} (relative); residual rms {fd.residual_rms:.6f} -> "
                  f"{ex.residual_rms:.6f}")
    print(f"all fits: 3-point {total['3-point']:.2f} s, exact {total['exact']:.2f} s, "
          f"ratio {total['3-point'] / total['exact']:.2f}x")


if __name__ == "__main__":
    main()
