"""What the reader is shown: each campaign's own band averages, the model the data select first,
adequacy as a table of named quantities, and one formatter that never prints more digits than
the uncertainty (or a float) supports."""

from __future__ import annotations

import numpy as np
import pytest

from jointid.report.formatting import format_ci, format_estimate, format_pm, format_value
from jointid.report.summary import (
    adequacy_rows,
    band_resolution,
    lead_lines,
    lead_tables,
    model_choice_lines,
    selected_model_rows,
    table5_rows,
)


def _campaign(preload, k3_center, seed):
    """One campaign's results.json part: one group of 21 records numbered 0..20 (as every campaign is)."""
    rng = np.random.default_rng(seed)
    k3 = k3_center + 2e6 * rng.standard_normal(21)
    return {
        "settings": {"force_gain": "known"},
        "groups": [{"preload": preload, "force_level": 1.5, "records": list(range(21)), "omega1": 166.0,
                    "omega1_stderr": 1e-4, "k3": k3_center, "k3_stderr": 1e4, "k3_mean": float(k3.mean())}],
        "records": [{"index": i, "preload": preload, "force_level": 1.5, "status": "ok", "k3": float(v)}
                    for i, v in enumerate(k3)],
    }


def _band_text(s):
    k3 = np.array([r["k3"] for r in s["records"]])
    return format_pm(s["groups"][0]["k3_mean"], k3.std(ddof=1) / np.sqrt(k3.size))


def test_band_average_of_each_preload_is_its_own_campaigns():
    a, b = _campaign(120.0, 3e7, 1), _campaign(540.0, -5e6, 2)
    # the report of several campaigns: Table 5 shows each preload's own band average (results.json's k3_mean)
    _, tables = lead_tables([a, b])
    (t5,) = [rows for caption, rows, _ in tables if caption.startswith("The paper's Table 5")]
    col = "k3 [N/m³] band average (paper)"
    assert [r["preload"] for r in t5] == ["120.0", "540.0"]
    assert t5[0][col] == _band_text(a) and t5[1][col] == _band_text(b)
    assert t5[0][col] != t5[1][col]
    # and records of two campaigns in one summary (same indices 0..20) are told apart by their preload
    merged = {"groups": a["groups"] + b["groups"], "records": a["records"] + b["records"]}
    for s, g in ((a, merged["groups"][0]), (b, merged["groups"][1])):
        band = band_resolution(merged, g)
        assert band["mean"] == pytest.approx(g["k3_mean"], rel=1e-12)
        assert format_pm(band["mean"], band["stderr"]) == _band_text(s)
    assert [r[col] for r in table5_rows(merged)] == [_band_text(a), _band_text(b)]


def _selected_vs_cubic():
    """A demo-like summary: the cubic preload model rejected by adequacy, micro-slip + cubic selected."""
    names = ["omega1^2", "omega1^2_1", "p(omega1^2)", "k3", "c0", "c1", "p(c)"]
    vals = [27501.19, -104126.3, 1.2054, -1855271.2, 0.510533, 21.937, 0.84963]
    errs = [0.0355, 1354.7, 0.00198, 25796.3, 9.08e-5, 0.0605, 0.000578]
    return {
        "settings": {"force_gain": "known"},
        "models": [{"preload": 120.0, "terms": ["q", "-q^3", "q'"], "omega1": 165.727, "omega1_stderr": 7.8e-5,
                    "parameter_names": ["omega1^2", "k3", "c0", "c1", "c2"],
                    "parameters": [27465.44, 5213188.0, 0.52011, 53.735, -1404.8],
                    "stderr": [0.0258, 4868.5, 4.4e-5, 0.0333, 5.52], "n_records": 63}],
        "adequacy": [{"preload": 120.0, "terms": ["q", "-q^3", "q'"], "model": "cubic", "adequate": False,
                      "verdict": "k3 changes 2.99x across levels (p < 1e-6): the cubic model does not hold",
                      "level_equality": {"chi2": 2.39e6, "dof": 4, "p_value": 0.0}, "misfit_median": 508.2,
                      "outliers": [], "explained_force": 0.9999985, "explained_force_min": 0.9999962,
                      "explained_harmonics": -1.3716, "explained_harmonics_min": -1.9137,
                      "harmonic_residual_to_noise": 553.46, "records": []}],
        "selection": [{"preload": 120.0, "selected": "micro-slip + cubic", "criterion": "bic",
                       "selected_terms": "q - q^3 + q'", "n_records": 63,
                       "ranking": [{"name": "micro-slip + cubic", "selected": True, "parameter_names": names,
                                    "parameters": vals, "stderr": errs, "dof": 236.5, "n_parameters": 7,
                                    "delta_ic": 0.0},
                                   {"name": "cubic", "selected": False, "delta_ic": 39054.0,
                                    "parameter_names": ["omega1^2", "k3", "c0", "c1", "c2"], "parameters": [1.0] * 5,
                                    "stderr": [1.0] * 5}]}],
        "groups": [], "records": [],
    }


