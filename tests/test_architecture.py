"""The data flow stays visible: every import points down the floors, and no module imports itself in a circle.

Floors, bottom to top (docs/architecture.md): the ground (errors, conventions, rounding, _blas, joints,
numerics, plotting) < io < signal < modal < identify < simulate < rig < report < app < cli.  A module in a
sub-package belongs to the floor of its top folder.  Every internal import is read, at module level and
inside functions, with relative imports resolved from the importing file's package.
"""

import ast
import sys
from functools import lru_cache
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "jointid"

#: The floor of every top-level module or folder of the package (``jointid`` is the package itself).
FLOORS = {
    "jointid": 0, "errors": 0, "conventions": 0, "rounding": 0, "_blas": 0, "joints": 0, "numerics": 0,
    "plotting": 0,
    "io": 1, "examples": 1,
    "signal": 2, "modal": 3, "identify": 4, "simulate": 5, "rig": 6, "report": 7, "app": 8, "cli": 9,
}
CORE = ("signal", "modal", "identify", "simulate")
#: Core numerics work on arrays and records in memory: they import none of these, not even inside a function.
CORE_FORBIDDEN = ("io", "report", "app", "cli")

#: Upward imports still waiting for their removal: (importing file, imported module) -> reason.  The list may
#: only shrink: an entry whose import is gone (or no longer points up) fails the test below, so remove it then.
ALLOWED_UPWARD: dict = {}


def _room(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def _module_file(module: str, src: Path = SRC) -> Path | None:
    """The file of a dotted ``jointid...`` module (``.py`` or a package's ``__init__.py``), else None."""
    rel = Path(*module.split(".")[1:])
    for path in (src / rel.with_suffix(".py") if rel.parts else None, src / rel / "__init__.py"):
        if path is not None and path.is_file():
            return path
    return None


def _module_name(path: Path, src: Path = SRC) -> str:
    rel = path.relative_to(src.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


@lru_cache(maxsize=None)
def _imports(path: Path, src: Path = SRC) -> tuple:
    """Every internal import of ``path`` as ``(line, dotted module)``, module level and inside functions.

    ``from a.b import c`` names the module ``a.b.c`` when ``c`` is a module, else ``a.b``; relative imports
    are resolved from the file's own package."""
    package = _module_name(path, src).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1] + (node.module.split(".") if node.module else [])
                base = ".".join(base)
            else:
                base = node.module or ""
            if _room(base) != "jointid" and not base.startswith("jointid"):
                continue
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                out.append((node.lineno, sub if _module_file(sub, src) else base))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] == "jointid"]
    return tuple(out)


def _source_files(src: Path = SRC):
    return sorted(p for p in src.rglob("*.py"))


def _rel(path: Path, src: Path = SRC) -> str:
    return path.relative_to(src).as_posix()


def _arrows(src: Path = SRC):
    """``(file, line, imported module)`` for every internal import of the package."""
    for path in _source_files(src):
        for line, module in _imports(path, src):
            yield _rel(path, src), line, module


def _file_room(rel: str) -> str:
    first = rel.split("/")[0]
    return "jointid" if first == "__init__.py" else first.removesuffix(".py")


def test_every_room_has_a_floor():
    rooms = {_file_room(_rel(p)) for p in _source_files()}
    assert rooms <= set(FLOORS), f"place {sorted(rooms - set(FLOORS))} on a floor (here and docs/architecture.md)"


def test_every_internal_import_resolves_to_a_module():
    bad = [f"{f}:{line} -> {m}" for f, line, m in _arrows() if _module_file(m) is None]
    assert not bad, "imports of modules that do not exist: " + "; ".join(bad)


def test_no_import_points_up_a_floor():
    up = []
    for rel, line, module in _arrows():
        if FLOORS[_room(module)] > FLOORS[_file_room(rel)] and (rel, module) not in ALLOWED_UPWARD:
            up.append(f"{rel}:{line} ({_file_room(rel)}, floor {FLOORS[_file_room(rel)]}) imports {module} "
                      f"(floor {FLOORS[_room(module)]})")
    assert not up, "imports pointing up the floors (docs/architecture.md):\n  " + "\n  ".join(up)


def test_allowed_upward_imports_still_exist():
    """The allow-list only shrinks: each entry names an import that is still there and still points up."""
    seen = {(rel, module) for rel, _, module in _arrows()}
    for (rel, module), reason in ALLOWED_UPWARD.items():
        assert reason
        assert (rel, module) in seen, f"{rel} no longer imports {module}: remove its ALLOWED_UPWARD entry"
        assert FLOORS[_room(module)] > FLOORS[_file_room(rel)], f"{rel} -> {module} is not upward: remove it"


