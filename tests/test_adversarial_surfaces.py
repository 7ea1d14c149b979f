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
    "campaign_records_huge": (lambda t: _add("vary", '"excitation.force_levels" = { uniform = [0.4, 2.0], size = [2, 50] }')(
        t.replace("n_frequencies = 5", "n_frequencies = 1000")), r"50 force level.*1000 frequencies.*records"),
    "frequencies_hz_tiny_drawn": (_add("vary", '"excitation.frequencies_hz" = { uniform = [1e-6, 30.0], size = 3 }'),
                                  r"samples"),
    "integer_key_uniform": (_add("vary", '"excitation.n_frequencies" = { uniform = [3.0, 9.0] }'),
                            r"excitation.n_frequencies.*use integers"),
    "normal_beyond_bounds": (_sub('"acquisition.noise" = { loguniform = [0.002, 0.02] }',
                                  '"acquisition.noise" = { normal = [0.01, 0.01] }'), r"acquisition.noise.*normal mean"),
    "identify_terms_number": (_sub("terms = \"q - q^3 + q'\"", "terms = 5"), r"\[identify\] terms"),
    "identify_terms_unknown": (_sub("terms = \"q - q^3 + q'\"", "terms = \"q + foo\""), r"\[identify\] terms.*foo"),
    "identify_terms_no_stiffness": (_sub("terms = \"q - q^3 + q'\"", "terms = \"q' + q^3\""),
                                    r"\[identify\] terms.*linear stiffness"),
    "identify_delay_inf": (_add("identify", "channel_delay = inf"), r"\[identify\] channel_delay"),
    "identify_delay_text": (_add("identify", 'channel_delay = "x"'), r"\[identify\] channel_delay"),
    "identify_flag_text": (_add("identify", 'repredict = "no"'), r"\[identify\] repredict"),
    "identify_flag_number": (_add("identify", "keep_flagged = 3"), r"\[identify\] keep_flagged"),
    "vary_table_key": (_add("vary", '"model.coefficients" = { uniform = [1.0, 2.0] }'), r"model.coefficients"),
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


# ------------------------------------------------------------------------ resumed studies
def _fake_campaign(plan, index):
    """A well-formed campaign line, without simulating (the resume checks are about the file)."""
    return {"index": int(index), "seed": plan.campaign_seed(index), "plan": plan.fingerprint,
            "grid_point": index % len(plan.points), "drawn": {"acquisition.noise": 0.01}, "status": "ok",
            "error": None, "n_records": 10, "n_failed": 0,
            "rows": [{"parameter": "groups.omega1", "where": "sim", "estimate": 170.1, "stderr": 0.1,
                      "ci95": [169.9, 170.3], "truth": 170.0, "z": 1.0, "covered": True}]}


@pytest.fixture
def study_folder(tmp_path, monkeypatch, capsys):
    """A finished study of 3 (fake) campaigns: plan, output folder."""
    import jointid.app.study as study

    plan = tmp_path / "plan.toml"
    plan.write_text(BASE_PLAN)
    out = tmp_path / "out"
    monkeypatch.setattr(study, "run_campaign", _fake_campaign)
    assert main(["study", str(plan), "--out", str(out), "--quiet", "--no-report"]) == 0
    capsys.readouterr()
    monkeypatch.setattr(study, "run_campaign", _never)
    return plan, out


def _lines(out):
    return [json.loads(t) for t in (out / "campaigns.jsonl").read_text().splitlines()]


def _write_lines(out, lines, raw=None):
    text = raw if raw is not None else "".join(json.dumps(line) + "\n" for line in lines)
    (out / "campaigns.jsonl").write_bytes(text if isinstance(text, bytes) else text.encode())


def _set(i, key, value):
    def edit(lines):
        lines[i][key] = value
        return lines
    return edit


def _drop(i, key):
    def edit(lines):
        del lines[i][key]
        return lines
    return edit


