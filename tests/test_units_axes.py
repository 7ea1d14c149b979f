"""Every axis of every report figure carries the right unit, and every figure that compares a
model with a measurement carries an error measure named in its PNG metadata.

The figures are those of the reports that are cheap to make: identify (known and unknown force
gain, with the backbones and re-predictions), the paper's example, modal (FRF with a modal fit,
updating residuals), study (calibration and z histograms) and, where the shared data are here,
the UNESP public-data figure.  Each axis label must hold a bracketed unit; a force in V where the
gain is unknown, ``k3`` instead of ``k3/m``, and Hz written over rad/s data (or the reverse) fail.
Tick labels must not overlap each other, the offset text must not run into the title, and a
legend must not cover measured points.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from jointid import identify_campaign
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.errors import JointidWarning
from jointid.report.figure_meta import COMPARISON_KEY, ERROR_MEASURE_KEY, MEASURES, figure_metadata, png_metadata
from jointid.report.output import campaign_figures, write_results

UNIT = re.compile(r"\[[^\]]+\]")

CONFIG = {
    "campaign": {"name": "units test"},
    "model": [{"preload": 120, "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
               "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
    "excitation": {"force_levels": [0.5, 2.0], "omega_start": 163.0, "omega_stop": 177.0, "n_frequencies": 9},
    "acquisition": {"fs": 2000.0, "periods": 30.0, "noise": 0.01, "seed": 5, "n_harmonics": 7},
}
#: the campaign's excitation frequencies in each unit (for the Hz / rad/s check)
RANGES = {"rad/s": (163.0, 177.0), "Hz": (163.0 / (2 * np.pi), 177.0 / (2 * np.pi))}

#: campaign figures that compare the identified model with the measurement (file-name prefixes)
COMPARISONS = ("damping_law_", "power_law_", "parameters_", "hysteresis_", "reprediction_", "backbone_")


# ---------------------------------------------------------------------------------------- helpers
def _categorical(axis) -> bool:
    """Ticks named by set_ticks(..., labels) (candidate models, parameters): no unit to carry."""
    from matplotlib.ticker import FixedFormatter, FuncFormatter

    if not isinstance(axis.get_major_formatter(), (FixedFormatter, FuncFormatter)):
        return False
    texts = [t.get_text() for t in axis.get_ticklabels() if t.get_text()]
    return not texts or any(re.search(r"[a-df-zA-DF-Z_]", t) for t in texts)


def _labelled_axes(fig):
    """``(axes, which, axis, label)`` of every visible, numeric axis of a figure."""
    out = []
    for ax in fig.axes:
        if not ax.get_visible() or not ax.axison:
            continue
        for which, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            if not axis.get_visible() or _categorical(axis):
                continue
            if not any(t.get_visible() and t.get_text() for t in axis.get_ticklabels()) and not axis.get_label_text():
                continue  # an axis with neither ticks nor label (shared panels)
            out.append((ax, which, axis, axis.get_label_text()))
    return out


def _draw(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    fig.canvas.draw()
    return fig.canvas.get_renderer()


def _overlap(a, b, pad=0.5) -> bool:
    return a.x0 < b.x1 - pad and b.x0 < a.x1 - pad and a.y0 < b.y1 - pad and b.y0 < a.y1 - pad


def check_units(name, fig, *, gain_free=False):
    """Every numeric axis labelled ``... [unit]``; the units of a gain-free run are per unit mass."""
    problems = []
    for ax, which, axis, label in _labelled_axes(fig):
        if not UNIT.search(label):
            problems.append(f"{name}: {which} axis '{label}' has no unit")
            continue
        if gain_free:
            if re.search(r"\[N\]|N/m³|N s/m|\[J\]|\(m/s²\)/N|m/\(s² N\)", label):
                problems.append(f"{name}: {which} axis '{label}' in newtons in a gain-free run")
            if re.match(r"\s*(k3|c|c\d)\s*(\(q_max\))?\s*\[", label):
                problems.append(f"{name}: {which} axis '{label}' is per unit modal mass (k3/m, c/m)")
    return problems


def check_frequency_unit(name, fig, ranges=RANGES):
    """A frequency axis says Hz over data in Hz and rad/s over data in rad/s."""
    problems = []
    for ax, which, axis, label in _labelled_axes(fig):
        if "frequency" not in label or which != "x":
            continue
        unit = "rad/s" if "rad/s" in label else "Hz" if "[Hz]" in label else None
        if unit is None:
            continue
        xs = np.concatenate([np.asarray(line.get_xdata(), float).ravel() for line in ax.get_lines()] or [[]])
        xs = xs[np.isfinite(xs)]
        if xs.size == 0:
            continue
        lo, hi = ranges[unit]
        med = float(np.median(xs))
        if not lo / 1.5 <= med <= hi * 1.5:
            problems.append(f"{name}: x axis '{label}' over data around {med:.4g} (the campaign is {lo:.4g}-{hi:.4g} "
                            f"{unit})")
    return problems


def check_layout(name, fig):
    """No overlapping tick labels, no offset text on the title, no legend over measured points."""
    r = _draw(fig)
    problems = []
    for ax in fig.axes:
        if not ax.get_visible() or not ax.axison:
            continue
        for which, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            boxes = [t.get_window_extent(r) for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
            for i in range(len(boxes) - 1):
                for j in range(i + 1, len(boxes)):
                    if _overlap(boxes[i], boxes[j]):
                        problems.append(f"{name}: overlapping {which} tick labels "
                                        f"{[t.get_text() for t in axis.get_ticklabels()]}")
                        break
            off = axis.get_offset_text()
            if off.get_visible() and off.get_text():
                ob = off.get_window_extent(r)
                texts = [ax.title, ax._left_title, ax._right_title]
                if fig._suptitle is not None:
                    texts.append(fig._suptitle)
                for t in texts:
                    if t.get_text() and _overlap(ob, t.get_window_extent(r)):
                        problems.append(f"{name}: offset text '{off.get_text()}' runs into the title '{t.get_text()}'")
        fb = fig.bbox
        for t in (ax.xaxis.label, ax.yaxis.label, ax.title):
            if t.get_visible() and t.get_text():
                b = t.get_window_extent(r)
                if b.x0 < fb.x0 - 1 or b.y0 < fb.y0 - 1 or b.x1 > fb.x1 + 1 or b.y1 > fb.y1 + 1:
                    problems.append(f"{name}: '{t.get_text()}' runs outside the figure")
        leg = ax.get_legend()
        if leg is not None and leg.get_visible():
            lb = leg.get_window_extent(r)
            inside = ax.get_window_extent(r)
            if not _overlap(lb, inside, pad=2):
                continue
            n = 0
            for line in ax.get_lines():
                if not line.get_visible() or line.get_transform() != ax.transData:
                    continue  # reference lines (axhline, axvline) are drawn in axes coordinates
                xy = np.column_stack([line.get_xdata(), line.get_ydata()]).astype(float)
                xy = xy[np.all(np.isfinite(xy), axis=1)]
                if xy.size == 0:
                    continue
                pix = ax.transData.transform(xy)
                n += int(np.sum((pix[:, 0] > lb.x0) & (pix[:, 0] < lb.x1) & (pix[:, 1] > lb.y0) & (pix[:, 1] < lb.y1)))
            if n:
                problems.append(f"{name}: the legend covers {n} point(s) of the data")
    return problems


def check_error_measure(name, fig, png=None):
    """The comparison note names error measures, each of which is drawn; a saved PNG carries it."""
    meta = figure_metadata(fig)
    if png is not None:
        saved = png_metadata(png)
        if saved.get(ERROR_MEASURE_KEY) != meta.get(ERROR_MEASURE_KEY):
            return [f"{name}: the saved PNG carries {saved.get(ERROR_MEASURE_KEY)!r}, "
                    f"the figure {meta.get(ERROR_MEASURE_KEY)!r}"]
    measures = [m for m in meta.get(ERROR_MEASURE_KEY, "").split("; ") if m]
    if not measures or not meta.get(COMPARISON_KEY):
        return [f"{name}: compares model and measurement but names no error measure"]
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.container import ErrorbarContainer

    problems = []
    texts = []
    for ax in fig.axes:
        texts += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()]
        if ax.get_legend() is not None:
            texts += [t.get_text() for t in ax.get_legend().get_texts()]
    if fig._suptitle is not None:
        texts.append(fig._suptitle.get_text())
    for m in measures:
        if m not in MEASURES:
            problems.append(f"{name}: unknown error measure {m!r}")
        elif m in ("stderr bars", "ci95 bars"):
            bars = [c for ax in fig.axes for c in ax.containers if isinstance(c, ErrorbarContainer) and c.has_yerr
                    and any(isinstance(b, LineCollection) and len(b.get_segments()) for b in c.lines[2])]
            if not bars:
                problems.append(f"{name}: says '{m}' but draws no error bars")
        elif m == "band95":
            if not any(isinstance(c, PolyCollection) for ax in fig.axes for c in ax.collections):
                problems.append(f"{name}: says '{m}' but draws no band")
        elif m == "rms error":
            if not any("rms" in t.lower() for t in texts):
                problems.append(f"{name}: says '{m}' but prints no rms error")
        elif m == "error axis":
            if not any("%" in t or "error" in t for t in texts):
                problems.append(f"{name}: says '{m}' but no axis shows an error")
    return problems


def _identify(tmp_path_factory, **kw):
    root = tmp_path_factory.mktemp("units")
    camp = simulate_campaign(load_simulation_config(CONFIG), root / "campaign")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        result = identify_campaign(camp, **kw)
    return result, root


@pytest.fixture(scope="module")
def known(tmp_path_factory):
    result, root = _identify(tmp_path_factory)
    paths = write_results(result, root / "out", html=False)
    return result, paths, campaign_figures(result)


@pytest.fixture(scope="module")
def gain_free(tmp_path_factory):
    result, root = _identify(tmp_path_factory, force_gain="unknown")
    return result, campaign_figures(result)


# ------------------------------------------------------------------------------------------- tests
def test_identify_figures_axes_units_and_layout(known):
    _, _, figs = known
    assert {n.split("_")[0] for n, _, _ in figs} >= {"damping", "power", "parameters", "hysteresis",
                                                    "reprediction", "backbone"}
    problems = []
    for name, _, fig in figs:
        problems += check_units(name, fig) + check_frequency_unit(name, fig) + check_layout(name, fig)
    assert not problems, "\n".join(problems)


def test_identify_comparison_figures_carry_an_error_measure_in_their_png(known):
    _, paths, figs = known
    saved = {p.name: p for p in paths["figures"]}
    problems = []
    n = 0
    for name, _, fig in figs:
        if name.startswith(COMPARISONS):
            n += 1
            problems += check_error_measure(name, fig, saved[name])
    assert n >= 6 and not problems, "\n".join(problems)


def test_gain_free_run_labels_excitation_in_volts_and_coefficients_per_unit_mass(gain_free):
    result, figs = gain_free
    assert any(g.gain is not None for g in result.groups)
    problems = []
    labels = []
    for name, _, fig in figs:
        problems += check_units(name, fig, gain_free=True) + check_frequency_unit(name, fig)
        if name.startswith(COMPARISONS):
            problems += check_error_measure(name, fig)
        labels += [lab for _, _, _, lab in _labelled_axes(fig)]
        for ax in fig.axes:
            if ax.get_legend() is not None:
                assert not any(re.search(r"F = [\d.]+ N\b", t.get_text()) for t in ax.get_legend().get_texts()), name
    assert any(lab.startswith("c/m") for lab in labels), labels
    assert not problems, "\n".join(problems)


def test_checks_catch_the_faults_they_look_for():
    """The checks above fail on the faults of the issue: Hz over rad/s, k3 in N/m³ in a gain-free
    run, a missing unit, crowded tick labels, a legend over the points, no error measure."""
    from jointid.report.identify_plots import new_axes

    ax = new_axes()
    ax.plot(np.linspace(160, 180, 21), np.ones(21), "o")
    ax.set_xlabel("excitation frequency [Hz]")
    ax.set_ylabel("k3 [N/m³]")
    assert check_frequency_unit("t", ax.figure) and check_units("t", ax.figure, gain_free=True)
    ax.set_ylabel("q_max")
    assert check_units("t", ax.figure)
    ax = new_axes(figsize=(2.0, 2.0))
    ax.plot(np.linspace(-0.005, 0.005, 50), np.linspace(-0.005, 0.005, 50), "o")
    ax.set_xticks(np.linspace(-0.005, 0.005, 9))
    ax.legend(["points"], loc="center")
    problems = check_layout("t", ax.figure)
    assert any("tick labels" in p for p in problems) and any("legend covers" in p for p in problems)
    ax.set_ylabel("a label far too long for a figure two inches high, running off the canvas [m]")
    assert any("outside the figure" in p for p in check_layout("t", ax.figure))
    assert check_error_measure("t", ax.figure)


def test_example_figures_fig5_in_rad_per_s_with_error_bars(tmp_path):
    from jointid.app.paper_example import example_figures, paper_config

    cfg = load_simulation_config(paper_config(n_frequencies=9), source="paper example")
    camp = simulate_campaign(cfg, tmp_path / "campaign")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        r21 = identify_campaign(camp, terms="q + -q^3 + q'", n_harmonics=9, damping_order=2)
    figs = dict(example_figures(cfg, r21))
    ranges = {"rad/s": (160.0, 180.0), "Hz": (160.0 / (2 * np.pi), 180.0 / (2 * np.pi))}
    problems = []
    for name, fig in figs.items():
        problems += check_units(name, fig) + check_frequency_unit(name, fig, ranges) + check_layout(name, fig)
    for name in ("fig5_parameters.png", "fig6_damping.png"):
        problems += check_error_measure(name, figs[name])
    assert not problems, "\n".join(problems)
    for ax in figs["fig5_parameters.png"].axes:
        assert "[rad/s]" in ax.get_xlabel()


def test_modal_frf_phase_wrapped_with_breaks_and_modal_fit_error():
    from jointid.report.modal_plots import plot_frf, wrapped_phase_deg
    from jointid.signal.frf import fit_modes, modal_frf

    f = np.linspace(0.5, 200.0, 2000)
    H = modal_frf(f, 2 * np.pi * np.array([30.0, 120.0]), np.array([0.01, 0.02]), np.array([1.0, 0.8]),
                  np.array([1.0, -0.6]))
    rng = np.random.default_rng(1)
    H = H * (1 + 0.02 * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)))
    fit = fit_modes((f, H, np.ones(f.size)), 2, output="acceleration")
    fig, axes = plot_frf((f, H, np.ones(f.size)), fit=fit)
    problems = check_units("frf", fig) + check_layout("frf", fig) + check_error_measure("frf", fig)
    assert not problems, "\n".join(problems)
    assert "(m/s²)/N" in axes[0].get_ylabel()
    phase = np.concatenate([np.asarray(line.get_ydata(), float) for line in axes[1].get_lines()])
    phase = phase[np.isfinite(phase)]
    assert phase.min() > -180.0 - 1e-9 and phase.max() <= 180.0 + 1e-9
    _, ph = wrapped_phase_deg(np.exp(1j * np.radians([170.0, 179.0, -179.0, -170.0])))
    assert np.isnan(ph[2]) and ph.size == 5  # a break, not a vertical stroke, at the wrap


def test_modal_shapes_and_updating_figures():
    from jointid.modal import SEED_TABLE4_HZ, modal_analysis, seed_bolted_beam, update_to_frequencies
    from jointid.report.modal_plots import plot_mode_shapes, plot_update_residuals

    fig, _ = plot_mode_shapes(modal_analysis(seed_bolted_beam(120), 3), sensors={"a": 0.3, "b": 0.42},
                              force_position=0.05)
    r = update_to_frequencies(seed_bolted_beam(), SEED_TABLE4_HZ[120], ("k_w", "k_t"), n_starts=2)
    fig2, _ = plot_update_residuals(r)
    problems = check_units("mode shapes", fig) + check_layout("mode shapes", fig)
    problems += check_units("updating", fig2) + check_layout("updating", fig2) + check_error_measure("updating", fig2)
    assert not problems, "\n".join(problems)


def test_study_figures_label_their_axes():
    from jointid.report.study_plots import distribution_text, plot_calibration, plot_z_histograms

    stats = [{"parameter": p, "std_z": s, "coverage": c, "coverage_low": c - 0.03, "coverage_high": min(c + 0.03, 1)}
             for p, s, c in (("omega1", 1.02, 0.95), ("k3", 0.9, 0.97), ("c0", 1.3, 0.9))]
    rng = np.random.default_rng(0)
    campaigns = [{"grid_point": 0, "rows": [{"parameter": p, "z": float(rng.standard_normal())}
                                            for p in ("omega1", "k3", "c0")]} for _ in range(30)]
    problems = []
    for name, fig in (("calibration", plot_calibration(stats)[0].figure),
                      ("z histograms", plot_z_histograms(campaigns, ["omega1", "k3", "c0"])[0].figure)):
        problems += check_units(name, fig) + check_layout(name, fig)
    assert not problems, "\n".join(problems)
    assert distribution_text({"loguniform": [0.001, 0.02]}) == "log-uniform 0.001 .. 0.02"
    assert "{" not in distribution_text({"uniform": [3e6, 6e6], "random_sign": True})


def test_unesp_figure_units_and_error_measure(shared_data, tmp_path):
    from jointid.app.public_data import unesp_sine_dwells
    from jointid.io.results import atomic_savefig

    r = unesp_sine_dwells()
    axes = r.plot()
    fig = np.ravel(axes)[0].figure
    path = atomic_savefig(fig, tmp_path / "unesp.png", dpi=80)
    problems = check_units("unesp", fig, gain_free=True) + check_layout("unesp", fig)
    problems += check_error_measure("unesp", fig, path)
    assert not problems, "\n".join(problems)
    assert all("q_max [m]" == ax.get_xlabel() for ax in np.ravel(axes))


@pytest.mark.slow
def test_demo_figures_units_layout_and_error_measures(demo_run):
    """The whole demo (slow): every figure's axes carry units, nothing overlaps, and each figure
    comparing the identified model with the measured dwells (Figs 10, 12-18) names its error measure."""
    from jointid.report.demo_report import demo_figures

    demo = demo_run
    figs = demo_figures(demo)
    problems = []
    compared = 0
    for name, _, fig in figs:
        problems += check_units(name, fig) + check_layout(name, fig)
        if re.match(r"fig(10|12|13|14|15|16|17|18)_", name):
            compared += 1
            problems += check_error_measure(name, fig, demo.out_dir / "figures" / f"{name}.png")
    assert compared >= 8 and not problems, "\n".join(problems)


@pytest.mark.slow
def test_public_data_figures(shared_data, tmp_path):
    """Silverbox levels, the Silverbox arrow and the F-16 restoring force (slow: reads the data sets)."""
    from jointid.app.public_data import f16_restoring_force, silverbox_benchmark, silverbox_multilevel
    from jointid.io.results import atomic_savefig

    problems = []
    for name, func, compares in (("silverbox", silverbox_multilevel, True), ("benchmark", silverbox_benchmark, True),
                                 ("f16", f16_restoring_force, False)):
        drawn = func().plot()
        fig = drawn if hasattr(drawn, "savefig") else np.ravel(drawn)[0].figure
        path = atomic_savefig(fig, tmp_path / f"{name}.png", dpi=60)
        problems += check_units(name, fig) + check_layout(name, fig)
        if compares:
            problems += check_error_measure(name, fig, path)
    assert not problems, "\n".join(problems)
