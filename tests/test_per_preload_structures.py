"""One physical campaign at several preloads: a structure per preload, Tables 4 and 5 in one run."""

from __future__ import annotations

import copy
import shutil
import warnings

import numpy as np
import pytest

from jointid.app.paper_example import paper_config
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign
from jointid.errors import ManifestError
from jointid.io.campaign import load_campaign, read_record, write_campaign, write_csv_record
from jointid.modal.structure import Structure


def _structure(preload):
    return {"model": "seed-bolted-beam", "preload": preload, "force_column": "force",
            "sensors": {"accel_30": 0.30, "accel_42": 0.42}}


@pytest.fixture(scope="module")
def modal_campaign(tmp_path_factory):
    """A modal campaign at two preloads (the paper's model with two natural frequencies)."""
    cfg = paper_config(n_frequencies=9, noise=0.0, periods=12)
    m120 = copy.deepcopy(cfg["model"][0])
    m120["preload"] = 120
    m540 = dict(copy.deepcopy(m120), preload=540, omega1=172.0)
    cfg["model"] = [m120, m540]
    return simulate_campaign(load_simulation_config(cfg), tmp_path_factory.mktemp("pp") / "modal")


def _physical(modal, folder, preloads, structures):
    """Each record of ``preloads`` in physical channels with its preload's structure."""
    entries = []
    for spec in load_campaign(modal).records:
        if spec.preload not in preloads:
            continue
        s = Structure.from_mapping(_structure(spec.preload), source="test")
        rec = read_record(spec)
        Q, qdd = rec.channels["force"], rec.channels["accel"]
        phi = dict(zip(s.sensors, s.phi_sensors[:, 0]))
        write_csv_record(folder / spec.file, rec.time, {"force": Q / s.phi_force[0], "accel_30": phi["accel_30"] * qdd,
                                                        "accel_42": phi["accel_42"] * qdd})
        entries.append({"file": spec.file, "frequency_hz": spec.frequency_hz, "force_level": spec.force_level,
                        "preload": spec.preload})
    write_campaign(folder, folder.name, entries, coordinates="physical", structure=structures)
    return folder


def _identify(folder):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify_campaign(folder, n_harmonics=7, repredict=False)


def test_two_preloads_in_one_campaign_equal_two_single_preload_campaigns(modal_campaign, tmp_path):
    both = _physical(modal_campaign, tmp_path / "both", (120, 540), {"120": _structure(120), "540": _structure(540)})
    res = _identify(both)
    assert not res.failed and len(res.groups) == 2
    # Table 4: each preload has its own structure (the joint stiffness depends on the preload)
    f4 = {p: s.modes.frequencies_hz for p, s in res.structures.items()}
    assert set(f4) == {120, 540} and f4[540][0] > f4[120][0]
    table4 = res.summary()["structures"]
    assert [row["preload"] for row in table4] == [120, 540] and all("frequencies_hz" in row for row in table4)
    for p in (120, 540):
        single = _identify(_physical(modal_campaign, tmp_path / f"only_{p}", (p,), _structure(p)))
        (g1,) = single.groups
        g2 = res.group(p, g1.force_level)
        assert g2.pooled.omega1 == pytest.approx(g1.pooled.omega1, rel=1e-12)
        assert g2.pooled.k3 == pytest.approx(g1.pooled.k3, rel=1e-10)
        assert np.allclose(g2.pooled.get("c"), g1.pooled.get("c"), rtol=1e-10)
        assert res.damping_laws[p].coefficients == pytest.approx(single.damping_laws[p].coefficients, rel=1e-8)
    # the modal coordinates are right only with each preload's own structure: omega1 as simulated
    assert res.group(120, 1.0).pooled.omega1 == pytest.approx(170.0, rel=1e-6)
    assert res.group(540, 1.0).pooled.omega1 == pytest.approx(172.0, rel=1e-6)


def test_structure_files_per_preload_and_a_missing_preload(modal_campaign, tmp_path):
    folder = tmp_path / "files"
    for p in (120, 540):
        folder.mkdir(exist_ok=True)
        (folder / f"structure_{p}.toml").write_text(
            f'[structure]\nmodel = "seed-bolted-beam"\npreload = {p}\nforce_column = "force"\n'
            '[structure.sensors]\naccel_30 = 0.30\naccel_42 = 0.42\n')
    _physical(modal_campaign, folder, (120, 540), {"120": {"file": "structure_120.toml"},
                                                  "540": {"file": "structure_540.toml"}})
    res = _identify(folder)
    assert res.group(540, 1.0).pooled.omega1 == pytest.approx(172.0, rel=1e-6)
    missing = tmp_path / "missing"
    shutil.copytree(folder, missing)
    _physical(modal_campaign, missing, (120, 540), {"120": {"file": "structure_120.toml"}})
    with pytest.raises(ManifestError, match=r"540"):
        _identify(missing)


@pytest.mark.slow
def test_two_preload_rig_campaign_gives_the_demo_table5(tmp_path, demo_run):
    """The demo's two single-preload rig campaigns joined into one: the same Table 5 in one run."""
    demo = demo_run
    joined = tmp_path / "joined"
    entries, structures = [], {}
    for pr in demo.preloads:
        sub = f"preload_{pr.preload:g}"
        shutil.copytree(pr.campaign.folder, joined / sub)
        for spec in load_campaign(joined / sub).records:
            entries.append({"file": f"{sub}/{spec.file}", "frequency_hz": spec.frequency_hz,
                            "force_level": spec.force_level, "preload": spec.preload})
        structures[f"{pr.preload:g}"] = {"file": f"{sub}/campaign.toml"}
    write_campaign(joined, "two preloads", entries, coordinates="physical", structure=structures)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(joined, demo.settings.identify)
    assert not res.failed
    for pr in demo.preloads:
        for g1 in pr.result.groups:
            g2 = res.group(g1.preload, g1.force_level)
            assert g2.pooled.omega1 == pytest.approx(g1.pooled.omega1, rel=1e-12)
            assert g2.pooled.k3 == pytest.approx(g1.pooled.k3, rel=1e-9)
            assert g2.power_law.n == pytest.approx(g1.power_law.n, rel=1e-9)
        assert res.structures[pr.preload].modes.frequencies_hz == pytest.approx(
            pr.structure.modes.frequencies_hz, rel=1e-12)
