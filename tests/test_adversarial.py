"""Adversarial corpus: bad inputs as a careless or unlucky user would give them.

Every case ends either in exit 2 with a message naming the file, key or record (nothing
is written), or in a failed or flagged record while the other records are identified.
Never a traceback, never a silent wrong number.  Cases: records, manifests, imports,
structures, command-line values, output folders and random perturbations; the signal
cases (SIGINT / SIGKILL of a running command) are in ``test_adversarial_kills.py``.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil

import numpy as np
import pytest

from jointid.app.paper_example import paper_config
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.cli import main
from jointid.io.campaign import load_campaign, read_record, toml_dumps, write_campaign, write_csv_record

N_BASE = 9  # records per group: the stepped sine of the seed's example around resonance
BAD = 4  # the corrupted record of a group


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A clean simulated campaign (2 % noise): the records every case starts from."""
    cfg = paper_config(n_frequencies=N_BASE, fs=2000.0, periods=20, noise=0.02, seed=7, write_frequency=False)
    folder = simulate_campaign(load_simulation_config(cfg), tmp_path_factory.mktemp("base"))
    return [read_record(s) for s in load_campaign(folder).records]


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    return code, err


# --------------------------------------------------------------------------------- records
def _bytes_csv(t, cols):
    lines = ["time," + ",".join(cols)] + [",".join(repr(float(v)) for v in row)
                                           for row in zip(t, *cols.values())]
    return ("\n".join(lines) + "\n").encode()


def corrupt_record(kind, t, Q, a, rng):
    """``(file bytes or None, (t, Q, a))`` of a corrupted record."""
    Q, a = Q.copy(), a.copy()
    pk = np.abs(a).max()
    simple = {
        "nan_accel": lambda: a.__setitem__(10, np.nan),
        "inf_force": lambda: Q.__setitem__(3, np.inf),
        "huge_value": lambda: a.__setitem__(50, 1e300),
        "spike": lambda: a.__setitem__(200, 50 * pk),
        "dropout": lambda: a.__setitem__(slice(300, 340), 0.0),
    }
    if kind in simple:
        simple[kind]()
    elif kind == "clip_40":
        a = np.clip(a, -0.4 * pk, 0.4 * pk)
    elif kind == "clip_90":
        a = np.clip(a, -0.9 * pk, 0.9 * pk)
    elif kind == "clip_force":
        Q = np.clip(Q, -0.8 * np.abs(Q).max(), 0.8 * np.abs(Q).max())
    elif kind == "in_g":
        a = a / 9.81
    elif kind == "sign_accel":
        a = -a
    elif kind == "sign_force":
        Q = -Q
    elif kind == "time_ms":
        t = t * 1000.0
    elif kind == "swapped":
        Q, a = a, Q
    elif kind == "stuck_981":
        a = np.full_like(a, 9.81)
    elif kind == "zero_accel":
        a = np.zeros_like(a)
    elif kind == "zero_force":
        Q = np.zeros_like(Q)
    elif kind == "dead_sensor":
        a = 1e-3 * a.std() * rng.standard_normal(a.size)
    elif kind == "noise_force":
        Q = Q.std() * rng.standard_normal(Q.size)
    elif kind == "transient":
        tau = (t[-1] - t[0]) / 4
        a = a + a.std() * np.exp(-(t - t[0]) / tau) * np.cos(0.97 * 170.0 * (t - t[0]))
    elif kind == "drive_off":
        n = int(0.8 * t.size)
        Q[n:] = 0.0
        a[n:] *= np.exp(-np.arange(t.size - n) / 50.0)
    elif kind == "short":
        t, Q, a = t[:20], Q[:20], a[:20]
    elif kind == "nonmonotonic":
        t = t.copy()
        t[20], t[21] = t[21], t[20]
    elif kind == "uneven":
        t = t.copy()
        t[100:] += 0.3 * (t[1] - t[0])
    elif kind == "utf16":
        return _bytes_csv(t, {"force": Q, "accel": a}).decode().encode("utf-16"), None
    elif kind == "binary":
        return rng.bytes(4000), None
    elif kind == "empty":
        return b"", None
    elif kind == "header_only":
        return b"time,force,accel\n", None
    elif kind == "ragged":
        raw = _bytes_csv(t, {"force": Q, "accel": a}).decode().splitlines()
        raw[30] = raw[30].rsplit(",", 1)[0]
        return ("\n".join(raw) + "\n").encode(), None
    elif kind == "text_cell":
        raw = _bytes_csv(t, {"force": Q, "accel": a}).decode().splitlines()
        raw[30] = raw[30].rsplit(",", 1)[0] + ",n/a"
        return ("\n".join(raw) + "\n").encode(), None
    elif kind == "latin1":
        raw = _bytes_csv(t, {"force": Q, "accel": a}).replace(b"accel", b"acc\xe9l", 1)
        return raw, None
    elif kind == "duplicate_column":
        return _bytes_csv(t, {"force": Q, "accel": a}).replace(b"time,force,accel", b"time,force,force", 1), None
    elif kind == "missing_column":
        return _bytes_csv(t, {"force": Q, "acceleration": a}), None
    else:  # pragma: no cover
        raise ValueError(kind)
    return None, (t, Q, a)