def test_summary_leads_with_the_selected_model_and_says_which_to_believe():
    s = _selected_vs_cubic()
    paragraphs, tables = lead_tables([s])
    # first table: the selected model's parameters, with standard errors, 95 % intervals and units
    caption, rows, _ = tables[0]
    assert "the model the data select" in caption
    k3 = next(r for r in rows if r["quantity"] == "k3")
    assert r"micro-slip + cubic" == k3["model"] and k3["value ± standard error"] == "(-1.855 ± 0.026)e6"
    assert k3["95 % interval"] == "[-1.906, -1.805]e6" and k3["unit"] == "N/m³"
    p_c = next(r for r in rows if r["quantity"] == "p(c)")
    assert p_c["value ± standard error"] == "0.84963 ± 0.00058" and p_c["unit"] == "1"
    c1 = next(r for r in rows if r["quantity"] == "c1")
    assert c1["unit"] == "N s/m^1.85"  # c0 + c1 q_max^p: the unit carries the fitted power
    assert [r["quantity"] for r in rows][:2] == ["f1 (at zero amplitude)", "omega1 (at zero amplitude)"]
    # second: the paper's cubic, labelled as such and as the comparison
    caption2, rows2, _ = tables[1]
    assert "for comparison" in caption2.lower() and "the paper's cubic (Eq 21)" in caption2
    assert all(r["model"] == "the paper's cubic (Eq 21)" for r in rows2)
    # one sentence: which to believe and why (the selection and the adequacy verdict)
    sentence, note = paragraphs  # and what the adequacy table's columns are
    assert note.startswith("Model adequacy: ")
    assert sentence.startswith("Preload 120.0: believe the micro-slip + cubic model")
    assert "reject the paper's cubic" in sentence and "does not hold" in sentence and "BIC" in sentence
    # the console leads with the same
    text = "\n".join(lead_lines(s))
    assert text.index("believe the micro-slip + cubic") < text.index("Selected model: micro-slip + cubic")
    assert text.index("k3 = (-1.855 ± 0.026)e6 N/m³") < text.index("k3 = (5.2132 ± 0.0049)e6 N/m³")


def test_no_selection_no_extra_table_and_a_selected_preload_model_is_not_shown_twice():
    s = _selected_vs_cubic()
    assert selected_model_rows(dict(s, selection=[])) == []
    chosen = s["selection"][0]["ranking"][0]
    same = dict(s, models=[dict(s["models"][0], parameter_names=chosen["parameter_names"],
                                parameters=chosen["parameters"], stderr=chosen["stderr"])])
    assert selected_model_rows(same) == []
    assert "the preload model shown below" in model_choice_lines(same)[0]


def test_adequacy_is_a_table_of_named_quantities_not_a_negative_fraction():
    (row,) = adequacy_rows(_selected_vs_cubic())
    assert row["verdict"].startswith("does not hold: k3 changes 2.99x")
    assert row["equality across force levels"] == "chi² 2.39e6 on 4 dof, p < 1e-6"
    assert row["median record misfit [× noise]"] == "508"
    # 1 - explained_harmonics: the residual energy of the harmonics over their measured energy (>= 0)
    assert row["harmonics above the first: residual / measured energy [1] (worst record)"] == "2.37 (2.91)"
    assert row["restoring force explained [%] (lowest record)"] == "99.99985 (99.99962)"
    assert not any("explained_harmonics" in str(v) or "; " in str(v) for v in row.values())


