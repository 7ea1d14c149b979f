"""The plotting protocol: lower floors reach report's drawing functions only by name, through one table."""

import ast
import importlib
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from jointid import plotting  # noqa: E402
from jointid.errors import JointidError  # noqa: E402

SRC = Path(__file__).resolve().parents[1] / "src" / "jointid"


def test_every_entry_names_a_callable_of_report():
    for name, target in plotting.DRAWERS.items():
        module, _, attribute = target.partition(":")
        assert module.startswith("jointid.report."), f"{name} points to {module}: drawing lives in report only"
        assert name == f"{module.rsplit('.', 1)[1]}.{attribute}", f"{name} should be named after {target}"
        assert callable(getattr(importlib.import_module(module), attribute))
        assert plotting.resolve(name) is getattr(importlib.import_module(module), attribute)


def test_unknown_name_is_a_clear_project_error():
    with pytest.raises(JointidError, match="no drawing function named 'modal_plots.nope'"):
        plotting.draw("modal_plots.nope", None)
    with pytest.raises(LookupError):
        plotting.resolve("")


def _draw_names(path):
    """The literal names passed to ``plotting.draw``/``plotting.resolve`` in ``path``."""
    for node in ast.walk(ast.parse(path.read_text())):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr in ("draw", "resolve") and isinstance(node.func.value, ast.Name)
                and node.func.value.id == "plotting"):
            arg = node.args[0] if node.args else None
            assert isinstance(arg, ast.Constant) and isinstance(arg.value, str), \
                f"{path.relative_to(SRC)}:{node.lineno}: plotting.{node.func.attr} needs a literal name"
            yield arg.value


def test_every_hook_of_the_lower_floors_names_an_entry_and_every_entry_is_used():
    used = set()
    for folder in ("signal", "modal", "identify", "simulate"):
        for path in sorted((SRC / folder).rglob("*.py")):
            for name in _draw_names(path):
                assert name in plotting.DRAWERS, f"{path.relative_to(SRC)} draws {name!r}, not in plotting.DRAWERS"
                used.add(name)
    assert used == set(plotting.DRAWERS), f"unused entries: {sorted(set(plotting.DRAWERS) - used)}"


def test_hooks_draw_through_the_table(monkeypatch):
    """The conveniences of the identify floor call the registered function with the object."""
    import matplotlib.pyplot as plt

    from jointid.identify.laws import fit_damping_law, fit_power_law

    q = np.linspace(1e-3, 5e-3, 8)
    law = fit_damping_law(q, 0.3 + 40 * q + 2e3 * q**2, order=2)
    power = fit_power_law(np.linspace(1.0, 4.0, 6), 0.2 * np.linspace(1.0, 4.0, 6) ** 2.5)
    seen = []
    real = plotting.resolve

    def spy(name):
        seen.append(name)
        return real(name)

    monkeypatch.setattr(plotting, "resolve", spy)
    ax = law.plot()
    power.plot()
    html = law._repr_html_()
    assert seen == ["identify_plots.plot_damping_law", "identify_plots.plot_power_law", "notebook.result_html"]
    assert ax is not None and "<" in html
    plt.close("all")


def test_selection_figure_shows_the_measure_that_decided():
    """Bars: the held-out prediction score when it decided (the BIC difference as dots), else the BIC difference."""
    from types import SimpleNamespace

    from jointid.report.selection_plots import plot_selection

    rows = [{"name": "cubic", "selected": True, "delta_ic": 0.0, "heldout_score": 0.002, "cv_force": 1.1},
            {"name": "linear", "selected": False, "delta_ic": 300.0, "heldout_score": 0.2, "cv_force": 9.0},
            {"name": "Iwan", "selected": False, "delta_ic": None, "heldout_score": 0.05, "cv_force": None}]
    for heldout, label, widths in ((True, "held-out prediction score", [0.002, 0.2, 0.05]),
                                   (False, "ΔBIC + 1", [1.0, 301.0, 0.0])):
        sel = SimpleNamespace(table=lambda: rows, criterion="bic", heldout=heldout, preload=1)
        ax = plot_selection(sel)
        assert ax.get_xlabel().startswith(label)
        got = [bar.get_width() for bar in ax.patches]
        assert np.allclose(np.nan_to_num(got), widths), got