#: kind -> ("failed", pattern in the message) or ("flagged", names of acceptable flags)
RECORD_CASES = {
    "nan_accel": ("failed", r"'accel'.*non-finite"),
    "inf_force": ("failed", r"'force'.*non-finite"),
    "huge_value": ("failed", r"'accel'.*beyond the usable range"),
    "spike": ("flagged", {"spikes"}),
    "dropout": ("flagged", {"spikes", "transient"}),
    "clip_40": ("flagged", {"clipping"}),
    "clip_90": ("flagged", {"clipping"}),
    "clip_force": ("flagged", {"clipping"}),
    "in_g": ("flagged", {"scale_outlier"}),
    "sign_accel": ("flagged", {"negative_input_power", "channel_swap", "negative_stiffness"}),
    "sign_force": ("flagged", {"negative_input_power", "channel_swap", "negative_stiffness"}),
    "time_ms": ("flagged", {"time_unit", "scale_outlier"}),
    "swapped": ("flagged", {"channel_swap", "negative_input_power"}),
    "stuck_981": ("failed", r"'accel'.*constant \(9.81"),
    "zero_accel": ("failed", r"'accel'.*zero at every sample"),
    "zero_force": ("failed", r"'force'.*zero"),
    "dead_sensor": ("flagged", {"dead_channel"}),
    "noise_force": ("failed|flagged", r"excitation frequency|dead_channel"),
    "transient": ("flagged", {"transient"}),
    "drive_off": ("flagged", {"transient", "spikes"}),
    "short": ("failed", r"period|samples"),
    "nonmonotonic": ("failed", r"'time'.*increasing"),
    "uneven": ("failed", r"'time'.*uniform"),
    "utf16": ("failed", r"UTF-8.*UTF-16"),
    "binary": ("failed", r"UTF-8|binary"),
    "empty": ("failed", r"empty|header|samples"),
    "header_only": ("failed", r"samples|empty|columns"),
    "ragged": ("failed", r"different lengths|columns"),
    "text_cell": ("failed", r"non-numeric|columns"),
    "latin1": ("failed", r"UTF-8"),
    "duplicate_column": ("failed", r"duplicate column"),
    "missing_column": ("failed", r"'accel'.*missing column"),
}


@pytest.fixture(scope="module")
def record_corpus(base, tmp_path_factory):
    """One campaign: a group per corruption (the clean records with one of them corrupted)."""
    folder = tmp_path_factory.mktemp("records")
    rng = np.random.default_rng(11)
    entries = []
    for g, kind in enumerate(RECORD_CASES):
        for i, rec in enumerate(base):
            rel = f"records/{kind}_{i}.csv"
            t, Q, a = rec.time, rec.channels["force"], rec.channels["accel"]
            raw = None
            if i == BAD:
                raw, arrays = corrupt_record(kind, t, Q, a, rng)
                if arrays is not None:
                    t, Q, a = arrays
            if raw is not None:
                (folder / rel).parent.mkdir(parents=True, exist_ok=True)
                (folder / rel).write_bytes(raw)
            else:
                write_csv_record(folder / rel, t, {"force": Q, "accel": a})
            entries.append({"file": rel, "force_level": 1.0, "preload": kind})
    write_campaign(folder, "record corpus", entries)
    out = folder.parent / (folder.name + "-out")
    code = main(["identify", str(folder), "--out", str(out), "--quiet", "--no-figures", "--no-reprediction"])
    return code, json.loads((out / "results.json").read_text())


@pytest.mark.parametrize("kind", list(RECORD_CASES))
def test_record_corpus(record_corpus, kind):
    code, res = record_corpus
    assert code == 1  # the run finished, some records failed or were flagged
    recs = {r["file"]: r for r in res["records"]}
    bad = recs[f"records/{kind}_{BAD}.csv"]
    outcome, expect = RECORD_CASES[kind]
    flags = {f["name"] for f in bad["flags"]}
    if bad["status"] == "failed":
        assert "failed" in outcome, (kind, bad["error"])
        assert f"records/{kind}_{BAD}.csv" in bad["error"] and f"record {bad['index']}" in bad["error"]
        assert re.search(expect if isinstance(expect, str) else "$^", bad["error"]), (kind, bad["error"])
        assert bad["error"].count(f"records/{kind}_{BAD}.csv") == 1  # the location once
    else:
        assert "flagged" in outcome, (kind, bad["flags"])
        names = expect if isinstance(expect, set) else set(re.findall(r"\w+", expect))
        assert flags & names, (kind, flags)
        assert all(f["values"] and f["message"] for f in bad["flags"])
    group = next(g for g in res["groups"] if g["preload"] == kind)
    assert bad["index"] not in group["records"]
    others = [recs[f"records/{kind}_{i}.csv"] for i in range(N_BASE) if i != BAD]
    assert all(r["status"] == "ok" and not r["flags"] for r in others), kind
    assert sorted(group["records"]) == sorted(r["index"] for r in others)
    assert group["omega1"] == pytest.approx(170.0, rel=5e-3)  # the good records still give the model


# ------------------------------------------------------------------------- random perturbations
PERTURBATIONS = 40