@pytest.mark.parametrize("value, stderr, expected", [
    (27.05634032562221236162, 0.00000000000000000053, "27.0563403256222 ± 5.3e-19"),
    (5073686.1, 8.2e4, "(5.074 ± 0.082)e6"),
    (1.00311916e-13, None, "1.003e-13"),
    (0.10326711514483389, None, "0.1033"),
])
def test_the_issue_examples_are_rounded(value, stderr, expected):
    assert format_pm(value, stderr) == expected


def test_intervals_and_exact_fits():
    assert format_estimate(5073686.1, 8.2e4, "N/m³") == "(5.074 ± 0.082)e6 N/m³, 95 % [4.913, 5.234]e6"
    # two records, two parameters: no standard error, no interval
    assert format_pm(1.11, 5e-13, dof=0) == "1.11 (standard error not available: no degrees of freedom)"
    assert format_ci([1.11, 1.11], 5e-13, dof=0) == "not available"
    assert format_ci([27.056340325622212, 27.056340325622214], 5.3e-19) == "[27.0563403256222, 27.0563403256222]"
    for v in (np.pi * 1e-300, np.pi, np.pi * 1e300):
        mant = format_value(v, 30).split("e")[0].replace("-", "").replace(".", "").lstrip("0")
        assert len(mant) <= 15


def test_a_two_record_power_law_has_no_standard_error():
    from jointid.report.output import _power_rows

    s = {"power_law": [{"preload": 1, "force_level": 2.0, "alpha": 1e-8, "n": 1.11, "n_stderr": 5e-13,
                        "force": [1.0, 2.0], "within_2_3": False},
                       {"preload": 1, "force_level": 3.0, "alpha": 1e-8, "n": 2.4515, "n_stderr": 0.0017,
                        "force": [1.0, 2.0, 3.0, 4.0], "within_2_3": True}]}
    two, four = _power_rows(s)
    assert two["n ± standard error [1]"] == "1.11 (standard error not available: no degrees of freedom)"
    assert four["n ± standard error [1]"] == "2.4515 ± 0.0017" and two["F [N]"] == "2"


def test_model_choice_names_the_rule_that_decided():
    """The summary sentence says what decided the pick: held-out prediction, or (older results) the criterion."""
    s = _selected_vs_cubic()
    for decided_by, said, not_said in (("held-out prediction", "held-out force levels", "lowest BIC"),
                                       ("bic", "lowest BIC", "held-out")):
        line = model_choice_lines(dict(s, selection=[dict(s["selection"][0], decided_by=decided_by)]))[0]
        assert said in line and not_said not in line, line


def test_selected_hysteretic_law_parameters_carry_their_units():
    """A selected Jenkins law's parameters are not terms of the library: their units come from the law's fit
    (results.json selection[*].hysteretic_model.units), not left blank."""
    from jointid.report.summary import selected_model_rows

    names = ["k", "c", "kt", "Fs", "slip_displacement"]
    units = {"k": "N/m", "c": "N s/m", "kt": "N/m", "Fs": "N", "slip_displacement": "m"}
    entry = {"name": "Jenkins", "selected": True, "hysteretic_law": "jenkins", "parameter_names": names,
             "parameters": [3.5e4, 5.6, 1.1e4, 10.7, 1e-3], "stderr": [1.2, 0.002, 1.3, 0.002, 1e-7]}
    summary = {"models": [{"preload": "p", "parameter_names": ["omega1^2", "c"]}],
               "selection": [{"preload": "p", "selected": "Jenkins", "ranking": [entry],
                              "hysteretic_model": {"law": "jenkins", "units": units}}]}
    rows = selected_model_rows(summary)
    assert {r["quantity"]: r["unit"] for r in rows} == units
