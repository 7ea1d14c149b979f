"""``jointid predict MODEL.toml``: the time-integration check of the peaks (``time_checks`` of results.json)."""

import json

import pytest

from jointid.app.structure_predict import predict_structure, write_structure_predictions

MODEL = """
[modal]
frequencies_hz = [20.0, 60.0]
damping_ratios = [0.02, 0.02]
dof_names = ["a", "b", "tip"]
shapes = [[0.1, 0.3], [0.4, -0.2], [1.0, 0.5]]
[[joint]]
name = "bolt"
dofs = ["a", "b"]
law = "jenkins"
parameters = { kt = 1e4, Fs = 0.05 }
k_model = "stuck"
[force]
dofs = { tip = 1.0 }
[response]
dofs = ["tip", "a"]
[predict]
frequency_range_hz = [16.0, 24.0]
force_levels = [0.5, 2.0]
n_harmonics = 7
"""


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    path = tmp_path_factory.mktemp("tc") / "MODEL.toml"
    path.write_text(MODEL)
    return path


def test_time_checks_of_the_peaks_in_results_and_report(model, tmp_path):
    res = predict_structure(model, force_levels=[0.5, 2.0], time_check=1)
    (c,) = res.time_checks  # one point: the largest level's peak
    assert c["force_level"] == 2.0 and not c["error"] and c["periods"] == 10 and c["n_steps"] >= 600
    lv = res.levels[1]
    assert c["frequency_hz"] == pytest.approx(lv.peak_point.frequency_hz, rel=1e-15)
    assert c["frequency_hz"] in lv.frequency_hz  # a point of the curve
    # the slipping Jenkins joint (slip 5e-6, the peak's joint motion far beyond): 7 harmonics agree with the
    # time integration to well below the check's level, and the integration is no copy of the harmonic balance
    assert 0 < c["relative_difference"] < 1e-3 and c["cost_s"] > 0
    assert any(line.startswith("time integration from the peaks") for line in res.lines())
    write_structure_predictions(res, tmp_path / "out")
    d = json.loads((tmp_path / "out" / "results.json").read_text())
    assert d["time_checks"][0]["relative_difference"] == c["relative_difference"]
    assert d["settings"]["time_check_points"] == 1
    assert predict_structure(model, force_levels=[2.0], time_check=0).time_checks == []