@pytest.fixture(scope="module")
def random_corpus(base, tmp_path_factory):
    """A group per seed with one record perturbed at random (kind, place and size)."""
    folder = tmp_path_factory.mktemp("random")
    kinds = ["scale_accel", "scale_force", "spikes", "nan_run", "clip", "truncate", "offset_time", "jitter",
             "polarity", "swap"]
    plan = {}
    entries = []
    for s in range(PERTURBATIONS):
        rng = np.random.default_rng(1000 + s)
        kind = kinds[s % len(kinds)]
        plan[s] = kind
        for i, rec in enumerate(base):
            t, Q, a = rec.time.copy(), rec.channels["force"].copy(), rec.channels["accel"].copy()
            if i == BAD:
                if kind == "scale_accel":
                    a *= float(rng.choice([1e-3, 1 / 9.81, 9.81, 1e3]))
                elif kind == "scale_force":
                    Q *= float(rng.choice([1e-3, 1 / 9.81, 9.81, 1e3]))
                elif kind == "spikes":
                    idx = rng.choice(a.size, int(rng.integers(1, 5)), replace=False)
                    a[idx] += float(rng.uniform(20, 1e6)) * np.abs(a).max() * rng.choice([-1, 1], idx.size)
                elif kind == "nan_run":
                    j = int(rng.integers(0, a.size - 5))
                    (a if rng.random() < 0.5 else Q)[j:j + int(rng.integers(1, 5))] = np.nan
                elif kind == "clip":
                    lim = float(rng.uniform(0.3, 0.9)) * np.abs(a).max()
                    a = np.clip(a, -lim, lim)
                elif kind == "truncate":
                    n = int(rng.integers(2, 30))
                    t, Q, a = t[:n], Q[:n], a[:n]
                elif kind == "offset_time":
                    t = t * float(rng.choice([1e-3, 1e3]))
                elif kind == "jitter":
                    t = t + float(rng.uniform(0.05, 0.5)) * (t[1] - t[0]) * rng.standard_normal(t.size)
                elif kind == "polarity":
                    a = -a
                elif kind == "swap":
                    Q, a = a, Q
            rel = f"records/s{s}_{i}.csv"
            write_csv_record(folder / rel, t, {"force": Q, "accel": a})
            entries.append({"file": rel, "force_level": 1.0, "preload": f"s{s}"})
    write_campaign(folder, "random corpus", entries)
    out = folder.parent / (folder.name + "-out")
    code = main(["identify", str(folder), "--out", str(out), "--quiet", "--no-figures", "--no-reprediction"])
    return code, json.loads((out / "results.json").read_text()), plan


@pytest.mark.parametrize("seed", range(PERTURBATIONS))
def test_random_perturbation_is_failed_or_flagged(random_corpus, seed):
    code, res, plan = random_corpus
    recs = {r["file"]: r for r in res["records"]}
    bad = recs[f"records/s{seed}_{BAD}.csv"]
    if bad["status"] == "failed":
        assert f"s{seed}_{BAD}.csv" in bad["error"] and "record" in bad["error"]
    else:
        assert bad["flags"], (plan[seed], bad)
    group = next(g for g in res["groups"] if g["preload"] == f"s{seed}")
    assert bad["index"] not in group["records"] and len(group["records"]) == N_BASE - 1
    assert group["omega1"] == pytest.approx(170.0, rel=5e-3)


# ------------------------------------------------------------------------------- manifests
GOOD_ENTRY = '[[record]]\nfile = "records/0.csv"\nforce_level = 1.0\npreload = 1\n'

