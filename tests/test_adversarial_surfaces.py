"""Adversarial corpus of the newer surfaces: study plans, resumed studies and ``backbone`` inputs.

Every case ends in exit 2 with one line naming the file and the key (or JSON path, or line)
at fault: no traceback, no output folder left behind, nothing run.
"""

from __future__ import annotations

import json
import re

import pytest

from jointid.cli import main

BASE_PLAN = """\
[study]
name = "adversarial"
campaigns = 3
seed = 5

[identify]
terms = "q - q^3 + q'"
damping_order = 2

[[model]]
preload = "sim"
omega1 = 170.0
coefficients = { k3 = 5e6 }
amplitude_laws = { c = [0.08, 70.0, 1e4] }

[excitation]
force_levels = [1.0, 2.0]
omega_start = 164.0
omega_stop = 176.0
n_frequencies = 5

[acquisition]
fs = 2000.0
periods = 15
noise = 0.01

[vary]
"acquisition.noise" = { loguniform = [0.002, 0.02] }
"model.coefficients.k3" = { uniform = [3e6, 6e6], random_sign = true }
"""


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    return code, err


def _never(*a, **k):  # pragma: no cover - the point is that it is not reached
    raise AssertionError("a campaign was run")


@pytest.fixture
def no_campaigns(monkeypatch):
    import jointid.app.study as study

    monkeypatch.setattr(study, "run_campaign", _never)


def _sub(old, new):
    def edit(text):
        assert old in text, old
        return text.replace(old, new, 1)
    return edit


def _add(table, line):
    return _sub(f"[{table}]\n", f"[{table}]\n{line}\n")


