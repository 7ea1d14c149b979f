"""The structure description built from a plain (TOML) dict."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from jointid.errors import RecordError, StructureError
from jointid.modal import SEED_TABLE4_HZ, Structure, modal_analysis, seed_bolted_beam

TOML = """
[campaign]
coordinates = "physical"

[structure]
model = "seed-bolted-beam"
preload = 120
force_position = 0.05

[structure.sensors]
accel_30 = 0.30
accel_42 = 0.42
"""


def _signals(n=64, seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n), {"accel_30": rng.standard_normal(n), "accel_42": rng.standard_normal(n)}


def test_seed_model_from_toml_matches_direct_computation():
    d = tomllib.loads(TOML)
    st = Structure.from_mapping(d["structure"], source="campaign.toml")
    assert Structure.from_mapping(d, source="campaign.toml").phi_force == pytest.approx(st.phi_force)  # whole file
    modes = modal_analysis(seed_bolted_beam(120), 6)
    assert st.phi_force[0] == pytest.approx(modes.shape_at([0.05], 0)[0], rel=1e-12)
    assert np.allclose(st.phi_sensors[:, 0], modes.shape_at([0.30, 0.42], 0), rtol=1e-12)
    assert st.required_columns == ("force", "accel_30", "accel_42")
    F, acc = _signals()
    Q, qdd, res = st.to_modal(F, acc)
    a = np.vstack([acc["accel_30"], acc["accel_42"]])
    phi = st.phi_sensors[:, 0]
    assert np.allclose(qdd, phi @ a / (phi @ phi))
    assert np.allclose(Q, st.phi_force[0] * F)
    assert 0 <= res <= 1
    # a record's channel dict (what the campaign workflow passes), extra columns ignored
    Q2, qdd2, res2 = st.to_modal({"force": F, "other": F, **acc})
    assert np.allclose(Q2, Q) and np.allclose(qdd2, qdd) and res2 == pytest.approx(res)
    json.dumps(st.summary())
    assert "accel_42" in st.report()


def test_fe_model_updated_to_frequencies():
    d = {
        "model": "seed-bolted-beam",
        "update_to_hz": list(SEED_TABLE4_HZ[540]),
        "update_parameters": ["k_w", "k_t", "k_c"],
        "sensors": {"accel_30": 0.30, "accel_42": 0.42},
    }
    st = Structure.from_mapping(d, source="t.toml")
    assert st.update is not None and st.update.max_abs_relative_residual < 0.005
    assert np.allclose(st.modes.frequencies_hz[:3], SEED_TABLE4_HZ[540], rtol=0.005)
    assert st.force_position == 0.05  # the seed's default


def test_explicit_beam_and_joint_without_model():
    d = {
        "beam": {"length": 0.42, "width": 0.0254, "thickness": 0.00636, "youngs_modulus": 210e9, "density": 7850.0,
                 "clamp_stiffness": 4284.843},
        "joint": {"k_w": 2.88809e6, "k_t": 2841.845},
        "force_position": 0.05,
        "sensors": {"a": 0.3, "b": 0.42},
    }
    st = Structure.from_mapping(d)
    assert np.allclose(st.modes.frequencies_hz[:3], SEED_TABLE4_HZ[120], rtol=1e-5)
    d2 = {**d, "joint": {**d["joint"]}}
    del d2["joint"]
    st2 = Structure.from_mapping(d2)  # no joint: a continuous beam
    assert st2.modes.fe.joint_nodes is None


def test_explicit_mode_shape():
    d = {"force_column": "F", "mode_shape": {"force": 0.1, "accel_30": 1.6, "accel_42": 2.7},
         "sensors": {"accel_30": 0.30, "accel_42": 0.42}}
    st = Structure.from_mapping(d)
    assert st.required_columns == ("F", "accel_30", "accel_42")
    F = np.ones(5)
    acc = {"accel_30": 1.6 * np.arange(5.0), "accel_42": 2.7 * np.arange(5.0)}
    Q, qdd, res = st.to_modal(F, acc)
    assert np.allclose(Q, 0.1) and np.allclose(qdd, np.arange(5.0)) and res < 1e-12
    # two modes per key
    st2 = Structure.from_mapping({"mode_shape": {"force": [0.1, 0.3], "s1": [1.0, 1.0], "s2": [2.0, -1.0],
                                                 "s3": [2.5, -2.0]}})
    assert st2.n_basis == 2 and st2.sensors["s1"] is None


def _err(d, match, source="campaign.toml"):
    with pytest.raises(StructureError, match=match) as info:
        Structure.from_mapping(d, source=source)
    assert source in str(info.value)
    return info


BASE = {"model": "seed-bolted-beam", "preload": 120, "sensors": {"accel_30": 0.30, "accel_42": 0.42}}


def test_negative_length():
    _err({**BASE, "beam": {"length": -0.42}}, r"structure\.beam\.length")


def test_sensor_outside_beam():
    _err({**BASE, "sensors": {"accel_30": 0.30, "accel_99": 0.99}}, r"structure\.sensors\.accel_99.*outside the beam")


def test_mode_shape_zero_at_force_point():
    _err({**BASE, "force_position": 0.0}, r"structure\.force_position.*~0")
    _err({**BASE, "force_position": 1e-4}, r"structure\.force_position.*~0")
    _err({"mode_shape": {"force": 0.0, "a": 1.0, "b": 2.0}}, r"structure\.mode_shape\.force.*~0")


def test_unknown_column_name():
    st = Structure.from_mapping(BASE, source="campaign.toml")
    F, acc = _signals()
    with pytest.raises(StructureError, match="'accel_99'.*unknown column") as info:
        st.to_modal(F, {**acc, "accel_99": acc["accel_30"]})
    assert "campaign.toml" in str(info.value)
    with pytest.raises(StructureError, match="'accel_42'.*missing"):
        st.to_modal(F, {"accel_30": acc["accel_30"]})
    with pytest.raises(StructureError, match="'force'.*missing"):
        st.to_modal(acc)
    _err({"mode_shape": {"force": 0.1, "accel_31": 1.0}, "sensors": {"accel_30": 0.3}},
         r"structure\.mode_shape\.accel_31: unknown column")


def test_other_bad_input():
    _err({**BASE, "colour": "red"}, r"structure\.colour: unknown key")
    _err({**BASE, "beam": {"lenght": 0.42}}, r"structure\.beam\.lenght: unknown key")
    _err({**BASE, "model": "my-beam"}, r"structure\.model: unknown model")
    _err({**BASE, "preload": 300}, r"structure\.preload")
    _err({"beam": {"length": 0.42}, "sensors": {"a": 0.3}, "force_position": 0.05}, r"structure\.beam\.width: required")
    _err({**BASE, "sensors": {}}, r"structure\.sensors: at least one sensor")
    _err({**BASE, "basis_modes": 3}, r"basis_modes")
    _err({**BASE, "joint": {"k_w": -1.0}}, r"structure\.joint\.k_w")
    _err({**BASE, "mode_shape": {"force": 1.0, "a": 1.0}}, r"either an FE model or mode_shape")
    st = Structure.from_mapping(BASE)
    with pytest.raises(RecordError):
        st.to_modal(np.ones(3), {"accel_30": np.ones(4), "accel_42": np.ones(4)})
