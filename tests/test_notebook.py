"""Results in a notebook: short reprs, HTML tables, one summary warning per call, a quick start."""

from __future__ import annotations

import warnings

import pytest

import jointid
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.errors import JointidWarning

CONFIG = {
    "campaign": {"name": "notebook test"},
    "model": [{"preload": 120, "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
               "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
    "excitation": {"force_levels": [1.0, 2.0], "omega_start": 160.0, "omega_stop": 180.0, "n_frequencies": 10},
    "acquisition": {"fs": 2000.0, "periods": 20.0, "noise": 0.01, "seed": 7, "n_harmonics": 7},
}


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    camp = simulate_campaign(load_simulation_config(CONFIG), tmp_path_factory.mktemp("nb") / "campaign")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = jointid.identify_campaign(camp, repredict=False)
    return result, [w for w in caught if issubclass(w.category, JointidWarning)]


def test_one_summary_warning_per_call_with_every_message_kept(identified):
    result, caught = identified
    per_record = sum(len(r.warnings) for r in result.records)
    assert per_record >= 2  # off-resonance dwells do not resolve k3 on their own
    assert len(caught) == 1
    text = str(caught[0].message)
    import re

    total = int(re.match(r"(\d+) warnings over (\d+) records", text).group(1))
    assert total >= per_record  # the records' messages, and those of the pooled fits if any
    n_k3 = sum("k3 not resolved" in w for r in result.records for w in r.warnings)
    assert f"{n_k3} x k3 not resolved by the data" in text
    assert caught[0].filename == __file__  # points at the caller's line


def _objects(result):
    g = next(g for g in result.groups if g.pooled is not None)
    rec = next(r for r in result.records if r.ok)
    return {"CampaignResult": result, "GroupResult": g, "PooledFit": g.pooled, "RecordFit": rec.fit,
            "DampingLaw": result.damping_laws[120], "PowerLaw": g.power_law, "PreloadModel": result.models[120]}


def test_reprs_are_short_and_say_what_they_hold(identified):
    result, _ = identified
    for name, obj in _objects(result).items():
        text = repr(obj)
        assert text.startswith(name + "(") and len(text) < 400, (name, len(text))
    assert "notebook test" in repr(result) and f"{len(result.records)} records" in repr(result)


def test_html_displays_are_tables_with_rounded_values_and_units(identified):
    result, _ = identified
    for name, obj in _objects(result).items():
        page = obj._repr_html_()
        assert "<table" in page and "<pre>" not in page, name
        assert "±" in page, name
    page = result._repr_html_()
    for text in ("identified model per preload", "rad/s", "Hz", "N/m³", "N s/m", "Table 5", "band average",
                 "warnings per group", "k3 not resolved"):
        assert text in page, text
    import re

    assert not re.search(r"\d\.\d{9,}", page)  # no 16-digit numbers


def test_quick_start_in_the_package_docstring():
    doc = jointid.__doc__
    assert "jointid.identify_campaign(" in doc and "docs/formats.md" in doc
    assert jointid.identify_campaign.__module__ == "jointid.app.workflow"
