"""Benchmark: the seed paper's nonlinear FRF (Fig 4) by harmonic balance vs brute force.

Run with ``python benchmarks/bench_frf.py`` (about one to two minutes).

Problem: seed Eq 19-20 (``seed_model()``), ``Q = sin(omega t)``, 401 frequencies between
160 and 180 rad/s, steady-state amplitude ``q_max`` with the amplitude-dependent damping
``c(q_max)`` closed on each steady state.

Measured:

* harmonic balance, ``frequency_response(model, 1, omegas)`` (sequential sweep with
  predictor + Newton, 9 harmonics), with and without Floquet stability; best of ``--repeat``;
* shooting (``timeint.periodic_orbit``: Newton on the period map + secant on ``q_max``)
  on an evenly spaced subset, per-point time scaled to 401 points;
* brute force as in the paper: ``solve_ivp`` (DOP853, via ``timeint.integrate``)
  integrated from rest until the transient has decayed below ``--delta``
  (``t = (2 / c) ln(1 / delta)``, ``c = c(q_max)``), ``q_max`` read off the last period,
  then updated and integrated on (secant update, continuing from the last state for
  ``(2 / c) ln(|change| / delta)``) until ``|max|q| - q_max| < delta q_max``.  Run on an
  evenly spaced subset (``--points``) and its per-point time scaled to 401 points.

Accuracy is reported as the largest relative ``q_max`` difference to harmonic balance.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time

import numpy as np

from jointid.simulate.hbm import _linear_closure_amplitude, frequency_response
from jointid.simulate.model import seed_model
from jointid.simulate.timeint import integrate, periodic_orbit

N_POINTS = 401
W0, W1 = 160.0, 180.0
F = 1.0


def _amplitude_of_last_period(model, omega, s, y, t0, rtol):
    """Integrate one more period; ``max |q|`` with parabolic refinement of the grid max."""
    T = 2.0 * np.pi / omega
    t = np.linspace(t0, t0 + T, 513)
    tr = integrate(model, omega, F, t, y[0], y[1], q_max=s, rtol=rtol)
    a = np.abs(tr.q[:-1])
    i = int(np.argmax(a))
    y0, y1, y2 = a[i - 1], a[i], a[(i + 1) % a.size]
    den = y0 - 2 * y1 + y2
    peak = y1 - 0.125 * (y0 - y2) ** 2 / den if den < 0 else y1
    return peak, np.array([tr.q[-1], tr.velocity[-1]]), t[-1]


def _settle(model, omega, s, y, t0, duration, rtol):
    T = 2.0 * np.pi / omega
    n = max(int(math.ceil(duration / T)), 2)
    tr = integrate(model, omega, F, [t0, t0 + n * T], y[0], y[1], q_max=s, rtol=rtol)
    return np.array([tr.q[-1], tr.velocity[-1]]), t0 + n * T, n


def brute_force_point(model, omega, delta, rtol, max_outer=40):
    """The paper's iterative approach with Runge-Kutta integration from rest."""
    ic = model.terms.index("q'")
    s0 = _linear_closure_amplitude(model, omega, F)  # "an initial value was considered for q_max"
    c = model.coefficients_at(s0)[ic]
    y, t, periods = np.zeros(2), 0.0, 0
    y, t, n = _settle(model, omega, s0, y, t, (2.0 / c) * math.log(1.0 / delta), rtol)
    A0, y, t = _amplitude_of_last_period(model, omega, s0, y, t, rtol)
    periods += n + 1
    g0, s1 = A0 - s0, A0
    for outer in range(2, max_outer + 1):
        c = model.coefficients_at(s1)[ic]
        change = max(abs(s1 - s0) / s1, delta)
        y, t, n = _settle(model, omega, s1, y, t, (2.0 / c) * math.log(change / delta), rtol)
        A1, y, t = _amplitude_of_last_period(model, omega, s1, y, t, rtol)
        periods += n + 1
        g1 = A1 - s1
        if abs(g1) <= delta * A1:
            return A1, outer, periods
        s0, g0, s1 = s1, g1, s1 - g1 * (s1 - s0) / (g1 - g0)
    raise RuntimeError(f"brute force closure did not converge at omega={omega}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--points", type=int, default=9, help="brute-force subset size (default 9)")
    p.add_argument("--delta", type=float, default=1e-6, help="brute-force relative accuracy target")
    p.add_argument("--rtol", type=float, default=1e-9, help="solve_ivp rtol of the brute force")
    p.add_argument("--repeat", type=int, default=11, help="repetitions of the harmonic-balance timing")
    args = p.parse_args(argv)

    model = seed_model()
    omegas = np.linspace(W0, W1, N_POINTS)
    print(f"seed Eq 19-20, F = {F}, {N_POINTS} frequencies {W0}-{W1} rad/s; python {sys.version.split()[0]}")

    # -- harmonic balance (fast path) --------------------------------------------------
    frequency_response(model, F, omegas)  # warm-up (imports, caches)
    times, times_ns, cpu, cpu_ns = [], [], [], []
    for _ in range(args.repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        hb = frequency_response(model, F, omegas)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        t0, c0 = time.perf_counter(), time.process_time()
        frequency_response(model, F, omegas, stability=False)
        times_ns.append(time.perf_counter() - t0)
        cpu_ns.append(time.process_time() - c0)
    t_hb = min(times)
    print(
        f"HB sweep, 401 pts, H=9, Floquet stability  : {t_hb:8.3f} s wall (best of {args.repeat}, "
        f"median {statistics.median(times):.3f} s; CPU {min(cpu):.3f} s)  ratio 1"
    )
    print(
        f"HB sweep, 401 pts, H=9, no stability       : {min(times_ns):8.3f} s wall (best of {args.repeat}, "
        f"median {statistics.median(times_ns):.3f} s; CPU {min(cpu_ns):.3f} s)  ratio {min(times_ns) / t_hb:.2f}"
    )
    t0 = time.perf_counter()
    cont = frequency_response(model, F, omega_range=(W0, W1))
    t_cont = time.perf_counter() - t0
    print(f"HB continuation 160-180 ({len(cont):3d} pts, adaptive) : {t_cont:8.3f} s  ratio {t_cont / t_hb:.2f}")

    idx = np.unique(np.round(np.linspace(0, N_POINTS - 1, args.points)).astype(int))
    sub = omegas[idx]

    # -- shooting -----------------------------------------------------------------------
    t0 = time.perf_counter()
    shoot = np.array([periodic_orbit(model, w, F).q_max for w in sub])
    t_sh = time.perf_counter() - t0
    t_sh401 = t_sh / sub.size * N_POINTS
    err_sh = np.max(np.abs(shoot / hb.q_max[idx] - 1))
    print(
        f"shooting (DOP853 rtol 1e-12), {sub.size} of 401 pts : {t_sh:8.3f} s measured, "
        f"{t_sh / sub.size:.3f} s/pt -> {t_sh401:8.1f} s scaled to 401  ratio {t_sh401 / t_hb:,.0f}; "
        f"max rel diff to HB {err_sh:.1e}"
    )

    # -- brute force ----------------------------------------------------------------------
    t0 = time.perf_counter()
    results = []
    for w in sub:
        t1 = time.perf_counter()
        A, outer, periods = brute_force_point(model, w, args.delta, args.rtol)
        results.append((w, A, outer, periods, time.perf_counter() - t1))
    t_bf = time.perf_counter() - t0
    brute = np.array([r[1] for r in results])
    err_bf = np.max(np.abs(brute / hb.q_max[idx] - 1))
    for w, A, outer, periods, dt in results:
        print(f"    brute force at {w:7.2f} rad/s: q_max {A:.9e}, {outer} q_max iterations, "
              f"{periods:6d} periods integrated, {dt:6.2f} s")
    t_bf401 = t_bf / sub.size * N_POINTS
    print(
        f"brute force (DOP853 rtol {args.rtol:g}, delta {args.delta:g}), {sub.size} of 401 pts : "
        f"{t_bf:8.2f} s measured, {t_bf / sub.size:.2f} s/pt -> {t_bf401:8.0f} s scaled to 401 (estimate)  "
        f"ratio {t_bf401 / t_hb:,.0f}; max rel diff to HB {err_bf:.1e}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
