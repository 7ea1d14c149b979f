"""Benchmark: peak memory of ``jointid identify`` on one long stepped-sine record.

Writes a campaign of one record (``--samples``, default 2e7: the campaign limit) in HDF5 or
CSV into a temporary folder, identifies it in a subprocess and prints the subprocess's peak
resident set size, the same for a record of 20,000 samples (the interpreter, its imports and
the figures), and the bytes per sample between the two (the record itself is 24 bytes per
sample: time, force and acceleration as float64).

    python benchmarks/bench_huge_record.py                       # 2e7 samples, HDF5, ~3 min
    python benchmarks/bench_huge_record.py --format csv          # the same as CSV (~1 GB file)
    python benchmarks/bench_huge_record.py --samples 2e6
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: The subprocess's own peak resident memory is its VmHWM: ``ru_maxrss`` after a fork and exec also holds
#: the parent's resident size at the fork.
RUN = """
import json, resource, sys
from jointid.cli import main
rc = main(["identify", sys.argv[1], "--out", sys.argv[2], "--quiet"])
try:
    with open("/proc/self/status") as fh:
        peak = next(float(line.split()[1]) for line in fh if line.startswith("VmHWM:")) / 1024.0
except (OSError, StopIteration):
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps({"rc": rc, "peak_mib": peak}))
"""


def record_block(i0, i1, fs, rng, w1=170.0, k3=5e6, w=160.0, A=2e-3, t0=0.25):
    """Samples ``i0:i1`` of a steady state of ``q'' + c q' + w1^2 q - k3 q^3 = Q`` with noise."""
    t = np.arange(i0, i1) / fs + t0
    q = A * np.cos(w * t) + 0.001 * A * np.cos(3 * w * t + 0.3)
    v = -A * w * np.sin(w * t) - 0.003 * A * w * np.sin(3 * w * t + 0.3)
    a = -A * w * w * np.cos(w * t) - 0.009 * A * w * w * np.cos(3 * w * t + 0.3)
    Q = a + w1**2 * q - k3 * q**3 + (0.1 + 50 * A) * v + 0.05 * rng.standard_normal(t.size)
    return t, Q, a + 1.2 * rng.standard_normal(t.size)


def write_campaign_of_one(folder: Path, n: int, fmt: str, fs=51200.0) -> None:
    import h5py

    from jointid.io.campaign import write_campaign

    rng = np.random.default_rng(1)
    (folder / "records").mkdir(parents=True)
    path = folder / "records" / f"0000.{fmt}"
    step = 1 << 20
    if fmt == "csv":
        with open(path, "w") as fh:
            fh.write("time,force,accel\n")
            for i0 in range(0, n, step):
                np.savetxt(fh, np.column_stack(record_block(i0, min(n, i0 + step), fs, rng)), delimiter=",",
                           fmt="%.17g")
    else:
        with h5py.File(path, "w") as f:
            f.attrs["format"] = "jointid.channels"
            f.attrs["format_version"] = 1
            f.attrs["channel_names"] = '["force", "accel"]'
            g = f.create_group("channels")
            ds = [f.create_dataset("time", (n,), "f8"), g.create_dataset("force", (n,), "f8"),
                  g.create_dataset("accel", (n,), "f8")]
            for i0 in range(0, n, step):
                i1 = min(n, i0 + step)
                for d, x in zip(ds, record_block(i0, i1, fs, rng)):
                    d[i0:i1] = x
    write_campaign(folder, "one long record", [{"file": f"records/0000.{fmt}", "force_level": 1.0, "preload": 1}])


#: Samples of the reference record (the memory of everything but the samples).
SMALL = 20_000


def run(*args) -> dict:
    p = subprocess.run([sys.executable, "-c", RUN, *map(str, args)], capture_output=True, text=True, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=float, default=2e7)
    ap.add_argument("--format", choices=("h5", "csv"), default="h5")
    args = ap.parse_args()
    n = int(args.samples)
    with tempfile.TemporaryDirectory(prefix="jointid-bench-") as d:
        camp = Path(d) / "camp"
        t = time.perf_counter()
        write_campaign_of_one(camp, n, args.format)
        size = (camp / "records" / f"0000.{args.format}").stat().st_size
        print(f"wrote {n:.3g} samples ({args.format}, {size / 2**20:.0f} MiB) in {time.perf_counter() - t:.0f} s")
        write_campaign_of_one(Path(d) / "small", SMALL, args.format)
        base = run(Path(d) / "small", Path(d) / "small-out")["peak_mib"]
        t = time.perf_counter()
        out = run(camp, Path(d) / "out")
        wall = time.perf_counter() - t
    per_sample = (out["peak_mib"] - base) * 2**20 / (n - SMALL)
    print(f"identify: exit {out['rc']}, {wall:.0f} s, peak RSS {out['peak_mib']:.0f} MiB "
          f"({SMALL} samples: {base:.0f} MiB; {per_sample:.1f} bytes per sample beyond them)")


if __name__ == "__main__":
    main()
