"""The public measured data sets: the numbers of docs/public-data.md, asserted.

The data are read from ``../shared/data`` (``jointid.io.datasets.shared_data_dir``); every
test skips with the reason when a data set is absent.  Nothing is copied or written into
the repository (figures go to ``tmp_path``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from jointid.app import public_data as ex
from jointid.errors import RecordFileNotFoundError
from jointid.io.datasets import shared_data_dir


def _require(*parts):
    try:
        root = shared_data_dir()
    except RecordFileNotFoundError as exc:
        pytest.skip(f"shared data folder absent: {exc}")
    p = root.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"data set file {p} is absent")
    return p


@pytest.fixture(scope="module")
def silverbox_levels():
    _require("silverbox_multilevel_noel", "SNJP_um_full_FNSI_150.mat")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ex.silverbox_multilevel()


def test_silverbox_multilevel_meets_the_goals(silverbox_levels):
    r = silverbox_levels
    table = {row["level_mv"]: row for row in r.table()}
    assert sorted(table) == [5, 20, 50, 100, 150]
    for lv, row in table.items():
        assert abs(row["f1_hz"] / 68.58 - 1) < 0.005, lv  # f_n within 0.5 %
        assert abs(100 * (row["zeta"] - 0.0468)) < 0.3, lv  # damping ratio within 0.3 points
        assert 4e-6 < 1 / row["gain"] < 7e-6  # inertia coefficient of the circuit [V s^2]
    k3k = [table[lv]["k3_over_k"] for lv in (20, 50, 100)]
    assert (max(k3k) - min(k3k)) / abs(np.mean(k3k)) < 0.05  # k3/k equal within 5 %
    assert all(k < 0 for k in k3k)  # hardening: -k3 q^3 with k3 < 0
    # damping rises with level, the low level matches the reference
    z = [table[lv]["zeta"] for lv in (5, 20, 50, 100, 150)]
    assert all(np.diff(z) > 0) and abs(z[0] - 0.0468) < 0.001
    g = r.goals()
    assert g["f1_ok"] and g["zeta_ok"] and g["k3k_ok"]


def test_silverbox_raw_coordinate_matches_reference_polynomial(silverbox_levels):
    """With the output mean kept, k2 and k3 are the raw-coordinate spring coefficients (c1 = -0.256, c2 = 3.98)."""
    for row in silverbox_levels.table():
        if row["level_mv"] >= 20:
            assert row["raw_k2"] == pytest.approx(-0.256, abs=0.01)
            assert -row["raw_k3"] == pytest.approx(3.98, rel=0.03)
    s = silverbox_levels.summary()
    assert s["goals"]["k3k_ok"] and len(s["levels"]) == 5
    assert "goals" in silverbox_levels.report()


def test_silverbox_benchmark_arrow_simulation():
    _require("silverbox", "SNLS80mV.mat")
    r = ex.silverbox_benchmark()
    assert r.fit.n_records == 9
    assert 68.0 < r.fit.f1_hz < 68.7
    assert r.rms_test_mv < 0.5  # measured 0.395 mV on samples 86..40086
    assert r.rms_validation_mv < 0.4  # held-out multisine: 0.309 mV
    assert r.rms_test_linear_mv > 10 * r.rms_test_mv  # the cubic spring matters
    assert r.y_rms_test_mv == pytest.approx(53.0, abs=1.0)
    s = r.summary()
    assert s["published"] and s["rms_test_mv"] == r.rms_test_mv


def test_unesp_dwells_gain_chain():
    _require("unesp_bolted_beam", "T5Nm", "Sine", "Sine_20Hz", "TimeShaker.mat")
    r = ex.unesp_sine_dwells()
    g = r.goals()
    assert g["omega1_ok"] and g["omega1_spread"] < 0.01  # per-dwell omega1 within 1 % (0.60 %)
    assert g["softening_ok"] and g["k3_over_m"] > 0  # softening, > 3 standard errors
    assert 18.5 < r.fit.f1_hz < 18.8  # mode 1 near 18.75 Hz (SOURCE.md)
    assert r.fit.gain > 0
    # the per-dwell damping carries the voltage/response phase: negative below resonance
    cm, _ = r.fit.per_record("c")
    assert cm[0] < 0 < cm[-1]
    labels = [a["label"] for a in r.alternatives]
    assert any("acc1" in lab for lab in labels)
    acc1 = next(a for a in r.alternatives if "acc1" in a["label"])
    assert acc1["f1_hz"] == pytest.approx(r.fit.f1_hz, rel=1e-3) and acc1["k3_over_m"] > 0
    # phase diagnostic: the response leads the voltage by about 0.6 ms; shifted back, every dwell has positive
    # damping, larger at the two large-amplitude dwells (friction in the joint), and the softening remains
    assert -1e-3 < r.delay_s < -3e-4
    c = r.corrected
    z = c.damping_ratio()
    assert np.all(z > 0)
    big = np.argsort(c.q_max)[-2:]
    small = np.argsort(c.q_max)[:2]
    assert z[big].min() > z[small].max()
    assert c.k3_over_m > 0 and c.omega1_spread() < 0.01


def test_f16_restoring_force_figure_and_softening(tmp_path):
    _require("f16_gvt_sinesweep_uliege", "F16_Data.mat")
    r = ex.f16_restoring_force()
    assert r.corr_low_velocity > 0.85  # restoring force follows relative displacement (0.916)
    assert r.spearman_k_amplitude < -0.9  # apparent stiffness falls with amplitude (-0.996)
    assert r.k_ratio_high_low < 0.5  # about 4x softer at 0.37 mm than at 0.04 mm (0.243)
    assert r.track.t.size >= 20
    fig = r.plot()
    from jointid.io.results import atomic_savefig

    out = atomic_savefig(fig, tmp_path / "f16_restoring_force.png", dpi=60)
    assert out.is_file() and out.stat().st_size > 10_000
    assert len(fig.axes) >= 4


def test_examples_main_writes_results(tmp_path, capsys):
    _require("f16_gvt_sinesweep_uliege", "F16_Data.mat")
    code = ex.main(["--only", "f16", "--out", str(tmp_path)])
    assert code == 0
    assert (tmp_path / "f16.png").is_file() and (tmp_path / "results.json").is_file()
    assert "F-16" in capsys.readouterr().out