# name: (edit of the plan text, pattern the message must match)
PLAN_CASES = {
    "study_not_table": (lambda t: "study = 5\n" + t.replace("[study]\nname = \"adversarial\"\ncampaigns = 3\nseed = 5\n", ""),
                        r"\[study\].*table"),
    "identify_not_table": (lambda t: "identify = \"q\"\n" + t.replace(
        "[identify]\nterms = \"q - q^3 + q'\"\ndamping_order = 2\n", ""), r"\[identify\].*table"),
    "vary_not_table": (lambda t: "vary = 3\n" + t[:t.index("[vary]")], r"\[vary\].*table"),
    "campaigns_inf": (_sub("campaigns = 3", "campaigns = inf"), r"\[study\] campaigns"),
    "campaigns_huge": (_sub("campaigns = 3", "campaigns = 1e12"), r"\[study\] campaigns"),
    "campaigns_huge_int": (_sub("campaigns = 3", "campaigns = 1000000000000"), r"\[study\] campaigns.*at most"),
    "campaigns_fraction": (_sub("campaigns = 3", "campaigns = 2.5"), r"\[study\] campaigns.*integer"),
    "campaigns_text": (_sub("campaigns = 3", 'campaigns = "10"'), r"\[study\] campaigns.*integer"),
    "campaigns_bool": (_sub("campaigns = 3", "campaigns = true"), r"\[study\] campaigns.*integer"),
    "seed_inf": (_sub("seed = 5", "seed = inf"), r"\[study\] seed"),
    "seed_fraction": (_sub("seed = 5", "seed = 1.5"), r"\[study\] seed.*integer"),
    "name_table": (_sub('name = "adversarial"', "name = { a = 1 }"), r"\[study\] name"),
    "choice_mixed": (_add("vary", '"acquisition.write_frequency" = { choice = [true, 3, "x"] }'),
                     r"acquisition.write_frequency.*choice"),
    "choice_wrong_type": (_add("vary", '"acquisition.write_frequency" = { choice = [1.0, 2.0] }'),
                          r"acquisition.write_frequency"),
    "size_on_scalar": (_add("vary", '"acquisition.fs" = { uniform = [1500.0, 4000.0], size = 3 }'),
                       r"acquisition.fs.*size"),
    "size_huge": (_add("vary", '"excitation.force_levels" = { uniform = [0.4, 2.0], size = 100000000 }'),
                  r"excitation.force_levels.*size"),
    "size_range_huge": (_add("vary", '"excitation.force_levels" = { uniform = [0.4, 2.0], size = [1, 100000000] }'),
                        r"excitation.force_levels.*size"),
    "grid_huge": (lambda t: t + "\n[grid]\n" + "\n".join(f'"acquisition.t0" = [{", ".join(str(float(i)) for i in range(200))}]'
                                                          for _ in range(1)) + '\n"acquisition.periods" = ['
                  + ", ".join(str(10 + i) for i in range(200)) + "]\n", r"grid.*point"),
    "grid_values_not_list": (lambda t: t + '\n[grid]\n"acquisition.t0" = 3.0\n', r"\[grid\] 'acquisition.t0'"),
    "fs_text": (_sub("fs = 2000.0", 'fs = "fast"'), r"\[acquisition\] fs"),
    "fs_inf": (_sub("fs = 2000.0", "fs = inf"), r"\[acquisition\] fs"),
    "fs_huge": (_sub("fs = 2000.0", "fs = 1e12"), r"\[acquisition\] fs"),
    "periods_huge": (_sub("periods = 15", "periods = 1e9"), r"periods|samples"),
    "noise_negative": (_sub("noise = 0.01", "noise = -0.01"), r"\[acquisition\] noise"),
    "write_frequency_text": (_add("acquisition", 'write_frequency = "yes"'), r"\[acquisition\] write_frequency"),
    "n_harmonics_huge": (_add("acquisition", "n_harmonics = 100000"), r"\[acquisition\] n_harmonics"),
    "acquisition_unknown_key": (_add("acquisition", "sampling_rate = 3000.0"), r"\[acquisition\].*'sampling_rate'"),
    "acquisition_typo": (_add("acquisition", "nosie = 0.01"), r"did you mean 'noise'"),
    "acquisition_not_table": (lambda t: t.replace("[acquisition]\nfs = 2000.0\nperiods = 15\nnoise = 0.01\n", "")
                              .replace("[study]", "acquisition = 4\n[study]"), r"\[acquisition\].*table"),
    "model_unknown_key": (_sub('preload = "sim"', 'preload = "sim"\nomega = 170.0'), r"\[model\].*'omega'"),
    "model_typo": (_sub("omega1 = 170.0", "omega1 = 170.0\namplitude_law = { c = [0.1] }"),
                   r"did you mean 'amplitude_laws'"),
    "model_omega1_text": (_sub("omega1 = 170.0", 'omega1 = "fast"'), r"\[model\] omega1"),
    "model_omega1_negative": (_sub("omega1 = 170.0", "omega1 = -170.0"), r"\[model\] omega1"),
    "model_power_law": (_sub("amplitude_laws = { c = [0.08, 70.0, 1e4] }", 'amplitude_laws = { c = "power" }'),
                        r"\[model\] amplitude_laws"),
    "model_law_text": (_sub("amplitude_laws = { c = [0.08, 70.0, 1e4] }", 'amplitude_laws = { c = ["a", 2] }'),
                       r"\[model\] amplitude_laws"),
    "model_law_huge_order": (_sub("amplitude_laws = { c = [0.08, 70.0, 1e4] }",
                                  "amplitude_laws = { c = [" + ", ".join(["0.1"] * 60) + "] }"),
                             r"\[model\] amplitude_laws"),
    "model_coefficient_text": (_sub("coefficients = { k3 = 5e6 }", 'coefficients = { k3 = "big" }'),
                               r"\[model\] coefficients"),
    "excitation_unknown_key": (_add("excitation", "amplitude = 3.0"), r"\[excitation\].*'amplitude'"),
    "excitation_n_huge": (_sub("n_frequencies = 5", "n_frequencies = 100000000"), r"\[excitation\] n_frequencies"),
    "excitation_n_fraction": (_sub("n_frequencies = 5", "n_frequencies = 5.5"), r"\[excitation\] n_frequencies"),
    "excitation_levels_text": (_sub("force_levels = [1.0, 2.0]", 'force_levels = ["a"]'), r"\[excitation\] force_levels"),
    "excitation_levels_inf": (_sub("force_levels = [1.0, 2.0]", "force_levels = [inf]"), r"\[excitation\] force_levels"),
    "excitation_omega_tiny": (_sub("omega_start = 164.0", "omega_start = 1e-9"), r"samples"),
    "vary_fs_huge": (_add("vary", '"acquisition.fs" = { uniform = [1500.0, 1e13] }'), r"acquisition.fs"),
    "vary_periods_huge_samples": (_add("vary", '"acquisition.periods" = { uniform = [10.0, 1e8] }'),
                                  r"acquisition.periods|samples"),
    "vary_noise_negative": (_add("vary", '"acquisition.seed" = { integers = [0, 3] }').__call__ if False else
                            _sub('"acquisition.noise" = { loguniform = [0.002, 0.02] }',
                                 '"acquisition.noise" = { uniform = [-0.5, 0.02] }'), r"acquisition.noise"),
    "campaign_not_table": (lambda t: "campaign = [1, 2]\n" + t, r"\[campaign\].*table"),
}


@pytest.mark.parametrize("name", list(PLAN_CASES))
def test_study_plan_corpus(tmp_path, capsys, no_campaigns, name):
    edit, pattern = PLAN_CASES[name]
    plan = tmp_path / "plan.toml"
    plan.write_text(edit(BASE_PLAN))
    out = tmp_path / "out"
    code, err = _run(["study", plan, "--out", out, "--quiet"], capsys)
    assert code == 2 and str(plan) in err and re.search(pattern, err), err
    assert len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_base_plan_is_valid(tmp_path):
    from jointid.app.study import load_study_plan

    plan = tmp_path / "plan.toml"
    plan.write_text(BASE_PLAN)
    assert load_study_plan(plan).n_campaigns == 3


@pytest.mark.parametrize("jobs", ["-1", "10000"])
def test_study_jobs_out_of_range(tmp_path, capsys, no_campaigns, jobs):
    plan = tmp_path / "plan.toml"
    plan.write_text(BASE_PLAN)
    out = tmp_path / "out"
    code, err = _run(["study", plan, "--out", out, "--quiet", "--jobs", jobs], capsys)
    assert code == 2 and "jobs" in err and jobs in err, err
    assert not out.exists()
