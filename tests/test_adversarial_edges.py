"""Adversarial cases at the edges: numbers that used to come out silently wrong.

Each case ends in exit 2 with a message naming the cause, or in a flagged record (with the
numbers that triggered the flag); never a traceback and never a confident wrong number.
Cases: channel delays (given and estimated), units of the wrong dimension on import,
broadband and ring-down records that cannot carry what they claim, HDF5 datasets of the
wrong kind, and user text in figure titles.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign
from jointid.cli import main
from jointid.errors import IdentificationError

SIM = {
    "campaign": {"name": "edges"},
    "model": [{"preload": "p", "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
               "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
    "excitation": {"force_levels": [0.5, 1.0], "omega_start": 160.0, "omega_stop": 180.0, "n_frequencies": 9},
    "acquisition": {"fs": 2000.0, "periods": 20.0, "noise": 0.01, "seed": 1, "write_frequency": False,
                    "n_harmonics": 5},
}


@pytest.fixture(scope="module")
def camp(tmp_path_factory):
    """A clean simulated stepped-sine campaign with no channel delay (c from 0.08 up, k3 = 5e6)."""
    return simulate_campaign(load_simulation_config(SIM), tmp_path_factory.mktemp("edges"))


def _identify(folder, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify_campaign(folder, repredict=False, **kw)


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    return code, out, err


# ------------------------------------------------------------------------------ channel delay
@pytest.mark.parametrize("gain", ["known", "unknown"])
def test_given_delay_that_turns_damping_negative_is_flagged(camp, gain):
    res = _identify(camp, channel_delay=0.001 if gain == "known" else 0.0005, force_gain=gain)
    neg = [r for r in res.records if r.ok and r.fit.c < 0]
    assert neg, "the wrong delay no longer makes damping negative: the case is gone"
    # every negative damping is a flag, not a result, and the delay is flagged on every record
    assert all(any(f.name == "negative_damping" for f in r.flags) for r in neg)
    assert all(any(f.name == "channel_delay_implausible" for f in r.flags) for r in res.records if r.ok)
    assert all(g.pooled is None for g in res.groups)  # no pooled numbers from flagged records
    assert res.summary()["flagged"]


def test_given_delay_is_checked_by_input_power_when_the_terms_have_no_viscous_term(camp):
    res = _identify(camp, channel_delay=0.001, terms="q - q^3 + |q'|q'")
    neg = [r for r in res.records if any(f.name == "negative_damping" for f in r.flags)]
    assert neg and all(f.values["input_power"] < 0 for r in neg for f in r.flags if f.name == "negative_damping")
    assert all(any(f.name == "channel_delay_implausible" for f in r.flags) for r in res.records if r.ok)


@pytest.mark.parametrize("delay", ["-0.037", "1e9", "nan"])
def test_given_delay_longer_than_a_fraction_of_the_period_is_refused(camp, tmp_path, capsys, delay):
    code, _, err = _run(["identify", camp, "--out", tmp_path / "r", "--channel-delay", delay, "--quiet",
                         "--no-reprediction", "--no-figures"], capsys)
    assert code == 2 and "delay" in err and "s" in err, err
    assert not (tmp_path / "r" / "results.json").exists()


def test_unresolved_estimate_from_an_inadequate_fit_is_not_applied(camp):
    # a constant damping law cannot follow c(q_max) growing 10-fold: reduced chi2 ~ 4e4, delay ~ 0 +- 1e-4 s
    res = _identify(camp, channel_delay="estimate", damping_order=0)
    assert res.channel_delay is None
    assert "reduced chi2" in res.channel_delay_error and "not resolved" in res.channel_delay_error
    raw = _identify(camp, damping_order=0)
    for a, b in zip(res.records, raw.records):
        assert a.fit.c == b.fit.c  # the records were not moved by an estimate their errors do not carry


def test_estimated_delay_uncertainty_is_carried_into_c(camp):
    res = _identify(camp, channel_delay="estimate")
    d = res.channel_delay
    assert d is not None and d.stderr_s > 0
    raw = _identify(camp)
    far = [i for i, r in enumerate(res.records) if abs(r.fit.omega1**2 - r.signals.omega**2) > 1e3]
    assert far
    for i in far:
        extra = d.stderr_s * abs(res.records[i].fit.omega1**2 - res.records[i].signals.omega**2)
        added = res.records[i].fit.c_stderr ** 2 - raw.records[i].fit.c_stderr ** 2
        assert added == pytest.approx(extra**2, rel=0.1)


def test_check_delay_plausible_messages():
    from jointid.identify.delay import check_delay_plausible

    check_delay_plausible(1e-3, [20.0, 30.0], [1.0])
    with pytest.raises(IdentificationError, match="periods of the highest dwell frequency 30"):
        check_delay_plausible(0.01, [20.0, 30.0], [1.0])
    with pytest.raises(IdentificationError, match="of the shortest record"):
        check_delay_plausible(0.01, [1.0], [0.05])


# ------------------------------------------------------------------------------ import units
def _lab_csv(folder):
    t = np.arange(2048) / 512.0
    rows = np.column_stack([t, np.sin(2 * np.pi * 20 * t), 0.5 * np.cos(2 * np.pi * 20 * t)])
    np.savetxt(folder / "lab.csv", rows, delimiter=",", header="time,Load,Acc", comments="")


@pytest.mark.parametrize("column, unit, kind", [("accel", "kN", "force"), ("force", "ms", "time"),
                                                ("accel", "mm/s", "velocity"),
                                                ("force", "deg", "angle")])
def test_import_refuses_a_unit_of_the_wrong_dimension(tmp_path, capsys, column, unit, kind):
    _lab_csv(tmp_path)
    chans = {"force": '"Load"', "accel": '"Acc"'}
    chans[column] = f'{{ channel = {chans[column]}, unit = "{unit}" }}'
    (tmp_path / "d.toml").write_text(
        "[import]\nchannels = { " + ", ".join(f"{k} = {v}" for k, v in chans.items()) + " }\n"
        '[[record]]\nfile = "lab.csv"\nfrequency_hz = 20.0\n')
    code, _, err = _run(["import", tmp_path / "d.toml", "--out", tmp_path / "c"], capsys)
    assert code == 2, err
    assert "d.toml" in err and f"channels.{column}" in err and repr(unit) in err and kind in err, err
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize("column, unit", [("force", "V"), ("force", "kN"), ("accel", "g"), ("time", "ms"),
                                          ("accel_b", "mm/s^2"), ("sensor7", "g")])
def test_import_takes_units_of_the_right_dimension(tmp_path, column, unit):
    from jointid.io.units import check_column_unit

    check_column_unit(column, unit, "d.toml: ")


@pytest.mark.parametrize("fmt", ["csv", "h5"])
def test_import_refuses_a_time_column_inside_the_column_map(tmp_path, capsys, fmt):
    import h5py

    t = np.arange(2048) / 512.0
    F, a = np.sin(2 * np.pi * 20 * t), np.cos(2 * np.pi * 20 * t)
    if fmt == "csv":
        np.savetxt(tmp_path / "d.csv", np.column_stack([t, F, a]), delimiter=",", header="t,F,A", comments="")
    else:
        with h5py.File(tmp_path / "d.h5", "w") as h5:
            h5["t"], h5["F"], h5["A"] = t, F, a
    (tmp_path / "d.toml").write_text(f'[import]\nfs = 512.0\nchannels = {{ time = "t", force = "F", accel = "A" }}\n'
                                     f'[[record]]\nfile = "d.{fmt}"\nfrequency_hz = 20.0\n')
    code, _, err = _run(["import", tmp_path / "d.toml", "--out", tmp_path / "c"], capsys)
    assert code == 2 and "channels.time" in err and "time =" in err, err


# ------------------------------------------------------------------------------ HDF5 datasets
def _bad_h5(path, kind, layout="generic"):
    import h5py

    t = np.arange(2048) / 512.0
    with h5py.File(path, "w") as h5:
        g = h5 if layout == "generic" else h5.create_group("record")
        c = g if layout == "generic" else g.create_group("channels")
        if layout != "generic":
            g.attrs["fs"] = 512.0
        c["accel"] = np.cos(2 * np.pi * 20 * t)
        if kind == "text":
            c["force"] = np.array([b"1.0"] * t.size)
        elif kind == "compound":
            c["force"] = np.zeros(t.size, dtype=[("a", "f8"), ("b", "i4")])
        elif kind == "complex":
            c["force"] = np.exp(1j * t)
        elif kind == "vlen_text":
            c.create_dataset("force", data=np.array(["1.0"] * t.size, dtype=object), dtype=h5py.string_dtype())
        elif kind == "empty":
            c.create_dataset("force", data=h5py.Empty("f8"))
        else:  # a compressed dataset of 1e11 values stored in a few kilobytes (never written)
            c.create_dataset("force", shape=(100_000_000_000,), dtype="f8", compression="gzip", chunks=(1 << 20,))


@pytest.mark.parametrize("kind, words", [("text", "text"), ("compound", "compound"), ("complex", "complex"),
                                         ("vlen_text", "text"), ("empty", "empty"), ("huge", "more than the limit")])
def test_import_of_hdf5_datasets_of_the_wrong_kind(tmp_path, capsys, kind, words):
    _bad_h5(tmp_path / "d.h5", kind)
    (tmp_path / "d.toml").write_text('[import]\nfs = 512.0\nchannels = { force = "force", accel = "accel" }\n'
                                     '[[record]]\nfile = "d.h5"\nfrequency_hz = 20.0\n')
    code, _, err = _run(["import", tmp_path / "d.toml", "--out", tmp_path / "c"], capsys)
    assert code == 2 and "d.h5" in err and "'force'" in err and words in err, err


@pytest.mark.parametrize("kind, words", [("text", "text"), ("compound", "compound"), ("huge", "more than the limit")])
def test_jointid_hdf5_record_of_the_wrong_kind(tmp_path, kind, words):
    from jointid.errors import RecordError
    from jointid.io.hdf5 import read_hdf5

    _bad_h5(tmp_path / "r.h5", kind, layout="jointid")
    with pytest.raises(RecordError, match=words):
        read_hdf5(tmp_path / "r.h5", group="record")


# ------------------------------------------------------------------------------ broadband records
BB_FS, BB_N = 256.0, 2048
BB_W1, BB_K3, BB_C = 2 * np.pi * 20.0, 4e5, 2 * 0.02 * 2 * np.pi * 20.0


def _bb_multisine(rng, n_lines=240):
    k = np.arange(1, n_lines + 1)
    X = np.zeros(BB_N // 2 + 1, complex)
    X[k] = np.exp(2j * np.pi * rng.random(k.size))
    u = np.fft.irfft(X, BB_N)
    return 75.0 * u / np.std(u)


def _bb_response(u):
    from jointid.identify.broadband import simulate_response
    from jointid.identify.terms import library

    q, _ = simulate_response(library("q + -q^3 + q'"), np.array([BB_W1**2, BB_K3, BB_C]), 1.0, u, BB_FS)
    return q


def _bb_campaign(folder, records):
    """``records``: (name, excitation, u, q, period_s or None) -> a broadband campaign folder."""
    from jointid.io.campaign import write_campaign, write_csv_record

    entries = []
    for name, excitation, u, q, period in records:
        write_csv_record(folder / f"{name}.csv", np.arange(u.size) / BB_FS, {"force": u, "displacement": q})
        e = {"file": f"{name}.csv", "preload": 1, "force_level": 1, "excitation": excitation}
        if period is not None:
            e["period_s"] = period
        entries.append(e)
    write_campaign(folder, "broadband edges", entries)
    return folder


def _ms_records(rng, n=3, periods=3):
    out = []
    for i in range(n):
        u = np.tile(_bb_multisine(rng), periods)
        q = _bb_response(u)
        out.append((f"ms_{i}", "multisine", u, q + 1e-4 * np.std(q) * rng.standard_normal(q.size), BB_N / BB_FS))
    return out


def _bb_flags(res):
    (g,) = res.broadband
    return g, {f.name for _, f in g.flags}


def test_clean_multisines_carry_no_flag(tmp_path):
    res = _identify(_bb_campaign(tmp_path, _ms_records(np.random.default_rng(3))), force_gain="known")
    g, names = _bb_flags(res)
    assert not names and g.fit.derived()["f1_hz"][0] == pytest.approx(20.0, rel=1e-3)


def test_multisine_with_the_wrong_period_is_flagged(tmp_path, capsys):
    recs = [(n, e, u, q, 0.7 * p) for n, e, u, q, p in _ms_records(np.random.default_rng(4))]
    folder = _bb_campaign(tmp_path / "c", recs)
    g, names = _bb_flags(_identify(folder))
    assert names == {"multisine_period"} and g.fit is None and not g.estimation
    share = [f.values["non_periodic_share"] for _, f in g.flags]
    assert len(share) == 3 and min(share) > 0.3
    code, out, _ = _run(["identify", folder, "--out", tmp_path / "r", "--no-figures", "--no-reprediction"], capsys)
    assert code == 1  # not a clean run
    s = json.loads((tmp_path / "r" / "results.json").read_text())["broadband"][0]
    assert {f["name"] for f in s["flags"]} == {"multisine_period"} and s["flags"][0]["file"].startswith("ms_")


def test_multisine_period_beyond_the_record_and_plain_sine(tmp_path):
    rng = np.random.default_rng(5)
    recs = _ms_records(rng, n=2)
    u = np.tile(_bb_multisine(rng), 3)
    recs.append(("long", "multisine", u, _bb_response(u), 0.8 * u.size / BB_FS))  # a period and a bit, wrong
    u = np.tile(_bb_multisine(rng), 3)
    recs.append(("longer", "multisine", u, _bb_response(u), 2 * u.size / BB_FS))  # beyond the record
    t = np.arange(3 * BB_N) / BB_FS
    u = 20.0 * np.sin(2 * np.pi * 15.0 * t)
    recs.append(("sine", "multisine", u, _bb_response(u), BB_N / BB_FS))
    g, _ = _bb_flags(_identify(_bb_campaign(tmp_path, recs)))
    by_file = {file: f.name for file, f in g.flags}
    assert by_file["long.csv"] == "multisine_period" and by_file["sine.csv"] == "multisine_lines"
    assert any("longer.csv" in m and "period_s" in m for m in g.failed)
    assert g.estimation == ("ms_0.csv",) and g.held_out[0]["file"] == "ms_1.csv"  # the good ones still used
    assert g.fit.derived()["f1_hz"][0] == pytest.approx(20.0, rel=1e-3)


def test_white_noise_random_records_are_flagged_not_identified(tmp_path, capsys):
    rng = np.random.default_rng(6)
    recs = [(f"noise_{i}", "random", rng.standard_normal(8 * BB_N), rng.standard_normal(8 * BB_N), None)
            for i in range(2)]
    folder = _bb_campaign(tmp_path / "c", recs)
    g, names = _bb_flags(_identify(folder))
    assert names == {"random_coherence"} and g.fit is None
    assert all(f.values["mean_coherence"] < 0.2 for _, f in g.flags)
    code, _, _ = _run(["identify", folder, "--out", tmp_path / "r", "--no-figures", "--no-reprediction"], capsys)
    assert code == 1


def test_negative_damping_of_a_broadband_model_is_a_flag():
    from types import SimpleNamespace

    from jointid.app.broadband_records import model_flags

    fit = SimpleNamespace(derived=lambda: {"zeta": (-0.075, 0.004), "f1_hz": (7.9, 0.1)})
    states = [SimpleNamespace(band=(10.0, 30.0))]
    names = {f.name for f in model_flags(fit, states)}
    assert names == {"negative_damping", "resonance_outside_band"}
    fit = SimpleNamespace(derived=lambda: {"zeta": (0.02, 0.001), "f1_hz": (20.0, 0.01)})
    assert model_flags(fit, states) == []


def test_campaign_mixing_record_types_with_broken_broadband_records(camp, tmp_path, capsys):
    import shutil

    from jointid.io.campaign import write_csv_record

    folder = tmp_path / "mixed"
    shutil.copytree(camp, folder)
    rng = np.random.default_rng(8)
    u = np.tile(_bb_multisine(rng), 3)
    q = _bb_response(u)
    q[100] = np.nan
    write_csv_record(folder / "ms_nan.csv", np.arange(u.size) / BB_FS, {"force": u, "displacement": q})
    write_csv_record(folder / "ms_short.csv", np.arange(BB_N // 2) / BB_FS, {"force": u[:BB_N // 2],
                                                                              "displacement": q[:BB_N // 2]})
    with open(folder / "campaign.toml", "a", encoding="utf-8") as fh:
        for name in ("ms_nan", "ms_short"):
            fh.write(f'\n[[record]]\nfile = "{name}.csv"\npreload = "p"\nforce_level = 9.0\n'
                     f'excitation = "multisine"\nperiod_s = {BB_N / BB_FS}\n')
    code, _, err = _run(["identify", folder, "--out", tmp_path / "r", "--no-figures", "--no-reprediction",
                         "--quiet"], capsys)
    assert code == 1 and "ms_nan.csv" in err and "ms_short.csv" in err, err
    res = json.loads((tmp_path / "r" / "results.json").read_text())
    assert len(res["groups"]) == 2 and all(g["k3"] > 0 for g in res["groups"])  # the stepped sines identified
    (b,) = res["broadband"]
    assert len(b["failed"]) == 2 and b["error"] == "no usable record"


# ------------------------------------------------------------------------------ ring-down records
def _free_decay(c, q0, n=8000, fs=2000.0):
    from scipy.integrate import solve_ivp

    t = np.arange(n) / fs

    def rhs(_, y):
        return [y[1], -c * y[1] - 170.0**2 * y[0] + 5e6 * y[0] ** 3]

    sol = solve_ivp(rhs, (0, t[-1]), [q0, 0.0], t_eval=t, rtol=1e-11, atol=1e-14, method="DOP853")
    return t, -c * sol.y[1] - 170.0**2 * sol.y[0] + 5e6 * sol.y[0] ** 3


@pytest.fixture(scope="module")
def ringdowns(camp, tmp_path_factory):
    """The stepped-sine campaign with one good ring-down and six that are not free decays."""
    import shutil

    from jointid.io.campaign import write_csv_record

    folder = tmp_path_factory.mktemp("rd") / "c"
    shutil.copytree(camp, folder)
    rng = np.random.default_rng(9)
    t, good = _free_decay(0.08, 0.01)
    _, growing = _free_decay(-0.08, 0.002)
    cases = {"good": good, "growing": growing, "steady": 100.0 * np.sin(170.0 * t),
             "noise": rng.standard_normal(t.size), "constant": np.full(t.size, 9.81), "short": good[:600],
             "nan": np.where(np.arange(t.size) == 50, np.nan, good)}
    with open(folder / "campaign.toml", "a", encoding="utf-8") as fh:
        for name, x in cases.items():
            noisy = x + 1e-3 * np.nanstd(x) * rng.standard_normal(x.size) if name != "constant" else x
            write_csv_record(folder / f"rd_{name}.csv", t[:x.size], {"accel": noisy})
            fh.write(f'\n[[record]]\nfile = "rd_{name}.csv"\npreload = "p"\nforce_level = 0.5\n'
                     'excitation = "ringdown"\n')
    return folder


def test_ringdowns_that_are_not_free_decays_give_no_backbone(ringdowns, tmp_path, capsys):
    code, _, err = _run(["identify", ringdowns, "--out", tmp_path / "r", "--no-figures", "--no-reprediction",
                         "--quiet"], capsys)
    assert code == 1  # listed, not a clean run
    bad = ("growing", "steady", "noise", "constant", "short", "nan")
    for name in bad:
        assert f"rd_{name}.csv" in err, err
    assert "rd_good.csv" not in err
    (p,) = json.loads((tmp_path / "r" / "results.json").read_text())["backbones"]["preloads"]
    assert [b["label"] for b in p["ringdown"]] == ["rd_good.csv"]
    errs = {m.split(" [")[0]: m for k, m in p["errors"].items() if k.startswith("record ")}
    assert set(errs) == {f"rd_{n}.csv" for n in bad}, errs
    assert "ringdown_growing" in errs["rd_growing.csv"] and "damping ratio -" in errs["rd_growing.csv"]
    assert "ringdown_no_decay" in errs["rd_steady.csv"]
    assert "ringdown_noise" in errs["rd_noise.csv"]
    assert "ringdown_short" in errs["rd_short.csv"] or "window" in errs["rd_short.csv"]


# ------------------------------------------------------------------------------ user text in figures
MATH = r"$\frac{a$"  # invalid mathtext: matplotlib raises when it parses it


def test_preload_force_level_and_file_names_holding_mathtext(camp, tmp_path, capsys):
    import shutil

    folder = tmp_path / "c"
    shutil.copytree(camp, folder)
    (folder / "$x$").mkdir()
    (folder / "records" / "0000.csv").rename(folder / "$x$" / "r.csv")
    text = (folder / "campaign.toml").read_text(encoding="utf-8")
    text = text.replace('"records/0000.csv"', '"$x$/r.csv"').replace('preload = "p"', 'preload = "$\\\\frac{a$"')
    text = text.replace("force_level = 0.5\n", 'force_level = "$\\\\sqrt{b$"\n')
    (folder / "campaign.toml").write_text(text, encoding="utf-8")
    code, _, err = _run(["identify", folder, "--out", tmp_path / "r", "--figures", "summary", "--no-reprediction",
                         "--quiet"], capsys)
    assert code in (0, 1), err
    res = json.loads((tmp_path / "r" / "results.json").read_text())
    assert res["models"][0]["preload"] == MATH  # the label itself is kept as given
    pngs = sorted(p.name for p in (tmp_path / "r" / "figures").glob("*.png"))
    assert any(n.startswith("adequacy_") for n in pngs), pngs


def test_backbone_figure_with_mathtext_labels():
    import matplotlib

    matplotlib.use("Agg")
    from jointid.identify.backbone import model_backbone
    from jointid.report.backbone_plots import plot_backbones
    from jointid.report.html import figure_to_png

    b = model_backbone("q + -q^3 + q'", [170.0**2, 5e6, 0.08], np.geomspace(1e-4, 1e-2, 5), label=MATH)
    fig, _ = plot_backbones([b], title=f"preload {MATH}")
    assert figure_to_png(fig)[:4] == b"\x89PNG"
