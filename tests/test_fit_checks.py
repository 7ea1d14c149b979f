"""Goodness of fit of the campaign-level regressions (results.json fit_checks) and the exit status."""

from __future__ import annotations

import contextlib
import io
import json
from types import SimpleNamespace

import numpy as np
import pytest

from jointid.app.fit_checks import CHI2_DOF_LIMIT, P_LIMIT, fit_checks, misfit_lines, misfits
from jointid.cli import main
from jointid.identify.delay import ChannelDelay
from jointid.identify.laws import DampingLaw


def _law(chi2, dof):
    n = dof + 2
    return DampingLaw(np.array([0.3, 100.0]), np.array([1e-3, 0.1]), np.linspace(1e-3, 1e-2, n), np.ones(n),
                      np.full(n, 1e-3), None, chi2, dof)


@pytest.mark.parametrize("chi2, dof, fits", [
    (649.25, 2, False),          # the UNESP dwells: chi2/dof 325, p = 1e-141
    (4.0, 2, True),              # within the noise
    (1.3 * 20000, 20000, True),  # p tiny but a scatter only 14 % above the errors: not called a misfit
    (3.0 * 100, 100, False),
])
def test_damping_law_check(chi2, dof, fits):
    (c,) = fit_checks(SimpleNamespace(damping_laws={5: _law(chi2, dof)}, channel_delay=None))
    assert c["fits"] is fits and c["check"] == "damping_law" and c["preload"] == 5 and c["dof"] == dof
    assert (c["p_value"] < P_LIMIT and c["chi2_dof"] > CHI2_DOF_LIMIT) is (not fits)
    lines = misfit_lines({"fit_checks": [c]})
    assert bool(lines) is (not fits)
    if not fits:
        assert "does not fit" in lines[1] and "understate" in lines[1]


def test_a_stand_ins_damping_law_beside_a_selected_hysteretic_law_is_not_a_misfit():
    """--terms auto picked a hysteretic law at preload 5: the damping law there is the polynomial stand-in's."""
    sel = {5: SimpleNamespace(hysteretic_model=object()), 6: SimpleNamespace(hysteretic_model=None)}
    c5, c6 = fit_checks(SimpleNamespace(damping_laws={5: _law(649.25, 2), 6: _law(649.25, 2)}, channel_delay=None,
                                        selections=sel))
    assert c5["fits"] is False and c5["stand_in"] is True and "stand-in" in c5["label"]
    assert c6["fits"] is False and "stand_in" not in c6
    assert misfits([c5, c6]) == [c6]
    lines = misfit_lines({"fit_checks": [c5, c6]})
    assert len(lines) == 2 and "preload 6" in lines[1]


def test_immaterial_misfit_of_noise_free_data_fits():
    """Values on the law to 1e-13 with standard errors at rounding level: a huge chi2, no misfit."""
    q = np.linspace(1e-3, 1e-2, 6)
    c = 0.3 + 100 * q
    law = DampingLaw(np.array([0.3, 100.0]), np.array([1e-15, 1e-13]), q, c * (1 + 1e-13 * (-1) ** np.arange(6)),
                     np.full(6, 1e-16), None, 800.0, 4)
    (c_,) = fit_checks(SimpleNamespace(damping_laws={1: law}, channel_delay=None))
    assert c_["fits"] is True and c_["relative_rms_residual"] < 1e-12 and "noise-free" in c_["message"]


def test_channel_delay_check_and_what_has_none():
    d = ChannelDelay(-7.7e-4, 5e-6, reduced_chi2=649.0, dof=1, n_dwells=4)
    res = SimpleNamespace(damping_laws={1: None, 2: _law(float("nan"), 0)}, channel_delay=d)
    (c,) = fit_checks(res)  # no law, a law without degrees of freedom: nothing to check
    assert c["check"] == "channel_delay" and c["fits"] is False and "scaled" in c["message"]
    given = SimpleNamespace(damping_laws={}, channel_delay=ChannelDelay(1e-4, 0.0, source="given"))
    assert fit_checks(given) == []


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, err.getvalue()


CONFIG = """
[campaign]
name = "damping law check"
[[model]]
preload = 1
omega1 = 170.0
coefficients = {{ k3 = 5e6 }}
amplitude_laws = {{ c = [0.08, 70.0, {c2}] }}
[excitation]
force_levels = [1.0, 2.0]
omega_start = 162.0
omega_stop = 178.0
n_frequencies = 9
[acquisition]
fs = 3000.0
periods = 12.5
noise = 0.002
seed = 3
"""


@pytest.mark.parametrize("order, exit_code", [(2, 0), (0, 1)])
def test_identify_exits_1_when_the_damping_law_does_not_fit(tmp_path, order, exit_code):
    """c(q_max) = 0.08 + 70 q + 3e4 q^2 fitted as a constant does not fit (exit 1); as a quadratic it does (exit 0)."""
    cfg = tmp_path / "sim.toml"
    cfg.write_text(CONFIG.format(c2=3e4))
    assert main(["simulate", str(cfg), "--out", str(tmp_path / "camp"), "--quiet"]) == 0
    code, err = _run(["identify", str(tmp_path / "camp"), "--out", str(tmp_path / "res"), "--quiet",
                      "--no-figures", "--no-reprediction", "--damping-order", str(order)])
    res = json.loads((tmp_path / "res" / "results.json").read_text())
    (c,) = res["fit_checks"]
    assert not res["flagged"] and res["n_failed"] == 0
    assert code == exit_code and c["fits"] is (exit_code == 0)
    assert ("does not fit" in err) is (exit_code == 1)
