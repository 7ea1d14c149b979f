"""Benchmark: the whole ``jointid demo`` and the rig's two ways of simulating a stepped sine.

1. ``run_demo`` end to end (goal: under 60 s on 2 cores), with the time of each stage
   and the acceptance checks;
2. one stepped-sine level of the rig (120 N, F = 6 N, 21 dwells) simulated
   (a) by multi-harmonic balance of the reduced model with the AFT Iwan force, a settle
       check by time integration from each orbit, and records sampled from the solution
       (the rig's method), and
   (b) by the vectorised fixed-step integrator of the same reduced model, every dwell
       from rest until it has settled (the alternative);
   with the difference of the recorded fundamentals between the two.

    python benchmarks/bench_demo.py                 # both parts
    python benchmarks/bench_demo.py --demo-only
    python benchmarks/bench_demo.py --cores 2       # pin the process to 2 cores first
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings

import numpy as np


def fundamental(rec, f_hz, name="accel_42"):
    t = rec.time
    w = 2 * np.pi * f_hz
    A = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)])
    c = np.linalg.lstsq(A, rec[name], rcond=None)[0]
    return float(np.hypot(c[0], c[1]))


def bench_demo():
    from jointid.app.demo import run_demo

    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        res = run_demo(os.path.join(d, "demo"), progress=False)
        total = time.perf_counter() - t
    print(f"run_demo: {total:.1f} s wall ({os.cpu_count()} CPUs visible, "
          f"{len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else '?'} usable)  goal < 60 s")
    for k, v in res.timings.items():
        print(f"  {k:32s} {v:7.2f} s")
    print(res.report())
    return total


def bench_stepped_sine(n_dwells=21, force=6.0, max_time=120.0, settle_tol=5e-3):
    from jointid.rig.rig import Acquisition, seed_rig

    rig = seed_rig(120)
    f1 = rig.linear_frequencies_hz[0]
    freqs = f1 * np.linspace(0.982, 1.010, n_dwells)
    acq = Acquisition()
    t = time.perf_counter()
    states = rig.sweep(freqs, force)
    t_hbm = time.perf_counter() - t
    from jointid.rig.reduced import settle_check

    t = time.perf_counter()
    dev = settle_check(rig.model, states, n_periods=acq.settle_periods, steps_per_period=1024)
    t_settle = time.perf_counter() - t
    t = time.perf_counter()
    recs = [rig.record(s, acq, 0) for s in states]
    t_rec = time.perf_counter() - t
    H = [s.n_harmonics for s in states]
    print(f"\nstepped sine, 120 N, F = {force} N, {n_dwells} dwells, records of {acq.duration} s at {acq.fs:g} Hz")
    print(f"(a) harmonic balance (H = {min(H)}..{max(H)} harmonics, {rig.model.n_modes} modes): "
          f"{t_hbm:.2f} s solve + {t_settle:.2f} s settle check (max deviation {dev.max():.1e}) "
          f"+ {t_rec:.2f} s sampling = {t_hbm + t_settle + t_rec:.2f} s")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t = time.perf_counter()
        dw = rig.stepped_sine(freqs, force, Acquisition(force_noise=0.0, accel_noise=0.0, settle_tol=settle_tol),
                              rng=0, method="time", max_time=max_time)
        t_time = time.perf_counter() - t
    settle_time = dw[0].record.meta["settle_time"]
    err = [abs(fundamental(d.record, d.frequency_hz) / fundamental(r, d.frequency_hz) - 1) for d, r in zip(dw, recs)]
    print(f"(b) time integration from rest (central differences, dt = 1/(8 fs)): {t_time:.2f} s for "
          f"{settle_time:.0f} s of settling + {acq.duration} s of record; {sum(d.settled for d in dw)}/{n_dwells} "
          f"settled (tol {settle_tol:g})")
    print(f"    fundamental of accel_42, (b) vs (a): max relative difference {max(err):.2e}")
    print(f"    speed-up of (a): {t_time / (t_hbm + t_settle + t_rec):.0f}x")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--demo-only", action="store_true", help="skip the stepped-sine comparison")
    ap.add_argument("--cores", type=int, default=None, help="pin the process to this many cores first")
    ap.add_argument("--settle-tol", type=float, default=5e-3,
                    help="settle tolerance of the time-integration alternative (default: %(default)s)")
    args = ap.parse_args(argv)
    if args.cores and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[: args.cores])
    bench_demo()
    if not args.demo_only:
        bench_stepped_sine(settle_tol=args.settle_tol)


if __name__ == "__main__":
    main()
