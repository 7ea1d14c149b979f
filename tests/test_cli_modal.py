import json

import numpy as np

from jointid.cli import main
from jointid.io.campaign import write_csv_record
from jointid.modal.analysis import modal_analysis, simulate_beam_response
from jointid.modal.beam import seed_bolted_beam

STRUCTURE = """
[structure]
model = "seed-bolted-beam"
preload = 120
[structure.sensors]
accel_30 = 0.30
accel_42 = 0.42
"""


def test_modal_command_prints_modes_and_fits_an_frf(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(STRUCTURE)
    modes = modal_analysis(seed_bolted_beam(120).assemble(), n_modes=6)
    fs = 2048.0
    rng = np.random.default_rng(0)
    force = rng.standard_normal(int(120 * fs))
    resp = simulate_beam_response(modes, force, fs, 0.05, [0.42], damping_ratio=0.01, n_modes=3, method="fft")
    t = np.arange(force.size) / fs
    write_csv_record(tmp_path / "random.csv", t, {"force": force, "accel_42": np.asarray(resp.response)[0]})
    code = main(["modal", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o"), "--frf", str(tmp_path / "random.csv"),
                 "--response", "accel_42", "--modes", "3"])
    assert code == 0
    out = capsys.readouterr().out
    assert "FE frequencies" in out and "mode 1" in out
    data = json.loads((tmp_path / "o" / "modal.json").read_text())
    f = np.array(data["frf_fit"]["frequencies_hz"])
    assert np.allclose(f, [26.4, 157.6, 471.8], rtol=2e-3)
    assert (tmp_path / "o" / "mode_shapes.png").is_file() and (tmp_path / "o" / "frf.png").is_file()


def test_modal_command_bad_structure(tmp_path, capsys):
    (tmp_path / "s.toml").write_text("[structure]\nmodel = 'seed-bolted-beam'\n[structure.sensors]\nfar = 0.9\n")
    assert main(["modal", str(tmp_path / "s.toml")]) == 2
    assert "far" in capsys.readouterr().err
