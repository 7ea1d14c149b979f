"""Benchmark: identify a campaign of 2,000 small records in this process, on one and on two workers.

Simulates a campaign (default 2,000 stepped-sine records: 20 force levels of 100 frequencies,
20-period records at 2 kHz, 1 % noise) once, then identifies it three times, measured in the
same process:

* in this process, without dask (``jobs=1``): the baseline;
* on a local cluster of one worker: the overhead of dask against the work;
* on a local cluster of ``--workers`` workers (default 2): the speed-up.

The clusters are started before the clock runs (their start-up and the workers' imports are
printed apart), and the end-to-end time of ``jobs=N`` (a cluster started for the call, as
``jointid identify --jobs N`` does) is printed too.  CPU time counts this process and the
workers (their CPU time during the run); the ratio of CPU per record to the in-process run
does not depend on the machine's load, the wall-time ratio does (compare with the load average
printed).  Reprediction by harmonic balance (serial, in this process) is left out: it is not
parallel work.  Checks that the three runs give the same results.json content.

    python benchmarks/bench_identify_parallel.py                # ~4 min on two quiet cores
    python benchmarks/bench_identify_parallel.py --records 600  # quicker
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
import warnings
from pathlib import Path

from jointid.app import parallel
from jointid.app.parallel import local_cluster
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign


def config(records: int) -> dict:
    levels = max(1, records // 100)
    return {
        "campaign": {"name": "parallel benchmark"},
        "model": [{"preload": "sim", "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
                   "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
        "excitation": {"force_levels": [0.4 + 0.1 * k for k in range(levels)], "omega_start": 160.0,
                       "omega_stop": 180.0, "n_frequencies": max(1, records // levels)},
        "acquisition": {"fs": 2000.0, "periods": 20, "noise": 0.01, "seed": 1},
    }


def _warm_up():
    import jointid.app.records  # noqa: F401 - imports are a one-off cost of a worker, not of its records
    import jointid.app.workflow  # noqa: F401


def run(camp, **kw):
    w, c = time.perf_counter(), time.process_time()
    res = identify_campaign(camp, repredict=False, **kw)
    wall, cpu = time.perf_counter() - w, time.process_time() - c
    cpu += parallel.LAST_RUN.get("worker_cpu_s", 0.0)
    return json.dumps(res.summary(), sort_keys=True, default=str), wall, cpu


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=2000)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    import distributed

    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        camp = Path(tmp) / "campaign"
        t0 = time.perf_counter()
        simulate_campaign(load_simulation_config(config(args.records)), camp)
        n = len(list((camp / "records").iterdir()))
        print(f"{n} records simulated in {time.perf_counter() - t0:.1f} s; load average {os.getloadavg()[0]:.2f} "
              f"on {os.cpu_count()} cores")
        ref, t_serial, cpu_serial = run(camp)
        print(f"in this process (no dask):   {t_serial:7.2f} s wall, {cpu_serial:7.2f} s CPU, "
              f"{1e3 * cpu_serial / n:6.2f} ms CPU per record")
        same, walls = [], {}
        for workers in (1, args.workers):
            t0 = time.perf_counter()
            with local_cluster(workers) as cl, distributed.Client(cl) as client:
                client.run(_warm_up)
                start = time.perf_counter() - t0
                out, t, cpu = run(camp, scheduler=cl.scheduler_address)
            same.append(out == ref)
            walls[workers] = t
            print(f"local cluster, {workers} worker(s): {t:7.2f} s wall, {cpu:7.2f} s CPU, "
                  f"{1e3 * cpu / n:6.2f} ms CPU per record ({cpu / cpu_serial:4.2f}x in-process); "
                  f"speed-up {t_serial / t:4.2f}x (cluster start and imports {start:.2f} s, not counted)")
        out, t, cpu = run(camp, jobs=args.workers)
        same.append(out == ref)
        print(f"jobs={args.workers} end to end (cluster started for the call): {t:7.2f} s wall, {cpu:7.2f} s CPU; "
              f"speed-up {t_serial / t:4.2f}x")
        print(f"goal: {args.workers} workers >= 1.6x in-process wall ({t_serial / walls[args.workers]:.2f}x), CPU per "
              f"record within 15 %; load average now {os.getloadavg()[0]:.2f}")
        print("results identical in all runs:", all(same))


if __name__ == "__main__":
    main()