def _row(i, key, value=None, drop=False):
    def edit(lines):
        if drop:
            del lines[i]["rows"][0][key]
        else:
            lines[i]["rows"][0][key] = value
        return lines
    return edit


# name: (edit of the parsed lines, or a function of the file's text giving bytes; pattern of the message)
RESUME_CASES = {
    "not_utf8": (lambda text: text.encode()[:20] + b"\xff\xfe" + text.encode()[20:], r"UTF-8"),
    "infinite_index": (lambda text: text.replace('"index": 1,', '"index": Infinity,', 1).encode(), r"line 2.*Infinity"),
    "nan_estimate": (lambda text: text.replace('"estimate": 170.1', '"estimate": NaN', 1).encode(), r"line 1"),
    "huge_index": (_set(1, "index", 1e300), r"line 2.*index"),
    "index_not_its_seed": (_set(1, "index", 7), r"line 2.*campaign 7: seed"),  # a line moved to another index
    "negative_index": (_set(1, "index", -1), r"line 2.*index"),
    "index_text": (_set(1, "index", "1"), r"line 2.*index"),
    "index_bool": (_set(1, "index", True), r"line 2.*index"),
    "missing_status": (_drop(0, "status"), r"line 1.*'status'"),
    "missing_rows": (_drop(2, "rows"), r"line 3.*'rows'"),
    "missing_seed": (_drop(0, "seed"), r"line 1.*'seed'"),
    "rows_not_list": (_set(0, "rows", {"a": 1}), r"line 1.*rows"),
    "row_not_table": (_set(0, "rows", [3]), r"line 1.*rows\[0\]"),
    "ok_row_without_estimate": (_row(0, "estimate", drop=True), r"line 1.*rows\[0\].*'estimate'"),
    "ok_row_without_truth": (_row(0, "truth", drop=True), r"line 1.*rows\[0\].*'truth'"),
    "row_estimate_text": (_row(0, "estimate", "big"), r"line 1.*rows\[0\].*estimate"),
    "row_covered_text": (_row(0, "covered", "yes"), r"line 1.*rows\[0\].*covered"),
    "row_parameter_missing": (_row(1, "parameter", drop=True), r"line 2.*rows\[0\].*'parameter'"),
    "status_unknown": (_set(0, "status", "great"), r"line 1.*status"),
    "seed_wrong": (_set(0, "seed", 12), r"line 1.*seed"),
    "grid_point_wrong": (_set(0, "grid_point", 4), r"line 1.*grid_point"),
    "n_records_negative": (_set(0, "n_records", -3), r"line 1.*n_records"),
    "duplicate_other_outcome": (lambda lines: lines + [{**lines[0], "status": "failed", "rows": [],
                                                         "error": "campaign 0: x"}], r"line 4.*campaign 0.*line 1"),
    "line_not_object": (lambda text: ("[1, 2]\n" + text).encode(), r"line 1.*JSON object"),
}


@pytest.mark.parametrize("name", list(RESUME_CASES))
def test_resumed_campaigns_file_corpus(study_folder, capsys, name):
    plan, out = study_folder
    edit, pattern = RESUME_CASES[name]
    text = (out / "campaigns.jsonl").read_text()
    if edit.__code__.co_varnames[:1] == ("text",):
        _write_lines(out, None, raw=edit(text))
    else:
        _write_lines(out, edit(_lines(out)))
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    code, err = _run(["study", plan, "--out", out, "--quiet", "--no-report"], capsys)
    assert code == 2 and "campaigns.jsonl" in err and re.search(pattern, err), err
    assert len(err.strip().splitlines()) == 1, err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before  # nothing rewritten



# ------------------------------------------------------------------------------ backbone
@pytest.fixture(scope="module")
def results_json(tmp_path_factory):
    """A real results.json of a small identified campaign (the parsed dict)."""
    from jointid.app.paper_example import paper_config
    from jointid.app.synthesis import load_simulation_config, simulate_campaign

    root = tmp_path_factory.mktemp("res")
    cfg = paper_config(n_frequencies=7, fs=2000.0, periods=15, noise=0.01, seed=7)
    simulate_campaign(load_simulation_config(cfg), root / "camp")
    assert main(["identify", str(root / "camp"), "--out", str(root / "res"), "--quiet", "--figures", "none"]) == 0
    return json.loads((root / "res" / "results.json").read_text())


