"""Plots of mode shapes, FRFs and updating residuals (Agg backend)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from jointid.modal import SEED_TABLE4_HZ, modal_analysis, seed_bolted_beam, update_to_frequencies  # noqa: E402
from jointid.report.modal_plots import plot_frf, plot_mode_shapes, plot_update_residuals  # noqa: E402
from jointid.signal.frf import fit_modes, modal_frf  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def test_plot_mode_shapes(tmp_path):
    m = modal_analysis(seed_bolted_beam(120), 4)
    fig, ax = plot_mode_shapes(m, sensors={"a": 0.3, "b": 0.42}, force_position=0.05)
    assert len(ax.get_legend().get_texts()) == 3 + 3  # three modes, joint, sensors, force
    fig.savefig(tmp_path / "modes.png")
    fig2, ax2 = plt.subplots()
    out_fig, out_ax = m.plot(ax=ax2, modes=[0])
    assert out_ax is ax2 and out_fig is fig2


def test_plot_frf_with_fit():
    f = np.linspace(1, 300, 3000)
    wr = 2 * np.pi * np.array([30.0, 150.0])
    H = modal_frf(f, wr, 0.01, [0.2, 0.4], [1.0, -0.8])
    fit = fit_modes((f, H), 2)
    fig, axes = plot_frf((f, H, np.ones_like(f)), fit=fit, f_max=250)
    assert len(axes) == 3
    fig, axes = plot_frf((f, H), coherence=False)
    assert len(axes) == 2


def test_plot_update_residuals():
    r = update_to_frequencies(seed_bolted_beam(), SEED_TABLE4_HZ[120], ("k_w", "k_t"), n_starts=2)
    fig, ax = r.plot()
    assert len(ax.patches) == 3
    fig2, ax2 = plt.subplots()
    assert plot_update_residuals(r, ax=ax2) == (fig2, ax2)


def test_figures_drawn_for_a_report_are_not_kept_by_pyplot():
    """A report draws many figures in one process; pyplot would keep every one of them alive."""
    from jointid.simulate import frequency_response, seed_model

    open_before = plt.get_fignums()
    plot_mode_shapes(modal_analysis(seed_bolted_beam(120), 2))
    f = np.linspace(20, 40, 200)
    plot_frf((f, modal_frf(f, [2 * np.pi * 30.0], 0.01, [0.2], [1.0])), coherence=False)
    frequency_response(seed_model(), 1.0, np.linspace(160, 180, 5)).plot()
    assert plt.get_fignums() == open_before