#: name -> (manifest text or bytes, "exit2" | "record", pattern)
MANIFEST_CASES = {
    "utf16": (("[campaign]\nname = 'x'\n" + GOOD_ENTRY).encode("utf-16"), "exit2", r"campaign.toml.*UTF-16"),
    "utf16_no_bom": (("[campaign]\nname = 'x'\n" + GOOD_ENTRY).encode("utf-16-le"), "exit2", r"campaign.toml.*UTF-8"),
    "binary": (bytes(range(256)) * 8, "exit2", r"campaign.toml.*UTF-8"),
    "latin1": ("[campaign]\nname = 'caf\xe9'\n".encode("latin-1") + GOOD_ENTRY.encode(), "exit2", r"UTF-8.*line 2"),
    "empty": ("", "exit2", r"campaign.toml.*record"),
    "invalid_toml": ("[campaign\n", "exit2", r"campaign.toml.*not valid TOML"),
    "no_records": ("[campaign]\nname = 'x'\n", "exit2", r"at least one \[\[record\]\]"),
    "record_not_table": ("record = 5\n", "exit2", r"campaign.toml.*record"),
    "record_list_of_int": ("record = [1, 2]\n", "exit2", r"campaign.toml.*'file'"),
    "no_file": ("[[record]]\npreload = 1\n", "exit2", r"record 0.*'file'"),
    "file_int": ("[[record]]\nfile = 5\n", "exit2", r"record 0.*'file'.*5"),
    "file_empty": ('[[record]]\nfile = ""\n', "exit2", r"record 0.*'file'"),
    "file_list": ('[[record]]\nfile = ["a.csv"]\n', "exit2", r"record 0.*'file'"),
    "table_typo": ("[campain]\nname = 'x'\n" + GOOD_ENTRY, "exit2", r"'campain'.*did you mean 'campaign'"),
    "records_typo": ('[[records]]\nfile = "records/0.csv"\n', "exit2", r"'records'.*did you mean 'record'"),
    "key_typo": (GOOD_ENTRY + 'frequncy_hz = 26.0\n', "exit2", r"record 0.*'frequncy_hz'.*'frequency_hz'"),
    "key_typo_preload": (GOOD_ENTRY.replace("preload", "prelaod"), "exit2", r"'prelaod'.*'preload'"),
    "key_typo_force": (GOOD_ENTRY.replace("force_level", "forcelevel"), "exit2", r"'forcelevel'.*'force_level'"),
    "coordinates_typo": ("[campaign]\ncoordinate = 'modal'\n" + GOOD_ENTRY, "exit2", r"'coordinate'.*'coordinates'"),
    "coordinates_bad": ("[campaign]\ncoordinates = 'polar'\n" + GOOD_ENTRY, "exit2", r"coordinates.*polar"),
    "name_int": ("[campaign]\nname = 5\n" + GOOD_ENTRY, "exit2", r"name"),
    "campaign_not_table": ("campaign = 5\n" + GOOD_ENTRY, "exit2", r"\[campaign\]"),
    "physical_no_structure": ("[campaign]\ncoordinates = 'physical'\n" + GOOD_ENTRY, "exit2", r"\[structure\]"),
    "structure_typo": ("[campaign]\ncoordinates = 'physical'\n[structure]\nmodel = 'seed-bolted-beam'\nsensor = {}\n"
                       + GOOD_ENTRY, "exit2", r"sensor.*'sensors'"),
    "structure_huge": ("[campaign]\ncoordinates = 'physical'\n[structure]\nmodel = 'seed-bolted-beam'\n"
                       "force_column = 'force'\nsensors = { accel = 0.3 }\nbeam = { n_elements = 200000 }\n"
                       + GOOD_ENTRY, "exit2", r"n_elements.*at most"),
    "structure_file_outside": ("[campaign]\ncoordinates = 'physical'\n[structure.120]\nfile = '../s.toml'\n"
                               + GOOD_ENTRY, "exit2", r"structure\.120.*leaves"),
    "structure_file_missing": ("[campaign]\ncoordinates = 'physical'\n[structure.120]\nfile = 'nope.toml'\n"
                               + GOOD_ENTRY, "exit2", r"nope.toml.*not found"),
    "preload_nan": (GOOD_ENTRY.replace("preload = 1", "preload = nan"), "record", r"preload must be finite"),
    "preload_inf": (GOOD_ENTRY.replace("preload = 1", "preload = inf"), "record", r"preload must be finite"),
    "preload_list": (GOOD_ENTRY.replace("preload = 1", "preload = [1, 2]"), "record", r"preload.*list"),
    "preload_table": (GOOD_ENTRY.replace("preload = 1", "preload = { a = 1 }"), "record", r"preload.*dict"),
    "preload_bool": (GOOD_ENTRY.replace("preload = 1", "preload = true"), "record", r"preload.*bool"),
    "preload_long": (GOOD_ENTRY.replace("preload = 1", "preload = '" + "x" * 300 + "'"), "record",
                     r"preload.*1 to 200 characters"),
    "force_level_list": (GOOD_ENTRY.replace("force_level = 1.0", "force_level = [1, 2]"), "record",
                         r"force_level.*list"),
    "force_level_table": (GOOD_ENTRY.replace("force_level = 1.0", "force_level = { F = 1 }"), "record",
                          r"force_level.*dict"),
    "frequency_text": (GOOD_ENTRY + "frequency_hz = 'abc'\n", "record", r"frequency_hz must be a number"),
    "frequency_negative": (GOOD_ENTRY + "frequency_hz = -26.0\n", "record", r"frequency_hz must be positive"),
    "frequency_zero": (GOOD_ENTRY + "frequency_hz = 0.0\n", "record", r"frequency_hz must be positive"),
    "frequency_nan": (GOOD_ENTRY + "frequency_hz = nan\n", "record", r"frequency_hz must be finite"),
    "excitation_bad": (GOOD_ENTRY + "excitation = 'chirp'\n", "record", r"excitation must be one of"),
    "multisine_no_period": (GOOD_ENTRY + "excitation = 'multisine'\n", "record", r"needs period_s"),
    "period_negative": (GOOD_ENTRY + "excitation = 'multisine'\nperiod_s = -1.0\n", "record", r"period_s"),
    "period_for_sine": (GOOD_ENTRY + "period_s = 1.0\n", "record", r"period_s"),
    "path_parent": (GOOD_ENTRY.replace("records/0.csv", "../outside.csv"), "record", r"leaves the campaign folder"),
    "path_absolute": (GOOD_ENTRY.replace("records/0.csv", "/etc/passwd"), "record", r"leaves the campaign folder"),
    "path_missing": (GOOD_ENTRY.replace("records/0.csv", "records/nope.csv"), "record", r"not found"),
    "path_folder": (GOOD_ENTRY.replace("records/0.csv", "records"), "record", r"got a folder"),
    "duplicate": (GOOD_ENTRY + GOOD_ENTRY.replace("preload = 1", "preload = 2"), "record", r"same file as record 0"),
    "unknown_format": (GOOD_ENTRY.replace("records/0.csv", "records/0.xlsx"), "record", r"unknown record format"),
}


@pytest.fixture(scope="module")
def manifest_base(base, tmp_path_factory):
    folder = tmp_path_factory.mktemp("manifest-records")
    for i in range(3):
        rec = base[i]
        write_csv_record(folder / f"records/{i}.csv", rec.time, dict(rec.channels))
    (folder / "records/0.xlsx").write_bytes(b"PK\x03\x04")
    return folder


