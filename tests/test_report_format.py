"""Numbers shown to a reader: rounded to their standard error, with units; summaries of
results.json that survive absent keys; messages grouped by kind."""

from __future__ import annotations

import numpy as np
import pytest
from html_page import parse_page, parse_tables

from jointid.report.formatting import format_ci, format_pm, format_value, html_table, label_with_unit, unit_of
from jointid.report.summary import (
    adequacy_rows,
    band_resolution,
    console_lines,
    error_lines,
    group_messages,
    message_kind,
    model_rows,
    selection_rows,
    summary_lines,
    table5_rows,
    warning_rows,
)


@pytest.mark.parametrize(
    "value, stderr, expected",
    [
        (0.09221303616276932, 0.0012345, "0.0922 ± 0.0012"),
        (170.00031, 0.00019, "170.00031 ± 0.00019"),
        (5013504.6, 1.4e4, "(5.014 ± 0.014)e6"),
        (-1644.2, 370.0, "-1640 ± 370"),
        (2.4515, 0.0017, "2.4515 ± 0.0017"),
        (1.0, 0.0996, "1.00 ± 0.10"),  # the standard error rounds up to the next decade
        (3.2e-9, 4.1e-11, "(3.200 ± 0.041)e-9"),
    ],
)
def test_value_rounded_to_two_digits_of_its_stderr(value, stderr, expected):
    assert format_pm(value, stderr) == expected


def test_digits_follow_the_stderr_not_the_value():
    # the same value with a ten times larger error loses exactly one digit
    a, b = format_pm(12.345678, 0.0123), format_pm(12.345678, 0.123)
    assert a == "12.346 ± 0.012" and b == "12.35 ± 0.12"


def test_missing_or_infinite_stderr_and_missing_values():
    assert format_pm(0.5, None) == "0.5"
    assert format_pm(0.5, float("nan"), "Hz") == "0.5 Hz"
    assert format_pm(None, 1.0) == "–"
    assert format_pm(float("nan"), 1.0) == "nan"
    assert format_value(None) == "–" and format_value(True) == "yes" and format_value(120) == "120"
    assert format_value(5013504.6) == "5.014e6" and format_value(0.5) == "0.5"


def test_interval_rounded_like_the_value():
    assert format_ci([169.99994, 170.00068], 0.00019) == "[169.99994, 170.00068]"
    assert format_ci([4.986e6, 5.041e6], 1.4e4) == "[4.986, 5.041]e6"
    assert format_ci(None) == "–"


def test_units_of_the_paper_tables():
    assert unit_of("omega1") == "rad/s" and unit_of("f1_hz") == "Hz"
    assert unit_of("k3") == "N/m³"
    assert [unit_of(f"c{k}") for k in range(3)] == ["N s/m", "N s/m²", "N s/m³"]
    assert unit_of("c4") == "N s/m^5"
    assert label_with_unit("q_max") == "q_max [m]" and label_with_unit("weird") == "weird"


def test_html_table_escapes_and_formats():
    page = html_table([{"a": "<b>", "b": 0.123456789}], caption="x & y")
    assert "<b>" not in page  # the text is escaped, not markup
    (table,) = parse_tables(page)
    assert table.caption == "x & y" and table.header == ["a", "b"] and table.rows == [["<b>", "0.1235"]]
    assert table.classes == {(0, 0): "text"}  # text cells left-aligned, numbers not
    assert html_table([]) == ""
    assert parse_page(html_table([], caption="t", empty="no rows")).outline == [("p", "t: no rows")]


def test_messages_grouped_by_kind_with_counts():
    msgs = [f"records/{i:04d}.csv [record {i}]: k3 not resolved by the data: k3 = {i}e6 ± 3e8" for i in range(5)]
    msgs += ["records/0009.csv: missing column 'force' (columns: time, accel)"] * 3
    kinds = group_messages(msgs)
    assert [n for _, n, _ in kinds] == [5, 3]
    assert kinds[0][0] == "k3 not resolved by the data" and kinds[0][2] == msgs[0]
    assert kinds[1][0].startswith("missing column 'force'")
    assert message_kind("column 12 missing in x_3.csv") == "column # missing in x_3.csv"