@pytest.mark.parametrize("package", CORE)
def test_core_floors_never_import_io_report_app_or_cli(package):
    bad = [f"{rel}:{line} -> {module}" for rel, line, module in _arrows()
           if _file_room(rel) == package and _room(module) in CORE_FORBIDDEN]
    assert not bad, f"{package} works in memory and never imports {CORE_FORBIDDEN}: " + "; ".join(bad)


# Ground-floor packages: every import in them (module level or inside a function) stays on the ground, and
# the shared numerics keep to their own company.
GROUND = {"joints": {"errors", "conventions", "joints"}, "numerics": {"errors", "conventions", "numerics"},
          "plotting": {"errors"}}


@pytest.mark.parametrize("package", sorted(GROUND))
def test_ground_floor_packages_import_only_the_ground(package):
    allowed = GROUND[package]
    rels = [(rel, line, m) for rel, line, m in _arrows() if _file_room(rel) == package]
    assert any(_file_room(_rel(p)) == package for p in _source_files()), f"no files in {package}"
    bad = sorted({f"{rel}:{line} -> {m}" for rel, line, m in rels if _room(m) not in allowed})
    assert not bad, f"{package} may import only {sorted(allowed)}: " + "; ".join(bad)


def test_numerics_imports_only_numpy_scipy_and_the_standard_library():
    """jointid.numerics is the ground floor of the shared numerics: besides errors and
    conventions (checked above) it may import only numpy, scipy and the standard library,
    at module level or inside a function."""
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


def _import_graph(src: Path = SRC, leave_out=()) -> dict:
    """File -> set of files it imports (every internal import, module level and inside functions), less the
    ``(file, module)`` arrows in ``leave_out``."""
    graph = {}
    for path in _source_files(src):
        targets = {_module_file(m, src) for _, m in _imports(path, src) if (_rel(path, src), m) not in leave_out}
        graph[_rel(path, src)] = {_rel(t, src) for t in targets if t is not None and t != path}
    return graph


def _cycles(graph: dict) -> list:
    """The strongly connected components of more than one file (Tarjan's algorithm, iterative)."""
    index, low, on_stack, stack, found, counter = {}, {}, set(), [], [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter[0]
                    counter[0] += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_no_import_circles():
    """No files import each other in a circle; the upward arrows still allowed (and nothing else) are left out."""
    circles = _cycles(_import_graph(leave_out=set(ALLOWED_UPWARD)))
    assert not circles, "files importing each other in a circle:\n  " + "\n  ".join(" <-> ".join(c) for c in circles)


def test_the_checks_see_imports_inside_functions_and_relative_imports(tmp_path):
    """On a small package: imports inside functions, relative imports from a sub-package, ``from . import
    module`` and ``from package import name`` are resolved; the circle finder sees a circle of three files."""
    src = tmp_path / "jointid"
    for rel, text in {
        "__init__.py": "",
        "errors.py": "",
        "plotting.py": "from .errors import *\n",
        "report/__init__.py": "",
        "report/plots.py": "import jointid.errors\n",
        "simulate/__init__.py": "from .hbm import results\n",
        "simulate/hbm/__init__.py": "",
        "simulate/hbm/results.py": ("from ..hbm import kernels\nfrom ...errors import Oops\n\n"
                                    "class R:\n    def plot(self):\n        from ... import plotting\n"
                                    "        from ...report.plots import draw\n        return draw\n"),
        "simulate/hbm/kernels.py": "from jointid.simulate import hbm\n",
    }.items():
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        (src / rel).write_text(text)
    got = set(_imports(src / "simulate" / "hbm" / "results.py", src))
    assert got == {(1, "jointid.simulate.hbm.kernels"), (2, "jointid.errors"), (6, "jointid.plotting"),
                   (7, "jointid.report.plots")}
    assert set(_imports(src / "simulate" / "__init__.py", src)) == {(1, "jointid.simulate.hbm.results")}
    assert set(_imports(src / "report" / "plots.py", src)) == {(1, "jointid.errors")}
    graph = _import_graph(src)
    assert graph["simulate/hbm/kernels.py"] == {"simulate/hbm/__init__.py"}
    assert graph["simulate/hbm/results.py"] == {"simulate/hbm/kernels.py", "errors.py", "plotting.py", "report/plots.py"}
    assert _cycles(graph) == []
    assert _cycles(_import_graph(src, leave_out={("simulate/hbm/results.py", "jointid.report.plots")})) == []
    (src / "simulate" / "hbm" / "__init__.py").write_text("def f():\n    from .results import R\n")
    _imports.cache_clear()
    assert _cycles(_import_graph(src)) == [["simulate/hbm/__init__.py", "simulate/hbm/kernels.py",
                                            "simulate/hbm/results.py"]]
    assert _cycles(_import_graph(src, leave_out={("simulate/hbm/results.py", "jointid.simulate.hbm.kernels")})) == []
    _imports.cache_clear()
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set(), "c": {"c"}}) == []
