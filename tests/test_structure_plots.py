"""report/structure_plots: a structure model's figures draw what they are given (issue 21)."""

from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np

from jointid.report.structure_plots import plot_backbones, plot_structure_frf, plot_update_fit


def _level(F, scale, error=""):
    f = np.linspace(70.0, 80.0, 11)
    amp = {d: list(scale * k / (1.0 + (f - 75.0) ** 2)) for k, d in ((1.0, "A.w0"), (2.0, "B.phi"))}
    peaks = {d: {"peak_frequency_hz": 75.0, "peak_amplitude": max(a)} for d, a in amp.items()}
    return NS(force_level=F, error=error, frequency_hz=list(f), amplitude=amp, peaks=peaks)


def _prediction(backbones=()):
    units = {"A.w0": "m", "B.phi": "rad"}
    return NS(model={"name": "lap", "response": ["A.w0", "B.phi"]},
              levels=[_level(0.5, 1e-6), _level(5.0, 1e-3, error="did not converge"), _level(2.0, 4e-6)],
              backbones=list(backbones), unit=units.get)


def _backbone(mode, n):
    a = list(np.geomspace(1e-6, 1e-3, n))
    return NS(mode=mode, amplitude=a, frequency_hz=list(75.0 - np.arange(n)), damping_ratio=list(np.full(n, 0.01)),
              response_amplitude={"A.w0": list(a), "B.phi": list(2 * np.array(a))})


def test_structure_frf_one_panel_per_dof_with_units_failed_levels_skipped():
    fig = plot_structure_frf(_prediction([_backbone(3, 5), _backbone(4, 0)]))
    ax1, ax2 = fig.axes
    assert ax1.get_ylabel() == "|A.w0| first harmonic [m]" and ax2.get_ylabel() == "|B.phi| first harmonic [rad]"
    assert ax2.get_xlabel() == "frequency [Hz]" and ax1.get_title().startswith("lap: multi-harmonic balance")
    # the failed 5 N level is not drawn; the empty backbone (mode 4) neither
    assert [t.get_text() for t in ax1.get_legend().get_texts()] == ["F = 0.5 N", "F = 2 N", "backbone, mode 3"]
    # y range from the drawn levels only (the failed one is 250 times larger)
    assert np.isclose(ax2.get_ylim()[1], 1.1 * 2 * 4e-6)
    dashed = [ln for ln in ax2.lines if ln.get_linestyle() == "--"]
    assert len(dashed) == 1 and np.allclose(dashed[0].get_ydata(), 2 * np.geomspace(1e-6, 1e-3, 5))


def test_backbones_figure_only_when_a_backbone_has_points():
    assert plot_backbones([_backbone(3, 0)], "lap") is None
    fig = plot_backbones([_backbone(3, 4), _backbone(5, 0)], "lap")
    ax1, ax2 = fig.axes
    assert ax1.get_xscale() == "log" and ax2.get_ylabel() == "damping ratio"
    assert [t.get_text() for t in ax1.get_legend().get_texts()] == ["mode 3"]
    assert "lap: nonlinear modes" in fig._suptitle.get_text()


def test_update_fit_sorted_curves_error_bars_and_units():
    f = np.array([23.0, 22.0, 24.0, 22.0, 23.0, 24.0])
    lv = np.array([1.0, 1.0, 1.0, 2.5, 2.5, 2.5])
    X = (1 + 0.1j) * lv * f
    meas = NS(force_level=lv, frequency_hz=f, dof=("x2",) * 6, X=X, se=0.01 * np.abs(X), levels=lambda: [1.0, 2.5])
    fig = plot_update_fit(meas, 1.02 * X, joint="slip", law="Jenkins", response_units={"x2": "mm"})
    (ax,) = fig.axes
    assert ax.get_ylabel() == "|x2| first harmonic [mm]" and ax.get_title() == "slip: updated Jenkins (dots: measured)"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["F = 1 N, fitted", "F = 2.5 N, fitted"]
    model_lines = [ln for ln in ax.lines if ln.get_label().endswith("fitted")]
    np.testing.assert_allclose(model_lines[0].get_xdata(), [22.0, 23.0, 24.0])  # sorted by frequency
    np.testing.assert_allclose(model_lines[0].get_ydata(), 1.02 * np.abs((1 + 0.1j) * np.array([22.0, 23.0, 24.0])))
    assert len(ax.containers) == 2  # one error-bar set per level
    fig2 = plot_update_fit(meas, X, joint="slip", law="Jenkins")
    assert fig2.axes[0].get_ylabel() == "|x2| first harmonic [m]"  # m where no unit is declared
