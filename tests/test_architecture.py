"""The import graph of ``pipeline`` and ``verify``: no circle anywhere, every import goes down the
layers of the data flow, and Meshcat is imported only under ``verify/viewer/``.

The graph is read from the source with ``ast`` (every ``import`` and ``from ... import``,
including those inside functions and ``if TYPE_CHECKING:`` blocks), not by importing, so a
lazy import cannot hide an edge.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pipeline", "verify")

#: The layers, lowest first: a module may import modules of its own layer or of a lower one.
#: A module belongs to the layer of the longest prefix that names it (``pipeline.io.jsonio`` ->
#: ``pipeline.io``); ``pipeline.certify`` has its place even before the package exists.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("base", ("pipeline.exceptions", "pipeline.validation", "pipeline.native", "pipeline.io")),
    ("model", ("pipeline.model",)),
    ("motion", ("pipeline.motion",)),
    ("geometry", ("pipeline.geometry",)),
    ("offline", ("pipeline.offline",)),
    ("certify", ("pipeline.certify",)),
    ("build", ("pipeline.build",)),
    ("online", ("pipeline.online",)),
    ("pipeline top level (API, CLI scaffold, CLIs)", ("pipeline", "pipeline.build.__main__")),
    ("verify library", ("verify.acceptance", "verify.benchmark", "verify.viewer")),
    ("verify CLIs", ("verify",)),
)

#: Where Meshcat may be imported.
MESHCAT_HOME = "verify.viewer"


def module_files() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the two packages."""
    modules = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join(parts)] = path
    return modules


MODULES = module_files()


def _resolve_relative(module: str, is_package: bool, level: int, target: str | None) -> str:
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (level - 1)] if level > 1 else base
    return ".".join([*base, target] if target else base)


def imported_names(module: str, path: Path) -> Iterator[str]:
    """Every dotted name ``module`` imports (absolute; ``from X import y`` gives X.y if that is a module, else X)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    is_package = path.name == "__init__.py"
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom):
            source = node.module if node.level == 0 else _resolve_relative(module, is_package, node.level, node.module)
            if source is None:
                continue
            for alias in node.names:
                candidate = f"{source}.{alias.name}"
                yield candidate if candidate in MODULES else source


def internal(name: str) -> str | None:
    """The project module ``name`` refers to (itself or its closest parent package), or None."""
    while name:
        if name in MODULES:
            return name
        name = name.rpartition(".")[0]
    return None


def import_graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports."""
    graph: dict[str, set[str]] = {}
    for module, path in MODULES.items():
        targets = {internal(name) for name in imported_names(module, path)}
        graph[module] = {t for t in targets if t is not None and t != module}
    return graph


def layer_of(module: str) -> int:
    best, best_length = None, -1
    for rank, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best_length:
                best, best_length = rank, len(prefix)
    if best is None:
        raise AssertionError(f"{module} belongs to no layer: add it to LAYERS")
    return best


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    """Every import of ``graph`` that goes up the layers, in words."""
    return [
        f"{module} ({LAYERS[layer_of(module)][0]}) imports {target} ({LAYERS[layer_of(target)][0]})"
        for module, targets in sorted(graph.items())
        for target in sorted(targets)
        if layer_of(target) > layer_of(module)
    ]


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle as a list of modules (first == last), or None."""
    state: dict[str, int] = {}  # 1: on the stack, 2: done
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for target in sorted(graph.get(node, ())):
            if state.get(target) == 1:
                return [*stack[stack.index(target) :], target]
            if target not in state:
                found = visit(target)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


# --------------------------------------------------------------------------------------------
# The checks of the checker itself: it must see what it is meant to catch.


def test_the_cycle_finder_finds_circles_and_only_circles():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"a2"}, "a2": set(), "b": {"b"}}) == ["b", "b"]


def test_relative_imports_and_imports_inside_functions_are_seen():
    graph = import_graph()
    # verify.sweep imports the viewer only inside a function (importlib) but the plots by a
    # function-level "from ... import"; verify.acceptance.plots imports .cases relatively.
    assert "verify.acceptance.plots" in graph["verify.sweep"]
    assert "verify.acceptance.cases" in graph["verify.acceptance.plots"]
    assert "pipeline.online.generator" in graph["verify.acceptance.metrics"]


def test_an_upward_import_is_a_violation():
    assert layer_violations({"pipeline.model.arm": {"pipeline.online.repair", "pipeline.io.jsonio"}}) == [
        "pipeline.model.arm (model) imports pipeline.online.repair (online)"
    ]
    assert layer_violations({"verify.acceptance.run": {"verify.sweep"}})
    assert not layer_violations({"verify.sweep": {"verify.acceptance.run", "pipeline.cli"}})


def test_layers_order_the_data_flow():
    assert layer_of("pipeline.io.jsonio") < layer_of("pipeline.model.arm") < layer_of("pipeline.motion.path")
    assert layer_of("pipeline.geometry.clearance") < layer_of("pipeline.offline.doe")
    assert layer_of("pipeline.offline.doe") < layer_of("pipeline.certify.range") < layer_of("pipeline.online.repair")
    assert layer_of("pipeline.online.repair") < layer_of("pipeline.cli") == layer_of("pipeline")
    assert layer_of("pipeline.certify.range") < layer_of("pipeline.build.run") < layer_of("pipeline.online.loading")
    assert layer_of("pipeline.build.__main__") == layer_of("pipeline.commands.build") == layer_of("pipeline")
    assert layer_of("pipeline.build") < layer_of("verify.acceptance.run") < layer_of("verify.sweep")
    assert layer_of("verify.viewer.server") == layer_of("verify.benchmark.run") < layer_of("verify.view")


# --------------------------------------------------------------------------------------------
# The rules.


def test_there_is_no_import_circle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import circle: " + " -> ".join(cycle or [])


def test_every_import_goes_down_the_layers():
    wrong = layer_violations(import_graph())
    assert not wrong, "imports against the layers:\n" + "\n".join(wrong)


@pytest.mark.parametrize("package", PACKAGES)
def test_meshcat_is_imported_only_under_verify_viewer(package):
    offenders = [
        module
        for module, path in MODULES.items()
        if module.split(".")[0] == package
        and not (module == MESHCAT_HOME or module.startswith(MESHCAT_HOME + "."))
        and any(name == "meshcat" or name.startswith("meshcat.") for name in imported_names(module, path))
    ]
    assert not offenders, f"Meshcat imported outside {MESHCAT_HOME}: {offenders}"