@pytest.mark.parametrize("name", list(MANIFEST_CASES))
def test_manifest_corpus(manifest_base, tmp_path, capsys, name):
    text, outcome, pattern = MANIFEST_CASES[name]
    camp = tmp_path / "camp"
    shutil.copytree(manifest_base, camp)
    extra = ('[[record]]\nfile = "records/1.csv"\nforce_level = 1.0\npreload = 1\n'
             '[[record]]\nfile = "records/2.csv"\nforce_level = 1.0\npreload = 1\n')
    data = text if isinstance(text, bytes) else (text + "\n" + extra if outcome == "record" else text).encode()
    (camp / "campaign.toml").write_bytes(data)
    out = tmp_path / "out"
    code, err = _run(["identify", camp, "--out", out, "--quiet", "--no-figures"], capsys)
    if outcome == "exit2":
        assert code == 2, (name, err)
        assert re.search(pattern, err), (name, err)
        assert "campaign.toml" in err or str(camp) in err
        assert not out.exists()  # refused before any work
    else:
        assert code == 1, (name, err)
        res = json.loads((out / "results.json").read_text())
        failed = [r for r in res["records"] if r["status"] == "failed"]
        assert len(failed) == 1 and re.search(pattern, failed[0]["error"]), (name, failed)
        assert f"[record {failed[0]['index']}]" in failed[0]["error"]
        assert sum(r["status"] == "ok" for r in res["records"]) == len(res["records"]) - 1


def test_too_many_records_is_refused_before_work(tmp_path, capsys, monkeypatch):
    import jointid.io.campaign as campaign

    monkeypatch.setattr(campaign, "MAX_RECORDS", 5)
    entries = [{"file": f"r{i}.csv", "preload": 1, "force_level": 1} for i in range(6)]
    write_campaign(tmp_path / "c", "many", entries)
    code, err = _run(["identify", tmp_path / "c", "--out", tmp_path / "o", "--quiet"], capsys)
    assert code == 2 and "6 records exceed the limit of 5" in err


def test_campaign_path_problems(tmp_path, capsys):
    (tmp_path / "file.txt").write_text("x")
    for path, pattern in ((tmp_path / "file.txt", "got a file"), (tmp_path / "nope", "campaign.toml.*not found")):
        code, err = _run(["identify", path, "--out", tmp_path / "o"], capsys)
        assert code == 2 and re.search(pattern, err), err
    (tmp_path / "d" / "campaign.toml").mkdir(parents=True)
    code, err = _run(["identify", tmp_path / "d", "--out", tmp_path / "o"], capsys)
    assert code == 2 and "got a folder" in err


# --------------------------------------------------------------------------------- imports
IMPORT_CASES = {
    "channels_text": ('[[record]]\nfile = "src.csv"\nchannels = "force"\n', r"channels must be a table"),
    "channels_int_value": ('[[record]]\nfile = "src.csv"\nchannels = { force = 5 }\n', r"channels.force"),
    "default_channels_text": ('[import]\nchannels = "force"\n[[record]]\nfile = "src.csv"\n', r"channels must be"),
    "file_int": ('[[record]]\nfile = 5\nchannels = { force = "F", accel = "A" }\n', r"record 0.*'file'.*5"),
    "no_file": ('[[record]]\nchannels = { force = "F" }\n', r"record 0.*needs 'file'"),
    "source_not_list": ('[[record]]\nsource = 5\n', r"record 0.*source"),
    "source_typo": ('[[record]]\n[[record.source]]\nfile = "src.csv"\nchanels = { force = "F" }\n',
                    r"'chanels'.*'channels'"),
    "record_typo": ('[[record]]\nfile = "src.csv"\nchannels = { force = "F", accel = "A" }\npreloads = 1\n',
                    r"'preloads'.*'preload'"),
    "table_typo": ('[imports]\nfs = 1.0\n[[record]]\nfile = "src.csv"\n', r"'imports'.*'import'"),
    "import_typo": ('[import]\nfss = 1.0\n[[record]]\nfile = "src.csv"\n', r"'fss'.*'fs'"),
    "fs_negative": ('[import]\nfs = -1.0\n[[record]]\nfile = "src.csv"\nchannels = { force = "F" }\n', r"fs must"),
    "fs_nan": ('[import]\nfs = nan\n[[record]]\nfile = "src.csv"\nchannels = { force = "F" }\n', r"fs must be finite"),
    "coordinates_bad": ('[campaign]\ncoordinates = "polar"\n[[record]]\nfile = "src.csv"\n'
                        'channels = { force = "F" }\n', r"coordinates"),
    "no_records": ('[campaign]\nname = "x"\n', r"at least one \[\[record\]\]"),
    "preload_nan": ('[[record]]\nfile = "src.csv"\nchannels = { force = "F", accel = "A" }\npreload = nan\n',
                    r"preload must be finite"),
    "frequency_text": ('[[record]]\nfile = "src.csv"\nchannels = { force = "F", accel = "A" }\nfrequency_hz = "x"\n',
                       r"frequency_hz"),
    "data_folder_missing": ('[import]\ndata_folder = "nope"\n[[record]]\nfile = "src.csv"\n'
                            'channels = { force = "F" }\n', r"data_folder.*not a folder"),
    "path_parent": ('[[record]]\nfile = "../src.csv"\nchannels = { force = "F", accel = "A" }\n',
                    r"leaves the data folder"),
    "path_absolute": ('[[record]]\nfile = "/etc/hostname"\nchannels = { force = "F", accel = "A" }\n',
                      r"leaves the data folder"),
    "missing_file": ('[[record]]\nfile = "nope.csv"\nchannels = { force = "F", accel = "A" }\n', r"not found"),
    "missing_channel": ('[[record]]\nfile = "src.csv"\nchannels = { force = "F", accel = "B" }\n',
                        r"channel 'B'.*missing column"),
    "utf16_source": ('[[record]]\nfile = "src16.csv"\nchannels = { force = "F", accel = "A" }\n', r"UTF-8.*UTF-16"),
    "binary_source": ('[[record]]\nfile = "bin.csv"\nchannels = { force = "F", accel = "A" }\n', r"UTF-8"),
    "uneven_source": ('[[record]]\nfile = "uneven.csv"\nchannels = { force = "F", accel = "A" }\n', r"uniform"),
    "unknown_format": ('[[record]]\nfile = "src.xlsx"\nchannels = { force = "F", accel = "A" }\n', r"unknown format"),
    "utf16_description": (None, r"UTF-8.*UTF-16"),
}