def _summary():
    """A results.json-like dict: one preload, one group, single-record k3 scattered around zero."""
    rng = np.random.default_rng(0)
    k3_records = 5e6 + 3e8 * rng.standard_normal(20)
    return {
        "models": [{"preload": 120, "omega1": 170.0, "omega1_stderr": 0.002, "parameter_names": ["omega1^2", "k3", "c0",
                                                                                                  "c1", "c2"],
                    "parameters": [28900.0, 5.01e6, 0.08, 70.0, -1644.0], "stderr": [0.6, 1.4e4, 4e-4, 0.3, 370.0],
                    "q_max_range": [1e-4, 8e-3], "n_records": 20, "warnings": ["preload 120: something"]}],
        "groups": [{"preload": 120, "force_level": 1.5, "records": list(range(20)), "omega1": 170.0,
                    "omega1_stderr": 0.003, "k3": 5.02e6, "k3_stderr": 3e4, "k3_mean": float(k3_records.mean())}],
        "records": [{"index": i, "preload": 120, "force_level": 1.5, "status": "ok", "k3": float(k),
                     "warnings": [f"r{i}.csv [record {i}]: k3 not resolved by the data: k3 = 1 ± 2"]}
                    for i, k in enumerate(k3_records)]
        + [{"index": 20 + i, "preload": 120, "force_level": 1.5, "status": "failed",
            "error": f"records/{i}.csv: missing column 'force'"} for i in range(7)],
    }


def test_model_rows_in_paper_units_with_intervals_and_notes():
    rows = {r["quantity"]: r for r in model_rows(_summary())}
    assert list(rows)[:2] == ["f1", "omega1"]
    assert rows["f1"]["unit"] == "Hz" and rows["omega1"]["unit"] == "rad/s"
    assert rows["omega1"]["value ± standard error"] == "170.0000 ± 0.0020"
    assert rows["k3"]["value ± standard error"] == "(5.010 ± 0.014)e6" and rows["k3"]["unit"] == "N/m³"
    assert rows["c2"]["unit"] == "N s/m³" and "negative" in rows["c2"]["note"]
    assert rows["k3"]["95 % interval"] == "[4.983, 5.037]e6"


def test_band_average_flagged_when_unresolved():
    s = _summary()
    band = band_resolution(s, s["groups"][0])
    assert not band["resolved"] and "unresolved" in band["note"]
    (row,) = table5_rows(s)
    assert "unresolved" in row["band average"]
    assert row["k3 [N/m³] (pooled)"] == "(5.020 ± 0.030)e6"
    # a well-resolved band is said to be so
    s["records"] = [dict(r, k3=5e6 + 1e4 * (i % 3)) for i, r in enumerate(s["records"])]
    assert band_resolution(s, s["groups"][0])["resolved"]


def test_warnings_per_group_and_errors_grouped_with_counts():
    s = _summary()
    (w,) = warning_rows(s)
    assert w["records"] == 20 and w["warning"] == "k3 not resolved by the data"
    (e,) = error_lines(s)
    assert e.startswith("7 records: missing column 'force'")
    text = "\n".join(console_lines(s) + error_lines(s))
    assert sum("missing column" in line for line in text.splitlines()) == 1  # 7 failures, one line
    assert "20 x k3 not resolved" in text
    assert "band average" in text and "unresolved" in text


def test_old_results_without_new_keys_still_summarise():
    old = {"records": [{"index": 0, "status": "ok", "k3": 1.0}], "groups": [{"preload": 1, "force_level": 1,
                                                                           "records": [0], "omega1": 10.0}]}
    assert model_rows(old) == [] and adequacy_rows(old) == []
    assert table5_rows(old)[0]["k3 [N/m³] (pooled)"] == "–"
    assert summary_lines({}) == [] and console_lines({}) == []


def test_adequacy_and_selection_shown_in_any_shape():
    rows = adequacy_rows({"adequacy": [{"preload": 120, "adequate": False, "verdict": "residual not white",
                                        "p_value": 0.001}],
                          "selection": {"120": {"selected": "q + -q^3 + q'", "aic": 12.0}}})
    assert rows[0]["verdict"] == "does not hold: residual not white" and "p_value = 0.001" in rows[0]["other"]
    (sel,) = selection_rows({"selection": {"120": {"selected": "q + -q^3 + q'", "aic": 12.0}}})
    assert sel["preload"] == "120" and sel["selected model"] == "q + -q^3 + q'"
