"""The data flow stays visible: core numerics never import io, report or cli at module level."""

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "jointid"
CORE = ("signal", "modal", "identify", "simulate")
FORBIDDEN = ("io", "report", "cli")


def _resolved_imports(path, top_level_only=False):
    """The room (first folder under jointid) of every internal import of ``path``, relative
    imports resolved from the file's own package, at any depth."""
    package = path.relative_to(SRC.parent).parent.parts  # ("jointid", "simulate", "hbm")
    tree = ast.parse(path.read_text())
    for node in (tree.body if top_level_only else ast.walk(tree)):
        names = []
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(package[: len(package) - node.level + 1])
                names = [base + (node.module.split(".") if node.module else [])]
            else:
                names = [node.module.split(".")]
        elif isinstance(node, ast.Import):
            names = [a.name.split(".") for a in node.names]
        for parts in names:
            if parts and parts[0] == "jointid":
                yield parts[1] if len(parts) > 1 else "jointid"


def _module_level_imports(path):
    tree = ast.parse(path.read_text())
    for node in tree.body:  # top level only: plot() methods import report lazily, by design
        if isinstance(node, ast.ImportFrom) and node.level >= 1:
            yield (node.module or "").split(".")[0] if node.level == 2 else None
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("jointid."):
            yield node.module.split(".")[1]


@pytest.mark.parametrize("package", CORE)
def test_core_does_not_import_io_report_or_cli(package):
    for path in sorted((SRC / package).rglob("*.py")):  # sub-packages too (simulate/hbm/)
        if path.parent == SRC / package:
            bad = [m for m in _module_level_imports(path) if m in FORBIDDEN]
        else:
            bad = [m for m in _resolved_imports(path, top_level_only=True) if m in FORBIDDEN]
        assert not bad, f"{path.relative_to(SRC)} imports {bad} at module level"


# Ground-floor packages: every import in them (module level or inside a function) stays on the ground.
GROUND = {"joints": {"errors", "conventions", "joints"}, "numerics": {"errors", "conventions", "numerics"}}


def _all_internal_imports(path, package):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if node.level == 1:
                yield package
            elif node.level == 2:
                yield mod.split(".")[0]
            elif node.level == 0 and mod.split(".")[0] == "jointid":
                yield mod.split(".")[1] if "." in mod else "jointid"
            elif node.level > 2:
                yield "jointid"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "jointid":
                    yield parts[1] if len(parts) > 1 else "jointid"


@pytest.mark.parametrize("package", sorted(GROUND))
def test_ground_floor_packages_import_only_the_ground(package):
    allowed = GROUND[package]
    files = sorted((SRC / package).glob("*.py"))
    assert files, f"no files in {package}"
    for path in files:
        bad = sorted({m for m in _all_internal_imports(path, package) if m not in allowed})
        assert not bad, f"{path.relative_to(SRC)} imports {bad}; {package} may import only {sorted(allowed)}"


def test_numerics_imports_only_numpy_scipy_and_the_standard_library():
    """jointid.numerics is the ground floor of the shared numerics: besides errors and
    conventions (checked above) it may import only numpy, scipy and the standard library,
    at module level or inside a function."""
    import sys

    allowed = set(sys.stdlib_module_names) | {"numpy", "scipy", "jointid", "__future__"}
    files = sorted((SRC / "numerics").rglob("*.py"))
    assert files
    for path in files:
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                tops = [a.name.split(".")[0] for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                tops = [(node.module or "").split(".")[0]]
            else:
                continue
            bad = sorted(set(tops) - allowed)
            assert not bad, f"{path.relative_to(SRC)} imports {bad}; numerics may import only numpy and scipy"


def test_resolved_imports_see_relative_imports_of_sub_packages():
    """The resolver behind the checks reads ``from ...report`` in simulate/hbm/ as report."""
    path = SRC / "simulate" / "hbm" / "results.py"
    assert "plotting" in set(_resolved_imports(path))  # FrequencyResponse.plot, inside a function
    assert "plotting" not in set(_resolved_imports(path, top_level_only=True))
    assert "report" not in set(_resolved_imports(path))
    assert "numerics" in set(_resolved_imports(SRC / "simulate" / "hbm" / "kernels.py"))