def _import_folder(folder):
    t = np.arange(2000) / 1000.0
    src = "time,F,A\n" + "".join(f"{x!r},{math.sin(60 * x)!r},{math.cos(60 * x)!r}\n" for x in t.tolist())
    (folder / "src.csv").write_text(src)
    (folder / "src16.csv").write_text(src, encoding="utf-16")
    (folder / "bin.csv").write_bytes(np.random.default_rng(0).bytes(3000))
    (folder / "src.xlsx").write_bytes(b"PK\x03\x04")
    t2 = t.copy()
    t2[500:] += 0.05e-3  # 5 % of a step: beyond the text tolerance
    (folder / "uneven.csv").write_text("time,F,A\n" + "".join(f"{x!r},{math.sin(60 * x)!r},1.0\n" for x in t2.tolist()))


@pytest.mark.parametrize("name", list(IMPORT_CASES))
def test_import_corpus(tmp_path, capsys, name):
    text, pattern = IMPORT_CASES[name]
    folder = tmp_path / "lab" / "exports"
    folder.mkdir(parents=True)
    _import_folder(folder)
    (tmp_path / "lab" / "src.csv").write_text((folder / "src.csv").read_text())
    desc = folder / "d.toml"
    if text is None:
        desc.write_text('[[record]]\nfile = "src.csv"\nchannels = { force = "F", accel = "A" }\n', encoding="utf-16")
    else:
        desc.write_text(text)
    out = tmp_path / "camp"
    code, err = _run(["import", desc, "--out", out], capsys)
    assert code == 2, (name, err)  # a single record that cannot be imported: nothing to write
    assert re.search(pattern, err), (name, err)
    assert "d.toml" in err or "src" in err or "nope" in err or "bin" in err or "uneven" in err
    assert not (out / "campaign.toml").exists()


def test_import_time_tolerance_is_the_campaigns(tmp_path, capsys):
    """Time stamps printed with few digits: accepted by import as by identify, written uniform."""
    t = np.arange(3000) / 1000.0
    rows = "".join(f"{x:.4f},{np.sin(170 * x):.9f},{-170**2 * np.sin(170 * x) / (170**2 - 160**2):.9f}\n"
                   for x in t + 0.0001234)
    (tmp_path / "src.csv").write_text("time,F,A\n" + rows)
    (tmp_path / "d.toml").write_text('[import]\nchannels = { force = "F", accel = "A" }\n'
                                     '[[record]]\nfile = "src.csv"\npreload = 1\nforce_level = 1\n')
    code, err = _run(["import", tmp_path / "d.toml", "--out", tmp_path / "c"], capsys)
    assert code == 0, err
    rec = read_record(load_campaign(tmp_path / "c").records[0])
    assert np.ptp(np.diff(rec.time)) < 1e-12
    # the same file as a campaign record: identify accepts it too
    write_campaign(tmp_path / "c2", "x", [{"file": "src.csv", "preload": 1, "force_level": 1}])
    (tmp_path / "c2" / "src.csv").write_text("time,force,accel\n" + rows)
    assert read_record(load_campaign(tmp_path / "c2").records[0]).time.size == 3000


# ------------------------------------------------------------------------------- structures
STRUCTURE_CASES = {
    "n_elements_huge": ("beam = { n_elements = 200000 }", r"n_elements.*at most 2000"),
    "n_elements_negative": ("beam = { n_elements = -1 }", r"n_elements"),
    "n_elements_float": ("beam = { n_elements = 2.5 }", r"n_elements"),
    "n_elements_text": ("beam = { n_elements = 'many' }", r"n_elements"),
    "beam_key_typo": ("beam = { lenght = 0.5 }", r"lenght.*'length'"),
    "top_key_typo": ("sensor = { accel = 0.3 }", r"'sensor'.*'sensors'"),
    "model_unknown": ("model = 'steel'", r"model"),
    "sensor_outside": ("sensors = { accel = 9.0 }", r"outside the beam"),
    "sensor_nan": ("sensors = { accel = nan }", r"accel"),
    "sensors_list": ("sensors = [0.3]", r"sensors.*table"),
    "force_position_text": ("force_position = 'tip'", r"force_position"),
    "preload_negative": ("preload = -5", r"preload"),
    "n_modes_zero": ("n_modes = 0", r"n_modes"),
    "basis_too_many": ("basis_modes = 50", r"basis_modes"),
    "joint_typo": ("joint = { k_ww = 1.0 }", r"k_ww"),
}


@pytest.mark.parametrize("name", list(STRUCTURE_CASES))
def test_structure_corpus(tmp_path, capsys, name):
    line, pattern = STRUCTURE_CASES[name]
    table = {"model": "model = 'seed-bolted-beam'", "sensors": "sensors = { accel = 0.3 }"}
    key = line.split("=")[0].strip()
    table[key] = line
    text = "[structure]\n" + "\n".join(v for k, v in table.items()) + "\n"
    (tmp_path / "s.toml").write_text(text)
    code, err = _run(["modal", tmp_path / "s.toml"], capsys)
    assert code == 2, (name, err)
    assert re.search(pattern, err), (name, err)
    assert "s.toml" in err


