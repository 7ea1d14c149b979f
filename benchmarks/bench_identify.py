"""Benchmark: identification of one 1e6-sample steady-state record.

Prints the time of the whole per-record chain (validation, frequency estimate, harmonic
fit, integration, force-state mapping) and its ratio to numpy merely streaming the same
arrays (one pass of sums over force and acceleration), measured in the same process.

    python benchmarks/bench_identify.py
"""

from __future__ import annotations

import time

import numpy as np

from bench_speed import record  # the same benchmark record (this folder is on the path when run as a script)

from jointid.identify.fsm import ForceStateMapping
from jointid.signal.harmonics import steady_state_signals


def best_of(fn, repeat=5):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main(n=1_000_000, fs=20000.0):
    t, Q, a, f = record(n, fs)

    def stream():
        return float(np.sum(Q)) + float(np.sum(a)) + float(np.sum(t))

    def identify(freq, refine=True):
        sig = steady_state_signals(t, Q, a, frequency_hz=freq, n_harmonics=5, refine_frequency=refine)
        return ForceStateMapping().fit(sig).result_

    base = best_of(stream)
    trusted = best_of(lambda: identify(f, refine=False))
    given = best_of(lambda: identify(f))
    est = best_of(lambda: identify(None), repeat=3)
    res = identify(None)
    print(f"record: {n} samples, fs {fs:g} Hz, 1 % noise")
    print(f"numpy streaming the arrays (baseline): {base * 1e3:8.2f} ms")
    print(f"identify, frequency given and trusted: {trusted * 1e3:8.2f} ms   ratio {trusted / base:7.1f}x")
    print(f"identify, frequency given (checked):   {given * 1e3:8.2f} ms   ratio {given / base:7.1f}x   (goal < 200 ms)")
    print(f"identify, frequency estimated:         {est * 1e3:8.2f} ms   ratio {est / base:7.1f}x")
    print(f"  identified omega1 = {res.omega1:.6f} rad/s (exact 170), k3 = {res.k3:.4g} (exact 5e6)")


if __name__ == "__main__":
    main()
