"""Adversarial audit: `jointid simulate` holds a configuration to the size limits of a campaign and refuses
ambiguous tables; a first-harmonic fit that does not converge stops at a bound scaled to its parameters and
is reported, and a candidate law that failed one left-out level is not fitted on the others."""

from __future__ import annotations

import re

import numpy as np
import pytest

from jointid.cli import main
from jointid.errors import IdentificationError, ManifestError
from jointid.identify import firstharmonic as fh
from jointid.identify.firstharmonic import AmplitudeLaw, FirstHarmonicLevel, FirstHarmonicModel, repredict_level

BASE = """[campaign]
name = "small"
[[model]]
preload = 120
terms = "q - q^3 + q'"
omega1 = 170.0
coefficients = { k3 = 5e6 }
amplitude_laws = { c = [0.08, 70.0, 1e4] }
[excitation]
force_levels = [1.0, 2.0]
omega_start = 164.0
omega_stop = 176.0
n_frequencies = 9
[acquisition]
fs = 2000.0
periods = 20.0
noise = 0.01
seed = 1
"""

SECOND_MODEL = """[[model]]
preload = {preload}
terms = "q - q^3 + q'"
omega1 = 150.0
coefficients = {{ k3 = 5e6 }}
amplitude_laws = {{ c = [0.08, 70.0, 1e4] }}
"""


def _with_second_model(preload):
    return BASE.replace("[excitation]", SECOND_MODEL.format(preload=preload) + "[excitation]")


CASES = {
    "huge_record": (BASE.replace("periods = 20.0", "periods = 100000.0"), r"samples; at most 2e\+06"),
    "many_records": (BASE.replace("force_levels = [1.0, 2.0]", "force_levels = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]")
                     .replace("n_frequencies = 9", "n_frequencies = 1000"), r"6000 records; at most 5000"),
    "two_models_same_preload": (_with_second_model("120"), r"\[\[model\]\] tables 1 and 2 both have preload 120"),
    "two_models_120_and_text": (_with_second_model('"120"'), r"preloads 120 and '120'"),
    "two_models_120_and_120.0": (_with_second_model("120.0"), r"preloads 120 and 120\.0"),
    "two_models_default_preload": (_with_second_model('"sim"').replace("preload = 120\n", ""),
                                   r"both have preload 'sim'"),
    "freqs_and_omega": (BASE.replace("n_frequencies = 9", "n_frequencies = 9\nfrequencies_hz = [27.0, 27.5]"),
                        r"both frequencies_hz and omega_start/omega_stop/n_frequencies; keep one"),
    "freqs_and_n": (BASE.replace("omega_start = 164.0\nomega_stop = 176.0\n", "")
                    .replace("n_frequencies = 9", "n_frequencies = 9\nfrequencies_hz = [27.0, 27.5]"),
                    r"both frequencies_hz and n_frequencies"),
}


@pytest.mark.parametrize("name", list(CASES))
def test_simulate_refuses_before_any_folder(tmp_path, capsys, monkeypatch, name):
    from jointid.app import synthesis

    def never(*a, **k):  # pragma: no cover - the point is that it is not reached
        raise AssertionError("steady states were computed")

    monkeypatch.setattr(synthesis, "simulate_steady_states", never)
    text, pattern = CASES[name]
    cfg = tmp_path / "sim.toml"
    cfg.write_text(text)
    out = tmp_path / "camp"
    code = main(["simulate", str(cfg), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and str(cfg) in err and re.search(pattern, err), err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert not out.exists()


def test_simulation_config_within_the_limits_is_accepted():
    import tomllib

    from jointid.app.synthesis import load_simulation_config

    cfg = load_simulation_config(tomllib.loads(_with_second_model("540")))
    assert [p for p, _ in cfg.models] == [120, 540] and cfg.omegas.size == 9
    freq_only = tomllib.loads(BASE.replace("omega_start = 164.0\nomega_stop = 176.0\nn_frequencies = 9",
                                           "frequencies_hz = [27.0, 27.5]"))
    assert load_simulation_config(freq_only).omegas.size == 2
    with pytest.raises(ManifestError, match="keep one"):
        load_simulation_config({**freq_only, "excitation": {**freq_only["excitation"], "omega_stop": 176.0}})


# ----------------------------------------------------------------------------------------------------------
# first harmonics: bounded fits

TRUTH = FirstHarmonicModel(AmplitudeLaw("poly2"), AmplitudeLaw("poly1"), 60.0,
                           np.array([-0.5, -0.4, -0.2, 80.0, -0.008, 0.004, 0.001, 0.003]))


def _levels(forces=(0.15, 0.4, 0.8), n=21, seed=1):
    rng = np.random.default_rng(seed)
    levels = []
    for k, F0 in enumerate(forces):
        f = np.linspace(79.0, 81.0, n)
        F = F0 * np.ones(n)
        a = repredict_level(TRUTH, FirstHarmonicLevel(f, F, 0.0, np.ones(n), 0.0, f"L{k + 1}")).accel_predicted
        H = TRUTH.frf(2 * np.pi * f, a)
        H = H + 0.01 * np.abs(H) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
        levels.append(FirstHarmonicLevel(f, F, 0.0, np.abs(H) * F, np.angle(H), f"L{k + 1}"))
    return levels


def test_every_fit_is_bounded_by_its_parameters(monkeypatch):
    from scipy import optimize

    seen = []
    orig = optimize.least_squares

    def spy(fun, x0, *a, **k):
        seen.append((len(x0), k.get("max_nfev")))
        return orig(fun, x0, *a, **k)

    monkeypatch.setattr(fh.optimize, "least_squares", spy)
    fh.fit_first_harmonic(_levels(), "poly2", "poly1", repredict=False, low_level=False)
    assert seen and all(m is not None and m <= 50 * n for n, m in seen), seen


def test_a_fit_at_the_bound_is_reported_not_returned(monkeypatch):
    from scipy import optimize

    orig = optimize.least_squares
    def two_evaluations(fun, x0, *a, **k):
        return orig(fun, x0, *a, **{**k, "max_nfev": 2})

    monkeypatch.setattr(fh.optimize, "least_squares", two_evaluations)
    with pytest.raises(IdentificationError, match=r"did not converge within \d+ evaluations"):
        fh.fit_first_harmonic(_levels(), "poly2", "poly1", repredict=False, low_level=False)


def test_select_laws_stops_a_candidate_at_its_first_failed_level(monkeypatch):
    calls = []

    def failing(levels, *a, **k):
        calls.append(len(levels))
        raise IdentificationError("did not converge")

    monkeypatch.setattr(fh, "fit_first_harmonic", failing)
    levels = _levels(forces=(0.15, 0.4, 0.8, 1.2), n=9)
    with pytest.raises(IdentificationError, match="no candidate law"):
        fh.select_laws(levels, candidates=(("poly1", "poly1"), ("poly2", "poly1")))
    assert len(calls) == 2  # one fit per candidate, not one per left-out level
    lolo = fh.leave_one_level_out(levels, "poly1", "poly1", stop_at_error=True)
    assert [("error" in e) for e in lolo] == [True] * 4 and "leaving out level L1 failed" in lolo[1]["error"]
    assert len(fh.leave_one_level_out(levels, "poly1", "poly1")) == 4 and len(calls) == 2 + 1 + 4