# ------------------------------------------------------------------------------ CLI values
CLI_CASES = {
    "harmonics_zero": (["--harmonics", "0"], "--harmonics"),
    "harmonics_negative": (["--harmonics", "-3"], "--harmonics"),
    "harmonics_text": (["--harmonics", "five"], "--harmonics"),
    "harmonics_huge": (["--harmonics", "100000"], "--harmonics"),
    "damping_order_negative": (["--damping-order", "-1"], "--damping-order"),
    "damping_order_huge": (["--damping-order", "99"], "--damping-order"),
    "weighting_bad": (["--weighting", "equal"], "--weighting"),
    "force_gain_bad": (["--force-gain", "maybe"], "--force-gain"),
    "jobs_text": (["--jobs", "two"], "--jobs"),
    "no_out": (None, "--out"),
}


@pytest.mark.parametrize("name", list(CLI_CASES))
def test_cli_values_are_refused_by_the_parser(tmp_path, capsys, name):
    extra, option = CLI_CASES[name]
    argv = ["identify", str(tmp_path)] + (["--out", str(tmp_path / "o")] + extra if extra else [])
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and option in err and "Traceback" not in err


CLI_LATE_CASES = {
    "modes_zero": (["modal", "{s}", "--modes", "0"], r"--modes"),
    "order_negative": (["modal", "{s}", "--order", "-1"], r"--order"),
    "coherence_nan": (["modal", "{s}", "--min-coherence", "nan"], r"--min-coherence"),
    "frequencies_one": (["example", "--frequencies", "1", "--out", "{o}"], r"--frequencies"),
}


@pytest.mark.parametrize("name", list(CLI_LATE_CASES))
def test_cli_values_of_other_commands(tmp_path, capsys, name):
    argv, option = CLI_LATE_CASES[name]
    argv = [a.format(s=tmp_path / "s.toml", o=tmp_path / "o") for a in argv]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and re.search(option, err)


def test_cli_values_checked_by_the_api(manifest_base, tmp_path, capsys):
    camp = tmp_path / "camp"
    shutil.copytree(manifest_base, camp)
    write_campaign(camp, "x", [{"file": f"records/{i}.csv", "preload": 1, "force_level": 1} for i in range(3)])
    for extra, pattern in ((["--jobs", "-1"], r"jobs must be an integer"),
                           (["--terms", "q + foo"], r"foo"),
                           (["--terms", ""], r"term"),
                           # a library without the linear stiffness has no omega1 to report
                           (["--terms", "q'"], r"no linear stiffness term 'q'"),
                           (["--terms", "q' + q^3"], r"no linear stiffness term 'q'"),
                           (["--terms", "sign(q')"], r"no linear stiffness term 'q'")):
        code, err = _run(["identify", camp, "--out", tmp_path / "o", "--quiet"] + extra, capsys)
        assert code == 2 and re.search(pattern, err), (extra, err)
        assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------- output folders
def test_out_refused_before_the_work(manifest_base, tmp_path, capsys, monkeypatch):
    import jointid.app.workflow as workflow

    def never(*a, **k):  # pragma: no cover - the point is that it is not reached
        raise AssertionError("the work started")

    monkeypatch.setattr(workflow, "identify_campaign", never)
    (tmp_path / "file").write_text("x")
    cases = {tmp_path / "file": "existing file", tmp_path / "file" / "below": "which is a file",
             manifest_base: "is the input"}
    for out, pattern in cases.items():
        code, err = _run(["identify", manifest_base, "--out", out], capsys)
        assert code == 2 and pattern in err and str(out) in err, err
    for cmd in (["simulate", tmp_path / "cfg.toml"], ["import", tmp_path / "d.toml"], ["demo"], ["example"]):
        code, err = _run(cmd + ["--out", tmp_path / "file"], capsys)
        assert code == 2 and "existing file" in err, (cmd, err)


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root writes into read-only folders")
def test_out_read_only_is_refused(manifest_base, tmp_path, capsys):  # pragma: no cover - needs a non-root user
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        code, err = _run(["identify", manifest_base, "--out", ro / "o"], capsys)
        assert code == 2 and "not writable" in err
    finally:
        ro.chmod(0o700)


def test_out_read_only_is_refused_by_access_check(manifest_base, tmp_path, capsys, monkeypatch):
    """Without root's override: the access check itself (os.access) refuses."""
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if "ro" in str(p) else real(p, mode))
    (tmp_path / "ro").mkdir()
    code, err = _run(["identify", manifest_base, "--out", tmp_path / "ro" / "o"], capsys)
    assert code == 2 and "not writable" in err


def _set_is_consistent(out):
    run_id = (out / ".jointid-run").read_text().splitlines()[0]  # the marker's first line
    res = json.loads((out / "results.json").read_text())
    assert res["run_id"] == run_id
    assert run_id in (out / "report.txt").read_text()
    assert run_id in (out / "report.html").read_text()
    assert not list(out.parent.glob(f".{out.name}.*.tmp"))
    return run_id, res


