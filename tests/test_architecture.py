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
