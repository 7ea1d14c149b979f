"""The data flow stays visible: core numerics never import io, report or cli at module level."""

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "jointid"
CORE = ("signal", "modal", "identify", "simulate")
FORBIDDEN = ("io", "report", "cli")


def _module_level_imports(path):
    tree = ast.parse(path.read_text())
    for node in tree.body:  # top level only: plot() methods import report lazily, by design
        if isinstance(node, ast.ImportFrom) and node.level >= 1:
            yield (node.module or "").split(".")[0] if node.level == 2 else None
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("jointid."):
            yield node.module.split(".")[1]


@pytest.mark.parametrize("package", CORE)
def test_core_does_not_import_io_report_or_cli(package):
    for path in sorted((SRC / package).glob("*.py")):
        bad = [m for m in _module_level_imports(path) if m in FORBIDDEN]
        assert not bad, f"{path.relative_to(SRC)} imports {bad} at module level"


# Ground-floor packages: every import in them (module level or inside a function) stays on the ground.
GROUND = {"joints": {"errors", "conventions", "joints"}}


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
