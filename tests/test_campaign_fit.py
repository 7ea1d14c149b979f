"""The campaign fit is one step that every identification path calls once; the modal command's workflow is an
app function."""

from __future__ import annotations

import json
import warnings

import pytest

import jointid.app.workflow as workflow
from jointid.app.paper_example import paper_config
from jointid.app.synthesis import load_simulation_config, simulate_campaign


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    cfg = paper_config(n_frequencies=5, fs=2000.0, periods=12, noise=0.01, seed=3)
    return simulate_campaign(load_simulation_config(cfg), tmp_path_factory.mktemp("fit") / "campaign")


def _counted(monkeypatch):
    calls = {"fit_campaign": 0, "process_all": 0}
    fit, process = workflow.fit_campaign, workflow.process_all

    def fit_campaign(*a, **kw):
        calls["fit_campaign"] += 1
        return fit(*a, **kw)

    def process_all(*a, **kw):
        calls["process_all"] += 1
        return process(*a, **kw)

    monkeypatch.setattr(workflow, "fit_campaign", fit_campaign)
    monkeypatch.setattr(workflow, "process_all", process_all)
    return calls


@pytest.mark.parametrize("terms", ["q - q^3 + q'", "auto"])
def test_each_path_fits_the_campaign_once(campaign, monkeypatch, terms):
    """Plain terms and terms='auto' (records processed once with the seed's terms for the selection, once with
    the selected terms): one campaign fit either way, and the estimated delay's search does not run the chain."""
    calls = _counted(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = workflow.identify_campaign(campaign, terms=terms, channel_delay="estimate", repredict=False)
    assert calls == {"fit_campaign": 1, "process_all": 2 if terms == "auto" else 1}
    d = json.loads(json.dumps(res.summary(), default=str))
    assert d["groups"] and d["damping_law"][0]["coefficients"] is not None
    if terms == "auto":  # a single force level: no cross-validation, the reason is kept
        assert d["selection"][0]["selected"] is None and "force levels" in d["selection"][0]["error"]
    assert all("energy_measured" in r for r in d["records"] if r["status"] == "ok")


def test_modal_workflow_is_an_app_function(tmp_path, capsys):
    from jointid.app.modal_workflow import ModalRun, modal_workflow, parse_bands, write_modal
    from jointid.errors import IdentificationError

    (tmp_path / "s.toml").write_text('[structure]\nmodel = "seed-bolted-beam"\npreload = 120\n'
                                     '[structure.sensors]\naccel_42 = 0.42\n')
    run = modal_workflow(tmp_path / "s.toml")
    assert isinstance(run, ModalRun) and run.fit is None and "FE frequencies" in run.report()
    paths = write_modal(run, tmp_path / "out")
    assert json.loads(paths[0].read_text()) == json.loads(json.dumps(run.summary()))
    assert parse_bands("24-29, 140-175") == [(24.0, 29.0), (140.0, 175.0)]
    with pytest.raises(IdentificationError, match="LO < HI"):
        parse_bands("29-24")
