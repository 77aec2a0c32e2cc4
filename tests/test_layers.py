"""The dependency rule of the package, checked from the source.

Every ``import`` of every module is read with :mod:`ast` (deferred imports inside functions
included, ``if TYPE_CHECKING:`` blocks excluded, since they never run).  A module may import
only from its own layer or a lower one, and no chain of imports may come back to where it
started, neither between modules nor between the subpackages of one layer.  The layer map is
:data:`LAYERS`, the one place that says which package belongs to which layer.
"""

from __future__ import annotations

import ast
import itertools
import re
from collections import defaultdict
from pathlib import Path

import pytest

PACKAGE_ROOT = Path(__file__).resolve().parents[1] / "optcal"

#: Package (dotted prefix) -> layer; a module belongs to the longest prefix that names it.
#: Lower numbers sit lower: a module imports only from its own layer or below.
LAYERS: dict[str, int] = {
    "optcal.errors": 0,        # exception classes, importable from everywhere
    "optcal.core": 1,          # maths: numpy and scipy only
    "optcal.solvers": 2,       # CasADi solver construction and caching
    "optcal.data": 3,          # reading files, evidence, decisions, static detection
    "optcal.families": 4,      # accelerometer, gyroscope, calibration types, noise, simulation
    "optcal.applications": 5,  # quality, diagnosis, plan, fleet, export, paper reproductions
    "optcal.problems": 5,      # the calibration problems as formulations (families' and applications' builders)
    "optcal.report": 6,        # presentation: text reports, figures, HTML
    "optcal.cli": 7,           # the command line
    "optcal": 8,               # the package's front door (lazy names), on top of everything
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE_ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    found: list[ast.Import | ast.ImportFrom] = []

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child.test):
                for other in child.orelse:
                    visit(other)
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                found.append(child)
            visit(child)

    visit(tree)
    return found


#: A string that names a module for :func:`importlib.import_module` (``"optcal.x.y"`` or
#: ``"optcal.x.y:attribute"``, as lazy registries write them): an import all the same.
MODULE_STRING = re.compile(r"^optcal(\.[A-Za-z_][A-Za-z0-9_]*)+(:[A-Za-z_][A-Za-z0-9_]*)?$")


def _module_strings(tree: ast.AST) -> list[str]:
    return [node.value.split(":")[0] for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and MODULE_STRING.match(node.value)]


def import_graph() -> dict[str, set[str]]:
    """Module -> the optcal modules it imports (a ``from package import name`` names the
    submodule when ``name`` is one, else the package; a string naming a module, as a lazy
    registry holds it, counts as an import of that module)."""
    paths = {module_name(p): p for p in PACKAGE_ROOT.rglob("*.py")}
    graph: dict[str, set[str]] = {name: set() for name in paths}
    for name, path in paths.items():
        is_package = path.name == "__init__.py"
        tree = ast.parse(path.read_text(encoding="utf-8"))
        strings = [s for s in _module_strings(tree) if s in paths]
        graph[name].update(s for s in strings if s != name)
        for node in _imports(tree):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                base = node.module or ""
                if node.level:
                    here = name.split(".") if is_package else name.split(".")[:-1]
                    here = here[: len(here) - (node.level - 1)]
                    base = ".".join(here + ([node.module] if node.module else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in paths else base for a in node.names]
            for target in targets:
                if target.split(".")[0] != "optcal":
                    continue
                while target not in paths and "." in target:
                    target = target.rsplit(".", 1)[0]
                if target != name:
                    graph[name].add(target)
    return graph


def layer_of(module: str) -> tuple[str, int]:
    for prefix in sorted(LAYERS, key=len, reverse=True):
        if module == prefix or module.startswith(prefix + "."):
            return prefix, LAYERS[prefix]
    raise AssertionError(f"{module} belongs to no layer: add its package to LAYERS")


def subpackage(module: str) -> str:
    """The unit whose cycles are checked: ``optcal.families.accel`` for its modules."""
    prefix, _ = layer_of(module)
    rest = module[len(prefix):].lstrip(".").split(".")
    return prefix if not rest[0] or len(rest) == 1 and prefix in ("optcal.core", "optcal.data", "optcal.report", "optcal.cli", "optcal.solvers") else f"{prefix}.{rest[0]}"


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one member (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    counter = itertools.count()
    components: list[list[str]] = []

    def strongconnect(v: str) -> None:
        index[v] = low[v] = next(counter)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                strongconnect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            strongconnect(v)
    return components


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    """The import graph, read once for the module's tests (each read parses every module of optcal: 3 s of CPU)."""
    return import_graph()


def test_every_module_belongs_to_a_layer(graph: dict[str, set[str]]) -> None:
    for module in graph:
        layer_of(module)


def test_no_import_reaches_a_higher_layer(graph: dict[str, set[str]]) -> None:
    upward = []
    for module, targets in sorted(graph.items()):
        own_name, own = layer_of(module)
        for target in sorted(targets):
            name, layer = layer_of(target)
            if layer > own:
                upward.append(f"{module} ({own_name}) imports {target} ({name})")
    assert not upward, "imports that run upward:\n" + "\n".join(upward)


def test_no_import_cycle_between_modules(graph: dict[str, set[str]]) -> None:
    cycles = find_cycles(graph)
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_no_import_cycle_between_subpackages(graph: dict[str, set[str]]) -> None:
    packages: dict[str, set[str]] = defaultdict(set)
    for module, targets in graph.items():
        for target in targets:
            if subpackage(module) != subpackage(target):
                packages[subpackage(module)].add(subpackage(target))
    cycles = find_cycles(dict(packages))
    assert not cycles, "cycles between subpackages:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_the_scanner_sees_a_deferred_upward_import_and_a_cycle() -> None:
    tree = ast.parse("def f():\n    from optcal.cli import main\nif TYPE_CHECKING:\n    import optcal.report\n")
    names = [n.module if isinstance(n, ast.ImportFrom) else n.names[0].name for n in _imports(tree)]
    assert names == ["optcal.cli"]
    assert find_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


@pytest.mark.parametrize("limit", [800])
def test_no_module_is_longer_than(limit: int) -> None:
    long = {module_name(p): n for p in PACKAGE_ROOT.rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > limit}
    assert not long, f"modules over {limit} lines: {long}"