def test_output_set_replaced_whole_and_stale_files_removed(base, tmp_path, capsys):
    camp = tmp_path / "camp"
    entries = []
    for i, rec in enumerate(base):
        write_csv_record(camp / f"r{i}.csv", rec.time, dict(rec.channels))
        entries.append({"file": f"r{i}.csv", "preload": "=cmd|' /C calc'!A0" if i < 5 else "$x^2$ /../" + "y" * 180,
                        "force_level": 1.0})
    write_campaign(camp, "labels", entries)
    out = tmp_path / "out"
    code, err = _run(["identify", camp, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    first, res = _set_is_consistent(out)
    figures = sorted(p.name for p in (out / "figures").iterdir())
    assert figures and all(len(n) < 120 and re.fullmatch(r"[A-Za-z0-9._+-]+", n) for n in figures)
    rows = (out / "records.csv").read_text().splitlines()
    assert not any(cell.startswith("=") for row in rows for cell in row.split(","))
    # second run with one group only: the figures of the other group are gone
    write_campaign(camp, "labels", entries[:5])
    code, err = _run(["identify", camp, "--out", out, "--quiet"], capsys)
    second, res = _set_is_consistent(out)
    assert second != first
    assert len(list((out / "figures").iterdir())) < len(figures)
    assert not any("y" * 30 in p.name for p in (out / "figures").iterdir())


def _wrapped_interrupt():
    """A Ctrl-C as Python reports it when it arrives inside a class body's ``__set_name__`` (an import)."""
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt as exc:
        raise RuntimeError("Error calling __set_name__ on '_lazy' instance 'x' in 'Y'") from exc


@pytest.mark.parametrize("wrapped", [False, True])
def test_interrupted_write_leaves_the_previous_set(base, tmp_path, capsys, monkeypatch, wrapped):
    import jointid.report.output as output

    camp = tmp_path / "camp"
    for i, rec in enumerate(base[:5]):
        write_csv_record(camp / f"r{i}.csv", rec.time, dict(rec.channels))
    write_campaign(camp, "x", [{"file": f"r{i}.csv", "preload": 1, "force_level": 1} for i in range(5)])
    out = tmp_path / "out"
    assert _run(["identify", camp, "--out", out, "--quiet", "--no-figures"], capsys)[0] == 0
    before, _ = _set_is_consistent(out)
    real = output.write_csv
    calls = []

    def interrupted(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            if wrapped:
                _wrapped_interrupt()
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(output, "write_csv", interrupted)
    code, err = _run(["identify", camp, "--out", out, "--quiet", "--no-figures"], capsys)
    assert code == 130 and "interrupted" in err and len(err.strip().splitlines()) == 1
    after, _ = _set_is_consistent(out)
    assert after == before


def test_leftover_of_a_killed_run_is_removed(base, tmp_path, capsys):
    camp = tmp_path / "camp"
    for i, rec in enumerate(base[:5]):
        write_csv_record(camp / f"r{i}.csv", rec.time, dict(rec.channels))
    write_campaign(camp, "x", [{"file": f"r{i}.csv", "preload": 1, "force_level": 1} for i in range(5)])
    out = tmp_path / "out"
    dead = tmp_path / ".out.new.999999999-20260101T000000Z-abcdef.tmp"
    dead.mkdir()
    (dead / "results.json").write_text("{}")
    assert _run(["identify", camp, "--out", out, "--quiet", "--no-figures"], capsys)[0] == 0
    assert not dead.exists()
    _set_is_consistent(out)


def test_exit_codes_documented_and_reached(manifest_base, tmp_path, capsys):
    import jointid.cli as cli

    readme = (cli.__file__.rsplit("src", 1)[0] + "README.md")
    text = open(readme, encoding="utf-8").read()
    line = next(ln for ln in text.splitlines() if "Exit codes" in ln)
    for code in ("0", "1", "2", "3", "130"):
        assert re.search(rf"\b{code}\b", line), line
    for code in ("0", "1", "2", "3", "130"):
        assert re.search(rf"\b{code}\b", cli.__doc__)
    # 0 (clean), 2 (bad input): above; 1: the corpora; 130: interrupt; 3: an internal error
    camp = tmp_path / "camp"
    shutil.copytree(manifest_base, camp)
    write_campaign(camp, "x", [{"file": f"records/{i}.csv", "preload": 1, "force_level": 1} for i in range(3)])
    assert _run(["identify", camp, "--out", tmp_path / "o", "--quiet", "--no-figures"], capsys)[0] == 0
    import jointid.app.workflow as workflow

    def boom(*a, **k):
        raise ZeroDivisionError("a bug")

    orig = workflow.identify_campaign
    workflow.identify_campaign = boom
    try:
        code = main(["identify", str(camp), "--out", str(tmp_path / "o2"), "--quiet"])
    finally:
        workflow.identify_campaign = orig
    err = capsys.readouterr().err
    assert code == 3 and "internal error" in err


def test_toml_writer_round_trips_hostile_labels(tmp_path):
    labels = ["=1+1", 'quote " and \\ backslash', "$x$", "tab\tnew\nline", "ünïcödé", "#comment"]
    write_campaign(tmp_path, "x", [{"file": f"r{i}.csv", "preload": p, "force_level": 1}
                                   for i, p in enumerate(labels)])
    import tomllib

    written = tomllib.loads((tmp_path / "campaign.toml").read_text(encoding="utf-8"))
    assert [r["preload"] for r in written["record"]] == labels  # the writer escapes every label
    camp = load_campaign(tmp_path)
    assert [r.preload for r in camp.records if r.error is None] == [p for p in labels if "\t" not in p]
    # control characters print as another label (or break the report): that record is refused
    assert "preload" in camp.records[3].error and "character" in camp.records[3].error
    assert toml_dumps({"a": {"b": 1}})  # tables write
