"""Variables are data: the map's modules, its compiled lookup and the online core name no scene
variable. They number axes; what an axis means (L, W, x, d) comes from the coefficients'
variables, so a map over any set of them takes the same route."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from pipeline.offline.variables import NAMES

ROOT = Path(__file__).resolve().parents[1] / "pipeline"
MODULES = (
    "certify/lookup.py",
    "certify/subpaving.py",
    "certify/region_map.py",
    "certify/map_files.py",
    "online/kernel.py",
)
#: Names that tie a role to one variable (an index, a range, a split, a flag per variable).
TIED = re.compile(
    r"(VARIES|GIVEN|extra_index|extra_ranges|length_range|width_range|split_[wW]|index_[LWxdlw]\b|_[LWxd]_range)"
)


def _docstrings(tree: ast.AST) -> set[int]:
    """ids of the docstring constants of a module, its classes and functions."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                found.add(id(first.value))
    return found


def _names(tree: ast.AST) -> set[str]:
    """Every identifier the code binds or reads."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            found.add(node.id)
        elif isinstance(node, ast.Attribute):
            found.add(node.attr)
        elif isinstance(node, ast.arg):
            found.add(node.arg)
        elif isinstance(node, ast.FunctionDef | ast.ClassDef):
            found.add(node.name)
        elif isinstance(node, ast.keyword) and node.arg:
            found.add(node.arg)
    return found


@pytest.mark.parametrize("module", MODULES)
def test_no_variable_is_named(module: str) -> None:
    tree = ast.parse((ROOT / module).read_text())
    docstrings = _docstrings(tree)
    strings = [
        node.value
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
    ]
    named = sorted({s for s in strings if s in NAMES or any(f"_{n}" == s or f"{n}_m" == s for n in NAMES)})
    assert named == [], f"{module} names variables in strings: {named}"
    tied = sorted(name for name in _names(tree) if TIED.search(name))
    assert tied == [], f"{module} ties names to variables: {tied}"


def test_the_check_catches_what_it_forbids(tmp_path) -> None:
    """The two checks fail on code that names a variable (so the test above can fail)."""
    code = 'VARIES_X = 1\ndef f(index_l, extra_ranges_m):\n    return {"x": index_l}\n'
    tree = ast.parse(code)
    assert any(TIED.search(name) for name in _names(tree))
    strings = [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)]
    assert "x" in strings and "x" in NAMES
