"""Memory linear in the number of records: 10,000 records of 2,000 samples in bounded memory.

(The slow test measures 500 and 2,000 records and extrapolates the slope to 10,000.)

The campaign is written and identified in a subprocess whose peak resident set size
(``VmHWM``, tests/memory_probe.py) is reported and bounded: the chain keeps per-record state
signals and fits, the pooled fits work group by group, and the figures are capped.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest
from memory_probe import PEAK_MIB

SCRIPT = PEAK_MIB + textwrap.dedent(
    """
    import json, sys, time, warnings
    from pathlib import Path
    import numpy as np
    from jointid.io.campaign import write_campaign
    from jointid.app.workflow import identify_campaign

    folder, n_records, n_samples, n_groups = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
    rng = np.random.default_rng(0)
    w1, k3, fs = 170.0, 5e6, 2000.0
    t = np.arange(n_samples) / fs
    entries = []
    (folder / "records").mkdir(parents=True)
    for i in range(n_records):
        g = i % n_groups
        w = w1 * (0.94 + 0.12 * rng.random())
        A = 1e-3 * (1 + g)
        c = 0.1 + 50 * A
        q = A * np.cos(w * t)
        v = -A * w * np.sin(w * t)
        a = -A * w * w * np.cos(w * t)
        Q = a + w1 ** 2 * q - k3 * q ** 3 + c * v
        a = a + 0.02 * a.std() * rng.standard_normal(n_samples)
        Q = Q + 0.02 * Q.std() * rng.standard_normal(n_samples)
        rel = f"records/{i:05d}.csv"
        np.savetxt(folder / rel, np.column_stack([t, Q, a]), delimiter=",", fmt="%.12g", header="time,force,accel",
                   comments="")
        entries.append({"file": rel, "frequency_hz": w / (2 * np.pi), "force_level": float(g + 1), "preload": 1})
    write_campaign(folder, "many records", entries)
    rss_written = peak_mib()
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(folder, repredict=False)
    elapsed = time.perf_counter() - start
    from jointid.report.output import write_results
    write_results(res, folder.parent / "out", figures=True)
    print(json.dumps({"peak_rss_mib": peak_mib(), "rss_after_writing_mib": rss_written,
                      "seconds": elapsed, "ok": sum(r.ok for r in res.records),
                      "usable": sum(r.usable for r in res.records),
                      "omega1": [g.pooled.omega1 for g in res.groups]}))
    """
)


def _run(tmp_path, n_records, n_samples, n_groups, timeout):
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path / "camp"), str(n_records), str(n_samples),
                           str(n_groups)], capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_memory_small_campaign(tmp_path):
    """The measurement itself, on 40 records: all identified, peak RSS stated."""
    m = _run(tmp_path, 40, 2000, 4, 600)
    print(f"40 records x 2000 samples: peak RSS {m['peak_rss_mib']:.0f} MiB, identify {m['seconds']:.1f} s")
    assert m["ok"] == 40 and m["usable"] == 40
    assert all(abs(w / 170.0 - 1) < 0.02 for w in m["omega1"])


@pytest.mark.slow
def test_ten_thousand_records_in_bounded_memory(tmp_path):
    """Peak RSS grows linearly with the records, slowly enough that 10,000 records of 2,000 samples
    stay under 1 GiB: measured at 500 and 2,000 records, extrapolated linearly to 10,000 (a
    10,000-record run took 7 minutes on two cores; the same bound, checked by the same slope)."""
    small = _run(tmp_path / "small", 500, 2000, 10, 3600)
    large = _run(tmp_path / "large", 2_000, 2000, 10, 3600)
    per_record = (large["peak_rss_mib"] - small["peak_rss_mib"]) / 1_500
    at_10k = large["peak_rss_mib"] + 8_000 * max(per_record, 0.0)
    print(f"peak RSS {small['peak_rss_mib']:.0f} MiB (500 records), {large['peak_rss_mib']:.0f} MiB (2,000): "
          f"{per_record * 1024:.0f} KiB per record, {at_10k:.0f} MiB extrapolated to 10,000")
    assert small["ok"] == 500 and large["ok"] == 2_000
    assert at_10k < 1024