def _model(key, value=None, drop=False):
    def edit(r):
        if drop:
            del r["models"][0][key]
        else:
            r["models"][0][key] = value
        return r
    return edit


def _saved(key, value):
    def edit(r):
        r["backbones"]["preloads"][0][key] = value
        return r
    return edit


def _scaled_cov(r, diag=1.0, corner=None, correlation=None):
    """The model's covariance with its first variance times ``diag``, its [0][1] entry alone set to
    ``corner`` times the product of the two standard errors, or both off-diagonal [0][1] entries set to
    ``correlation`` times it."""
    import copy

    C = copy.deepcopy(r["models"][0]["covariance"])
    s01 = (C[0][0] * C[1][1]) ** 0.5
    C[0][0] *= diag
    if corner is not None:
        C[0][1] = corner * s01
    if correlation is not None:
        C[0][1] = C[1][0] = correlation * s01
    return C


# name: (edit of the parsed results, pattern of the message: the JSON path of the bad entry)
BACKBONE_CASES = {
    "list": (lambda r: [r], r"JSON object expected, got list"),
    "null": (lambda r: None, r"JSON object expected, got null"),
    "number": (lambda r: 3, r"JSON object expected, got int"),
    "models_text": (lambda r: {**r, "models": "abc"}, r"models: a list"),
    "model_not_object": (lambda r: {**r, "models": [3]}, r"models\[0\]: a model"),
    "model_without_terms": (lambda r: {**r, "models": [{k: v for k, v in r["models"][0].items() if k != "terms"}],
                                       "backbones": None}, r"models\[0\]: no 'terms'"),
    "parameters_short": (lambda r: _model("parameters", r["models"][0]["parameters"][:2])(r),
                         r"models\[0\]\.parameters: 2 values"),
    "parameters_text": (_model("parameters", ["a", "b", "c", "d", "e"]), r"models\[0\]\.parameters"),
    "parameters_inf": (lambda r: _model("parameters", [1e400] + r["models"][0]["parameters"][1:])(r),
                       r"models\[0\]\.parameters"),
    "covariance_1x1": (_model("covariance", [[1.0]]), r"models\[0\]\.covariance: a 5 x 5"),
    "covariance_text": (_model("covariance", "big"), r"models\[0\]\.covariance"),
    "law_unknown_term": (_model("amplitude_laws", {"zz": 2}), r"models\[0\]\.amplitude_laws: 'zz'"),
    "law_order_50": (_model("amplitude_laws", {"c": 50}), r"models\[0\]\.amplitude_laws\.c: an order"),
    "law_order_text": (_model("amplitude_laws", {"c": "two"}), r"models\[0\]\.amplitude_laws\.c"),
    "laws_list": (_model("amplitude_laws", [2]), r"models\[0\]\.amplitude_laws"),
    "terms_number": (_model("terms", 3), r"models\[0\]\.terms"),
    "terms_unknown": (_model("terms", ["q", "foo"]), r"models\[0\]\.terms"),
    "preload_list": (_model("preload", [1, 2]), r"models\[0\]\.preload"),
    "q_max_range_text": (_model("q_max_range", "wide"), r"models\[0\]\.q_max_range"),
    "q_max_range_reversed": (lambda r: _model("q_max_range", r["models"][0]["q_max_range"][::-1])(r),
                             r"models\[0\]\.q_max_range: .*0 < low <= high"),
    "covariance_negative_variance": (lambda r: _model("covariance", _scaled_cov(r, diag=-1.0))(r),
                                     r"models\[0\]\.covariance: the variance of omega1\^2 is negative"),
    "covariance_not_symmetric": (lambda r: _model("covariance", _scaled_cov(r, corner=0.5))(r),
                                 r"models\[0\]\.covariance: not symmetric"),
    "covariance_not_positive": (lambda r: _model("covariance", _scaled_cov(r, correlation=1.5))(r),
                                r"models\[0\]\.covariance: not positive semi-definite"),
    "backbones_text": (lambda r: {**r, "backbones": "x"}, r"backbones: a JSON object"),
    "preloads_text": (lambda r: {**r, "backbones": {"preloads": "abc"}}, r"backbones\.preloads: a list"),
    "preload_entry_number": (lambda r: {**r, "backbones": {"preloads": [5]}}, r"backbones\.preloads\[0\]"),
    "saved_model_text": (_saved("model", "curve"), r"backbones\.preloads\[0\]\.model"),
    "saved_amplitude_text": (_saved("stepped_sine", {"amplitude": ["a"], "omega": [1.0], "zeta": [0.1]}),
                             r"backbones\.preloads\[0\]\.stepped_sine\.amplitude"),
    "saved_lengths_differ": (_saved("stepped_sine", {"amplitude": [1.0, 2.0], "omega": [1.0], "zeta": [0.1, 0.2],
                                                     "omega_stderr": [0.1, 0.1], "zeta_stderr": [0.1, 0.1]}),
                             r"backbones\.preloads\[0\]\.stepped_sine\.omega: 1 values"),
    "saved_ringdown_text": (_saved("ringdown", "x"), r"backbones\.preloads\[0\]\.ringdown"),
}


