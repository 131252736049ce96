"""No module-level mutable state in ``pipeline``: what a query needs is owned by a loaded object
(the coefficients' query state, the arm's derived data), not by a module-level cache.

Read from the source with ``ast``: a module-level name bound to a dict, list or set (a display, a
comprehension or a call of a mutable container type), a module-level function memoised with
``functools.lru_cache`` / ``functools.cache``, or a ``global`` statement anywhere is refused.
Constant tables are read-only (``types.MappingProxyType``, tuples, frozensets); ``__all__`` is a
declaration, not state.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MODULES = sorted((ROOT / "pipeline").rglob("*.py"))
#: Calls that make a mutable container.
MUTABLE_CALLS = frozenset(
    {"dict", "list", "set", "bytearray", "defaultdict", "OrderedDict", "Counter", "deque"}
    | {"WeakKeyDictionary", "WeakValueDictionary", "WeakSet"}
)
MUTABLE_DISPLAYS = (ast.Dict, ast.List, ast.Set, ast.DictComp, ast.ListComp, ast.SetComp)
MEMOISERS = frozenset({"lru_cache", "cache"})


def _called_name(node: ast.expr) -> str:
    return ast.unparse(node.func if isinstance(node, ast.Call) else node).split(".")[-1].split("(")[0]


def mutable_state(source: str) -> list[str]:
    """What in ``source`` is module-level mutable state, as "line: what" strings."""
    tree = ast.parse(source)
    found = []
    for node in tree.body:
        value = node.value if isinstance(node, ast.Assign | ast.AnnAssign) else None
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if value is not None else []
        names = [ast.unparse(t) for t in targets]
        if value is not None and names != ["__all__"]:
            if isinstance(value, MUTABLE_DISPLAYS) or (
                isinstance(value, ast.Call) and _called_name(value) in MUTABLE_CALLS
            ):
                found.append(f"{node.lineno}: {', '.join(names)} = {type(value).__name__}")
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            for decorator in node.decorator_list:
                if _called_name(decorator) in MEMOISERS:
                    found.append(f"{node.lineno}: {node.name} memoised by {ast.unparse(decorator)}")
    found += [f"{n.lineno}: global {', '.join(n.names)}" for n in ast.walk(tree) if isinstance(n, ast.Global)]
    return found


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_module_level_mutable_state(path: Path) -> None:
    assert mutable_state(path.read_text()) == []


@pytest.mark.parametrize(
    "source",
    [
        "_CACHE = {}",
        "_CACHE: dict[int, int] = {}",
        "PLANS = [x for x in range(3)]",
        "import weakref\n_ARMS = weakref.WeakKeyDictionary()",
        "import functools\n@functools.lru_cache(maxsize=4)\ndef f(x):\n    return x",
        "from functools import cache\n@cache\ndef f(x):\n    return x",
        "def f():\n    global _N\n    _N = 1",
    ],
)
def test_the_check_finds_each_kind_of_state(source: str) -> None:
    assert len(mutable_state(source)) == 1


def test_the_check_passes_read_only_tables() -> None:
    source = (
        "from types import MappingProxyType\n"
        "__all__ = ['A']\n"
        "A = MappingProxyType({'x': 1})\n"
        "B = (1, 2)\n"
        "C = frozenset({1})\n"
        "import numba\n@numba.njit(cache=True)\ndef f(x):\n    return x"
    )
    assert mutable_state(source) == []
