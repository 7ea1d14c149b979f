"""A physical campaign (force + two accelerometers) gives the same identification as the modal one."""

import warnings

import numpy as np
import pytest

from jointid.cli import main
from jointid.app.paper_example import paper_config
from jointid.errors import StructureError
from jointid.io.campaign import load_campaign, read_record, write_campaign, write_csv_record
from jointid.modal.structure import Structure
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign

STRUCTURE = {"model": "seed-bolted-beam", "preload": 120, "force_column": "force",
             "sensors": {"accel_30": 0.30, "accel_42": 0.42}}


def test_physical_campaign_matches_modal(tmp_path):
    cfg = paper_config(n_frequencies=11, noise=0.0, periods=12)
    modal = simulate_campaign(load_simulation_config(cfg), tmp_path / "modal")
    structure = Structure.from_mapping(STRUCTURE, source="test")
    phi_f = structure.phi_force[0]
    phi_s = dict(zip(structure.sensors, structure.phi_sensors[:, 0]))
    entries = []
    for spec in load_campaign(modal).records:
        rec = read_record(spec)
        Q, qdd = rec.channels["force"], rec.channels["accel"]
        write_csv_record(tmp_path / "phys" / spec.file, rec.time,
                         {"force": Q / phi_f, "accel_30": phi_s["accel_30"] * qdd, "accel_42": phi_s["accel_42"] * qdd})
        entries.append({"file": spec.file, "frequency_hz": spec.frequency_hz, "force_level": spec.force_level,
                        "preload": spec.preload})
    write_campaign(tmp_path / "phys", "physical", entries, coordinates="physical", structure=STRUCTURE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rm = identify_campaign(modal, n_harmonics=7)
        rp = identify_campaign(tmp_path / "phys", n_harmonics=7)
    gm, gp = rm.groups[0], rp.groups[0]
    assert gp.pooled.omega1 == pytest.approx(gm.pooled.omega1, rel=1e-10)
    assert gp.pooled.k3 == pytest.approx(gm.pooled.k3, rel=1e-7)
    assert np.allclose(gp.pooled.get("c"), gm.pooled.get("c"), rtol=1e-8)
    assert all(r.modal_residual < 1e-12 for r in rp.records)
    assert main(["identify", str(tmp_path / "phys"), "--out", str(tmp_path / "o"), "--quiet", "--no-figures"]) == 0


def test_physical_campaign_bad_structure_and_columns(tmp_path):
    t = np.arange(2000) / 1000.0
    write_csv_record(tmp_path / "r.csv", t, {"force": np.sin(2 * np.pi * 26 * t), "accel_30": np.sin(2 * np.pi * 26 * t)})
    bad = dict(STRUCTURE, sensors={"accel_30": 0.30, "accel_42": 0.42})
    write_campaign(tmp_path, "missing sensor column", [{"file": "r.csv", "preload": 1, "force_level": 1}],
                   coordinates="physical", structure=bad)
    with pytest.warns(Warning):
        res = identify_campaign(tmp_path)
    assert res.records[0].status == "failed" and "accel_42" in res.records[0].error
    outside = dict(STRUCTURE, sensors={"accel_99": 0.99})
    write_campaign(tmp_path, "bad", [{"file": "r.csv"}], coordinates="physical", structure=outside)
    with pytest.raises(StructureError, match="accel_99"):
        identify_campaign(tmp_path)


def test_swapped_sensors_are_flagged_by_the_modal_residual(tmp_path):
    """Every record with its two accelerometer columns swapped: the mode shape at the sensors explains 40 %
    of the accelerations; each record is flagged modal_residual (it was identified with k3 2.5x off and no
    flag), the correct campaign is not."""
    cfg = paper_config(n_frequencies=5, noise=0.0, periods=12)
    modal = simulate_campaign(load_simulation_config(cfg), tmp_path / "modal")
    structure = Structure.from_mapping(STRUCTURE, source="test")
    phi_f = structure.phi_force[0]
    phi_s = dict(zip(structure.sensors, structure.phi_sensors[:, 0]))
    for name, swap in (("right", False), ("swapped", True)):
        entries = []
        for spec in load_campaign(modal).records:
            rec = read_record(spec)
            a30, a42 = phi_s["accel_30"] * rec.channels["accel"], phi_s["accel_42"] * rec.channels["accel"]
            if swap:
                a30, a42 = a42, a30
            write_csv_record(tmp_path / name / spec.file, rec.time,
                             {"force": rec.channels["force"] / phi_f, "accel_30": a30, "accel_42": a42})
            entries.append({"file": spec.file, "frequency_hz": spec.frequency_hz, "force_level": spec.force_level,
                            "preload": spec.preload})
        write_campaign(tmp_path / name, name, entries, coordinates="physical", structure=STRUCTURE)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = identify_campaign(tmp_path / name, n_harmonics=5, repredict=False)
        flagged = [r for r in res.records if any(f.name == "modal_residual" for f in r.flags)]
        assert len(flagged) == (len(res.records) if swap else 0), name
        if swap:
            assert all(0.3 < r.modal_residual < 0.9 for r in res.records)