@pytest.mark.parametrize("name", list(BACKBONE_CASES))
def test_backbone_results_corpus(results_json, tmp_path, capsys, name):
    import copy

    edit, pattern = BACKBONE_CASES[name]
    path = tmp_path / "results.json"
    path.write_text(json.dumps(edit(copy.deepcopy(results_json))))
    out = tmp_path / "bb"
    code, err = _run(["backbone", path, "--out", out, "--quiet"], capsys)
    assert code == 2 and str(path) in err and re.search(pattern, err), err
    assert len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_backbone_of_the_untouched_results_is_drawn(results_json, tmp_path, capsys):
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results_json))
    code, err = _run(["backbone", path, "--out", tmp_path / "bb", "--quiet"], capsys)
    assert code == 0 and list((tmp_path / "bb").glob("backbone_*.png")), err


def test_backbone_of_a_model_that_does_not_hold_exits_1_and_says_why(results_json, tmp_path, capsys):
    """Negative damping (a joint feeding energy in) and omega1^2 <= 0 (no oscillation): the backbone
    says what is wrong on stderr (also with --quiet) and exits 1; the measured points are still drawn."""
    import copy

    for edit, pattern in ((lambda p: p[:2] + [-0.08, 0.0, 0.0], r"model damping: the model's damping ratio is negative"),
                          (lambda p: [-abs(p[0])] + p[1:], r"model: the model has no oscillation")):
        r = copy.deepcopy(results_json)
        assert r["models"][0]["parameter_names"][:3] == ["omega1^2", "k3", "c0"]
        r["models"][0]["parameters"] = edit(r["models"][0]["parameters"])
        path = tmp_path / "results.json"
        path.write_text(json.dumps(r))
        out = tmp_path / "bb"
        code, err = _run(["backbone", path, "--out", out, "--quiet"], capsys)
        assert code == 1 and re.search(pattern, err), err
        assert (out / "backbones.json").is_file()


