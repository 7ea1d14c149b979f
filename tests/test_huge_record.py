"""One long record in bounded memory: the record is read, checked and reduced block by block.

The fast tests shrink the blocks so that a short record spans many of them and check that
every block-wise result (plausibility checks, validation messages, state signals,
hysteresis loops, the first-harmonic fit of the backbone, a whole identification) equals
the one-block result.  The slow test identifies one stepped-sine record of 2e7 samples
(the largest record a campaign accepts) in a subprocess and bounds its peak resident set
size.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from memory_probe import PEAK_MIB

from jointid.io import channels as channels_mod
from jointid.signal import harmonics
from jointid.signal.checks import clipping_flag, record_flags
from jointid.signal.harmonics import steady_state_signals

FS, W1, K3, W = 5120.0, 170.0, 5e6, 160.0
AMP = 2e-3
C = 0.1 + 50 * AMP

# the generator of the slow test's record, also used for the short ones (one block of samples at a time)
GENERATOR = textwrap.dedent(
    """
    import numpy as np

    def record_block(i0, i1, fs, rng, w1=170.0, k3=5e6, w=160.0, A=2e-3, t0=0.25):
        t = np.arange(i0, i1) / fs + t0
        q = A * np.cos(w * t) + 0.001 * A * np.cos(3 * w * t + 0.3)
        v = -A * w * np.sin(w * t) - 0.003 * A * w * np.sin(3 * w * t + 0.3)
        a = -A * w * w * np.cos(w * t) - 0.009 * A * w * w * np.cos(3 * w * t + 0.3)
        c = 0.1 + 50 * A
        Q = a + w1 ** 2 * q - k3 * q ** 3 + c * v + 0.05 * rng.standard_normal(t.size)
        a = a + 1.2 * rng.standard_normal(t.size)
        return t, Q, a
    """
)
_ns: dict = {}
exec(GENERATOR, _ns)
record_block = _ns["record_block"]


def _record(n, fs=FS, seed=1):
    return record_block(0, n, fs, np.random.default_rng(seed))


def _close(a, b, path=""):
    """Every number of two JSON-like trees equal within 1e-12 relative (lists of differences)."""
    out = []
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [(path, "keys", sorted(set(a) ^ set(b)))]
        for k in a:
            if k not in ("run_id", "provenance"):
                out += _close(a[k], b[k], f"{path}/{k}")
    elif isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            return [(path, "length")]
        for i, (x, y) in enumerate(zip(a, b)):
            out += _close(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        if not (a == b or (math.isnan(a) and math.isnan(b)) or abs(a - b) <= 1e-12 * max(abs(a), abs(b))):
            out.append((path, a, b))
    elif a != b:
        out.append((path, a, b))
    return out


def _flags(signals):
    return [f.summary() for f in record_flags(signals)]


def test_checks_in_blocks_equal_the_whole_record(monkeypatch):
    t, Q, a = _record(20000)
    Q = np.minimum(Q, 0.9 * Q.max())  # a clipped force
    a = a.copy()
    a[[321, 7777, 15001]] += (400.0, -350.0, 500.0)  # spikes in three different small blocks
    s = steady_state_signals(t, Q, a, n_harmonics=5)
    whole = _flags(s), clipping_flag(Q, "force").summary()
    assert {f["name"] for f in whole[0]} >= {"clipping", "spikes"}
    spikes = next(f for f in whole[0] if f["name"] == "spikes" and f["values"]["channel"] == "accel")
    # the block-wise robust scale and spike count equal those of the whole residual
    r = a - s.acceleration(t)
    sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    assert spikes["values"]["robust_sigma"] == pytest.approx(sigma, rel=1e-12)
    assert spikes["values"]["n_samples"] == int(np.sum(np.abs(r) > 10 * sigma)) == 3
    assert spikes["values"]["worst_sample"] == 15001
    monkeypatch.setattr(harmonics, "BLOCK", 1000)
    blocked = _flags(s), clipping_flag(Q, "force").summary()
    assert _close(list(whole), list(blocked)) == []


def test_state_signals_and_loops_in_blocks(monkeypatch):
    from jointid.identify.hysteresis import hysteresis_loop

    t, Q, a = _record(20000)
    s = steady_state_signals(t, Q, a, n_harmonics=5)
    theta = [W1**2, K3, C]
    states = s.states()
    loops = [hysteresis_loop(s, "q + -q^3 + q'", theta, filtered=f).summary() for f in (True, False)]
    for got, series in zip(states, (s.displacement, s.velocity, s.acceleration)):
        np.testing.assert_allclose(got, series(t), rtol=1e-10, atol=1e-12 * np.abs(got).max())
    m = 1000
    np.testing.assert_array_equal(s.states(stop=m)[0], states[0][:m])
    monkeypatch.setattr(harmonics, "BLOCK", 999)
    for got, ref in zip(s.states(), states):  # the same sinusoids; the products may round differently
        np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-14 * np.abs(ref).max())
    blocked = [hysteresis_loop(s, "q + -q^3 + q'", theta, filtered=f).summary() for f in (True, False)]
    assert _close(loops, blocked) == []


def test_backbone_fundamental_equals_least_squares():
    from jointid.identify.backbone import _fundamental

    t, Q, _ = _record(50000)
    tau = t - t[0]
    A = np.column_stack([np.ones_like(tau), np.cos(W * tau), np.sin(W * tau)])
    coef, *_ = np.linalg.lstsq(A, Q, rcond=None)
    r = Q - A @ coef
    X_ref = (coef[1] - 1j * coef[2]) * np.exp(-1j * W * t[0])
    se_ref = np.sqrt(r @ r / (Q.size - 3)) * np.sqrt(2.0 / Q.size)
    X, se = _fundamental(t, Q, W)
    assert abs(X - X_ref) <= 1e-12 * abs(X_ref)
    assert se == pytest.approx(se_ref, rel=1e-10)


def test_validation_messages_in_blocks(monkeypatch):
    from jointid.errors import RecordError

    t = np.arange(100) / 100.0
    cases = []
    x = np.ones(100)
    x[57] = np.nan
    cases.append((t, {"x": x}))
    tt = t.copy()
    tt[43] += 0.003
    cases.append((tt, {"x": np.ones(100)}))
    tt = t.copy()
    tt[71] = tt[70]
    cases.append((tt, {"x": np.ones(100)}))

    def messages():
        out = []
        for time, data in cases:
            with pytest.raises(RecordError) as exc:
                channels_mod.validate_channels(time, data, source="r.csv")
            out.append(str(exc.value))
        return out

    whole = messages()
    assert "sample 57" in whole[0] and "samples 42 and 43" in whole[1] and "t[71]" in whole[2]
    monkeypatch.setattr(channels_mod, "BLOCK", 7)
    assert messages() == whole


def test_identify_in_blocks_equals_one_block(tmp_path, monkeypatch):
    from jointid.app.workflow import identify_campaign
    from jointid.io.campaign import write_campaign, write_csv_record

    t, Q, a = _record(24000)
    (tmp_path / "records").mkdir()
    write_csv_record(tmp_path / "records" / "0000.csv", t, {"force": Q, "accel": a})
    write_campaign(tmp_path, "long", [{"file": "records/0000.csv", "force_level": 1.0, "preload": 1}])

    def run():
        with pytest.warns(Warning):
            return identify_campaign(tmp_path).summary()

    whole = run()
    rec = whole["records"][0]
    assert rec["status"] == "ok" and rec["flags"] == []
    assert rec["omega1"] == pytest.approx(W1, rel=1e-3)
    monkeypatch.setattr(harmonics, "BLOCK", 1000)
    monkeypatch.setattr(channels_mod, "BLOCK", 1000)
    assert _close(whole, run()) == []


SCRIPT = PEAK_MIB + textwrap.dedent(
    """
    import json, sys
    from jointid.cli import main
    rc = main(["identify", sys.argv[1], "--out", sys.argv[2], "--quiet"])
    print(json.dumps({"rc": rc, "peak_mib": peak_mib()}))
    """
)


def _write_huge(folder, n, fmt, fs=51200.0):
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
    write_campaign(folder, "huge", [{"file": f"records/0000.{fmt}", "force_level": 1.0, "preload": 1}])


@pytest.mark.slow
@pytest.mark.parametrize("fmt, n", [("h5", 20_000_000), ("csv", 5_000_000)])
def test_huge_record_within_memory(tmp_path, fmt, n):
    """2e7 samples (the campaign limit) identified within 1.5 GiB peak RSS, the parameters recovered; a CSV
    record (5e6 samples: writing 2e7 as text takes most of a quarter of an hour) within the same bytes per
    sample beyond a short record's run (20,000 samples, measured here: the interpreter, imports and figures;
    the whole-record code took about 200 bytes per sample)."""
    def identify(n, name):
        _write_huge(tmp_path / name, n, fmt)
        p = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path / name), str(tmp_path / f"{name}-out")],
                           capture_output=True, text=True, timeout=1800)
        assert p.returncode == 0, p.stderr[-3000:]
        return json.loads(p.stdout.strip().splitlines()[-1])

    short = identify(20_000, "short")  # the interpreter, its imports and the figures
    run = identify(n, "camp")
    per_sample = (run["peak_mib"] - short["peak_mib"]) * 2**20 / n
    print(f"{fmt}: {n} samples, peak RSS {run['peak_mib']:.0f} MiB (20,000 samples: {short['peak_mib']:.0f} MiB; "
          f"{per_sample:.1f} bytes per sample beyond it)")
    assert run["rc"] == 0 and short["rc"] == 0
    assert run["peak_mib"] < 1536.0
    assert per_sample < 75.0, "bytes per sample beyond a short record's run"
    rec = json.loads((tmp_path / "camp-out" / "results.json").read_text())["records"][0]
    assert rec["status"] == "ok" and rec["flags"] == []
    coef, se = rec["coefficients"], rec["stderr"]
    for name, truth in (("omega1^2", W1**2), ("k3", K3), ("c", C)):
        assert abs(coef[name] - truth) < 4 * se[name], (name, coef[name], se[name])
    assert se["k3"] < 0.05 * K3 * (2e7 / n) ** 0.5  # the standard error shrinks as 1/sqrt(samples)