def test_backbone_output_is_one_set_never_a_mix_nor_the_users_files(results_json, tmp_path, capsys):
    """The backbone folder is an output set: a folder holding the user's files is refused (left as it
    was), and a second run replaces the first as a whole (no figure of the first run stays)."""
    import copy

    user = tmp_path / "mine"
    user.mkdir()
    (user / "backbone_simulated.png").write_text("my notes")
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results_json))
    code, err = _run(["backbone", path, "--out", user, "--quiet"], capsys)
    assert code == 2 and str(user) in err and (user / "backbone_simulated.png").read_text() == "my notes", err
    code, err = _run(["backbone", path, "--out", tmp_path, "--quiet"], capsys)  # the folder of its input
    assert code == 2 and path.is_file() and (user / "backbone_simulated.png").is_file(), err

    out = tmp_path / "bb"
    assert _run(["backbone", path, "--out", out, "--quiet"], capsys)[0] == 0
    first = sorted(p.name for p in out.iterdir())
    other = copy.deepcopy(results_json)
    for m in other["models"]:
        m["preload"] = "other"
    for e in other["backbones"]["preloads"]:
        e["preload"] = "other"
    path2 = tmp_path / "other.json"
    path2.write_text(json.dumps(other))
    assert _run(["backbone", path2, "--out", out, "--quiet"], capsys)[0] == 0
    second = sorted(p.name for p in out.iterdir())
    assert "backbone_other.png" in second and not set(first) & set(second) - {".jointid-run", "backbones.json"}
    assert json.loads((out / "backbones.json").read_text())["preloads"][0]["preload"] == "other"


def test_predict_refuses_a_model_without_oscillation(results_json, tmp_path, capsys):
    import copy

    r = copy.deepcopy(results_json)
    r["models"][0]["parameters"][0] = -abs(r["models"][0]["parameters"][0])
    path = tmp_path / "results.json"
    path.write_text(json.dumps(r))
    code, err = _run(["predict", path, "--force-levels", "1", "--out", tmp_path / "p", "--quiet"], capsys)
    assert code == 2 and "omega1^2 = -" in err and "no oscillation" in err, err
    assert not (tmp_path / "p").exists()


def test_backbone_results_not_utf8(tmp_path, capsys):
    path = tmp_path / "results.json"
    path.write_bytes(b'{"models": "\xff\xfe"}')
    code, err = _run(["backbone", path, "--out", tmp_path / "bb", "--quiet"], capsys)
    assert code == 2 and str(path) in err and not (tmp_path / "bb").exists(), err


# ----------------------------------------------------------------------------- simulate configurations
SIM = """
[[model]]
preload = 120
omega1 = 170.0
coefficients = { k3 = 5e6 }
amplitude_laws = { c = [0.08, 70.0, 1e4] }

[excitation]
force_levels = [1.0]
omega_start = 164.0
omega_stop = 176.0
n_frequencies = 3

[acquisition]
fs = 2000.0
periods = 10
"""


@pytest.mark.parametrize("edit, pattern", [
    (('fs = 2000.0', 'fs = "fast"'), r"\[acquisition\] fs: expected a finite number"),
    (('periods = 10', 'periods = 10\nnoize = 0.01'), r"unknown key 'noize'; did you mean 'noise'"),
    (('n_frequencies = 3', 'n_frequencies = 2.5'), r"n_frequencies: expected an integer"),
    (('force_levels = [1.0]', 'force_levels = [inf]'), r"force_levels: expected a list"),
    (('amplitude_laws = { c = [0.08, 70.0, 1e4] }', 'amplitude_laws = { c = "power" }'), r"power law is not simulated"),
    (('[excitation]', '[excitaton]'), r"unknown table 'excitaton'; did you mean 'excitation'"),
    (('[acquisition]', 'acquisition = 3\n[acq]'), r"(acquisition\] must be a table|unknown table 'acq')"),
])
def test_simulate_configuration_checked_like_a_study_plan(tmp_path, capsys, edit, pattern):
    """``jointid simulate``: the same table checks as a study plan (traceback or silent acceptance before)."""
    (tmp_path / "c.toml").write_text(SIM.replace(*edit))
    code, err = _run(["simulate", tmp_path / "c.toml", "--out", tmp_path / "camp"], capsys)
    assert code == 2 and re.search(pattern, err) and "c.toml" in err, err
    assert not (tmp_path / "camp").exists()
    (tmp_path / "ok.toml").write_text(SIM)
    assert main(["simulate", str(tmp_path / "ok.toml"), "--out", str(tmp_path / "ok"), "--quiet"]) == 0
